"""`crashlab damage SCENE|VEHICLE --side S --profile C1,...,Cn --width W [--with ...]`: the command's inputs
read from the command line, the work done by crashlab.damage (docs/physics.md §28)."""
from __future__ import annotations

import json
from pathlib import Path

from ..damage import check_profile, format_report, pair_report, report
from ..errors import InputError
from ..input_files import read_toml
from ..scene_file import load_scene
from ..vehicle import VehicleSpec, load_vehicle


def parse_profile(text: str, key: str = "--profile", where: str = "command line") -> list[float]:
    """'C1,...,Cn' (metres, comma separated) as a checked profile."""
    try:
        values = [float(t) for t in str(text).split(",")]
    except ValueError:
        raise InputError(where, key, f"comma-separated crush depths in metres, got {text!r}") from None
    return check_profile(values, key, where)


def is_scene(target: str) -> bool:
    """A `crashlab damage` target that is a scene file (a .toml file with [[vehicles]])."""
    return target.endswith(".toml") and Path(target).is_file() and "vehicles" in read_toml(Path(target), "scene")


def vehicle_for(target: str, vehicle: str | None = None, where: str = "command line", key: str = "--vehicle",
                target_key: str = "target") -> VehicleSpec:
    """The vehicle of `crashlab damage SCENE|VEHICLE`: a library vehicle's name or a vehicle file; a .toml file
    with [[vehicles]] is a scene, and `vehicle` names one of its vehicles (may be left out when it has one).
    Errors name `key` (the option naming a scene's vehicle) or `target_key` (the option naming the vehicle)."""
    if is_scene(target):
        scene = load_scene(target)
        names = [v.name for v in scene.vehicles]
        if vehicle is None:
            if len(names) != 1:
                raise InputError(where, key, f"the scene has {len(names)} vehicles: name one of "
                                 f"{', '.join(names)}")
            return scene.vehicles[0].spec
        if vehicle not in names:
            raise InputError(where, key, f"no vehicle {vehicle!r} in {target}: one of {', '.join(names)}")
        return scene.vehicles[names.index(vehicle)].spec
    if target.endswith(".toml") and Path(target).is_file() and "scene" in read_toml(Path(target), "study"):
        raise InputError(target, target_key, "a study file: give its scene file (its `scene` key) or a vehicle")
    if vehicle is not None:
        raise InputError(where, key, "names a vehicle of a scene; the target is a vehicle")
    return load_vehicle(target, base_dir=Path.cwd(), where=target_key, scene_file=where)


def parse_other(text: str, key: str = "--with", where: str = "command line") -> dict:
    """'VEHICLE:SIDE:C1,...,Cn:WIDTH[:OFFSET[:PDOF]]' (metres, degrees) as report arguments + the vehicle."""
    parts = str(text).split(":")
    if not 4 <= len(parts) <= 6:
        raise InputError(where, key, f"VEHICLE:SIDE:C1,...,Cn:WIDTH[:OFFSET[:PDOF]], got {text!r}")
    try:
        nums = [float(t) for t in parts[3:]]
    except ValueError:
        raise InputError(where, key, f"WIDTH, OFFSET and PDOF are numbers (m, m, deg), got {text!r}") from None
    return dict(vehicle=parts[0], side=parts[1], profile=parse_profile(parts[2], f"{key} profile", where),
                width=nums[0], offset=nums[1] if len(nums) > 1 else 0.0, pdof=nums[2] if len(nums) > 2 else None)


def command(target: str, side: str, profile: str, width: float, offset: float = 0.0, pdof: float | None = None,
            vehicle: str | None = None, other: str | None = None, restitution: float = 0.0,
            as_json: bool = False) -> str:
    """What `crashlab damage` prints: one vehicle's damage (`report`), or with `other` (parse_other: a second
    vehicle of the same scene, or a library vehicle or vehicle file when the target is a vehicle) both and
    their delta-V (`pair_report`); text (`format_report`) or JSON. Bad input: InputError naming the option."""
    spec = vehicle_for(target, vehicle)
    rep = report(spec, side, parse_profile(profile), width, offset, pdof, "command line", "--")
    if is_scene(target):  # the scene's name of the vehicle first: two of one model are told apart
        own = vehicle if vehicle is not None else load_scene(target).vehicles[0].name
        rep["vehicle"] = f"{own} ({rep['vehicle']})"
    if other is not None:
        o = parse_other(other)
        name = o.pop("vehicle")
        if is_scene(target):
            own = vehicle if vehicle is not None else load_scene(target).vehicles[0].name
            if name == own:
                raise InputError("command line", "--with", f"{name!r} is the damaged vehicle itself: name the "
                                 "scene's other vehicle of the impact")
            spec2 = vehicle_for(target, name, key="--with")
        else:
            spec2 = vehicle_for(name, target_key="--with")
        rep2 = report(spec2, o["side"], o["profile"], o["width"], o["offset"], o["pdof"], "command line",
                      "--with ")
        if is_scene(target):
            rep2["vehicle"] = f"{name} ({rep2['vehicle']})"
        elif rep2["vehicle"] == rep["vehicle"]:  # two of one model: told apart by where they were given
            rep["vehicle"], rep2["vehicle"] = f"{rep['vehicle']} (the first)", f"{rep2['vehicle']} (--with)"
        if not (isinstance(restitution, (int, float)) and 0.0 <= restitution < 1.0):
            raise InputError("command line", "--restitution", f"in [0, 1), got {restitution!r}")
        rep = pair_report(rep, rep2, restitution)
    elif restitution:
        raise InputError("command line", "--restitution", "only with --with (the delta-V of two vehicles)")
    return json.dumps(rep, indent=2) if as_json else format_report(rep)
