"""Vehicle data: the library of vehicle files shipped with crashlab and the validated `VehicleSpec`."""
from __future__ import annotations

import dataclasses
from importlib import resources
from pathlib import Path

import tomllib
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from .errors import InputError

Positive = Field(gt=0)


class VehicleFile(BaseModel):
    """Schema of a vehicle file (SI units). Per-model sections (e.g. [multibody]) are kept as they are."""

    model_config = ConfigDict(extra="allow")

    name: str = ""
    mass: float = Positive
    yaw_inertia: float = Positive
    roll_inertia: float = Positive
    pitch_inertia: float = Positive
    length: float = Positive
    width: float = Positive
    height: float = Positive
    wheelbase: float = Positive
    track: float = Positive
    cg_to_front_axle: float = Positive
    cg_to_front: float | None = Field(default=None, gt=0)  # CG to front bumper; default length / 2
    cg_height: float = Field(ge=0)
    rolling_resistance: float = Field(default=0.0, ge=0)
    cornering_stiffness: float = Field(default=60e3, gt=0)  # N/rad per tyre
    wheel_radius: float = Field(default=0.3, gt=0)

    @model_validator(mode="after")
    def _geometry(self):
        if self.cg_to_front_axle >= self.wheelbase:
            raise ValueError("cg_to_front_axle must be shorter than the wheelbase")
        if self.cg_to_front is not None and self.cg_to_front >= self.length:
            raise ValueError("cg_to_front must be shorter than the length")
        return self


@dataclasses.dataclass(frozen=True)
class VehicleSpec:
    """What every model may need to know about a vehicle (SI). `sections` holds per-model data."""

    name: str
    mass: float
    yaw_inertia: float
    roll_inertia: float
    pitch_inertia: float
    length: float
    width: float
    height: float
    wheelbase: float
    track: float
    cg_to_front_axle: float
    cg_to_front: float
    cg_height: float
    rolling_resistance: float
    cornering_stiffness: float
    wheel_radius: float
    sections: dict = dataclasses.field(default_factory=dict, compare=False, hash=False)

    @property
    def cg_to_rear_axle(self) -> float:
        return self.wheelbase - self.cg_to_front_axle

    @property
    def cg_to_rear(self) -> float:
        return self.length - self.cg_to_front


def library() -> list[str]:
    """Names of the vehicles shipped with crashlab."""
    return sorted(p.name[:-5] for p in resources.files("crashlab").joinpath("vehicles").iterdir()
                  if p.name.endswith(".toml"))


def _deep_merge(base: dict, update: dict) -> dict:
    out = dict(base)
    for k, v in update.items():
        out[k] = _deep_merge(out[k], v) if isinstance(v, dict) and isinstance(out.get(k), dict) else v
    return out


def read_toml(path: Path, what: str = "file") -> dict:
    try:
        with open(path, "rb") as fh:
            return tomllib.load(fh)
    except FileNotFoundError:
        raise InputError(path, what, "file not found") from None
    except tomllib.TOMLDecodeError as err:
        raise InputError(path, "(syntax)", f"malformed TOML: {err}") from None
    except UnicodeDecodeError:
        raise InputError(path, "(encoding)", "not a UTF-8 text file") from None
    except OSError as err:
        raise InputError(path, what, err.strerror or str(err)) from None


def pydantic_error(file, err: ValidationError, prefix: str = "") -> InputError:
    """The first validation error as one InputError line (file, dotted key, problem)."""
    first = err.errors()[0]
    key = ".".join(str(p) for p in first["loc"]) or "(top level)"
    msg = first["msg"].removeprefix("Value error, ")
    if first["type"] == "extra_forbidden":
        msg = "unknown key"
    elif first["type"] == "missing":
        msg = "missing key"
    return InputError(file, prefix + key, msg)


def load_vehicle(ref: str, base_dir: Path | None = None, overrides: dict | None = None,
                 where: str = "vehicle", scene_file: str | Path = "<scene>") -> VehicleSpec:
    """A vehicle from the library by name, or from a file path (relative to `base_dir`), with overrides."""
    if ref.endswith(".toml"):
        path = (base_dir or Path.cwd()) / ref
        if not path.exists():
            raise InputError(scene_file, where, f"vehicle file {ref!r} not found")
    else:
        names = library()
        if ref not in names:
            import difflib
            close = difflib.get_close_matches(ref, names, n=1)
            hint = f"; did you mean {close[0]!r}?" if close else f"; the library has {', '.join(names)}"
            raise InputError(scene_file, where, f"unknown vehicle {ref!r}{hint}")
        path = Path(str(resources.files("crashlab").joinpath("vehicles", ref + ".toml")))
    data = read_toml(path, "vehicle")
    try:  # the file itself first, so its own errors are blamed on it
        spec = VehicleFile.model_validate(data)
    except ValidationError as err:
        raise pydantic_error(path, err) from None
    if overrides:
        known = set(VehicleFile.model_fields) | set(data)
        for key, val in overrides.items():
            if key not in known:
                raise InputError(scene_file, f"{where}.overrides.{key}", "unknown vehicle key")
            if isinstance(data.get(key), dict) != isinstance(val, dict):
                raise InputError(scene_file, f"{where}.overrides.{key}",
                                 "a table is overridden by a table, a value by a value")
        try:
            spec = VehicleFile.model_validate(_deep_merge(data, overrides))
        except ValidationError as err:
            raise pydantic_error(scene_file, err, prefix=f"{where}.overrides.") from None
    fields = spec.model_dump()
    sections = {k: v for k, v in fields.items() if k not in VehicleSpec.__dataclass_fields__}
    core = {k: v for k, v in fields.items() if k in VehicleSpec.__dataclass_fields__}
    core["name"] = core["name"] or ref
    if core["cg_to_front"] is None:
        core["cg_to_front"] = spec.length / 2
    return VehicleSpec(**core, sections=sections)

