"""What every comparison study shares: the models to compare, the output folder, timing, the scenes and
the error of a result against another."""
from __future__ import annotations

import math
import os
import statistics
import time
from pathlib import Path

import numpy as np

from crashlab.errors import InputError
from crashlab.registry import MODELS, UnknownPluginError, available_models, listed_models, load
from crashlab.scene import Scene
from crashlab.scene_file import load_scene
from crashlab.tools import examples
from crashlab.units import US_UNITS, frame_in, shown_name, unit_in, unit_of, value_in, wrap_deg

STUDIES_DIR = examples.root()  # the bundled studies/ (package data crashlab.examples)


# ---------------------------------------------------------------- shown units (`crashlab study --units`)
# The units map (crashlab.units) of every study's CSV columns: by their unit suffix ("error_m", "d_pc_crash_m",
# "speed_kmh"), and the few named without one; a table with a "unit" column (validation.csv) gives the unit of
# its ROW_UNIT_COLUMNS row by row. Degrees, seconds and counts stay as they are.
STUDY_UNITS = {"<quantity>_m": "m", "<quantity>_kmh": "km/h", "x": "m", "y": "m", "engagement_depth": "m",
               "delta_v": "km/h", "dvx": "km/h", "dvy": "km/h"}
ROW_UNIT_COLUMNS = ("published", "simulated", "error")


def shown_column(name: str, system: str) -> str:
    """A study column's name as shown in `system` ("error_m" -> "error_ft" in "us")."""
    return shown_name(name, unit_of(name, STUDY_UNITS), system)


def shown_rows(rows: list[dict], system: str) -> list[dict]:
    """Rows (dicts) of a study table with a "unit" column as shown in `system`: ROW_UNIT_COLUMNS of a row whose
    unit has a US form converted and its unit said (names kept); the rows themselves in "si"."""
    if system != "us":
        return rows
    out = []
    for r in rows:
        unit = r.get("unit", "")
        if unit in US_UNITS:
            r = {**r, **{c: value_in(r[c], unit, system) for c in ROW_UNIT_COLUMNS if c in r},
                 "unit": unit_in(unit, system)}
        out.append(r)
    return out


def shown_table(df, system: str):
    """A study's table (a pandas DataFrame) as shown in `system`: each column with a unit (STUDY_UNITS)
    converted and renamed (crashlab.units.frame_in), a "unit" column's rows by their unit (shown_rows)."""
    if system != "us":
        return df
    import pandas as pd
    if "unit" in df.columns:
        df = pd.DataFrame(shown_rows(df.to_dict(orient="records"), system), columns=df.columns)
    return frame_in(df, system, STUDY_UNITS)


def write_table(df, path, system: str = "si") -> Path:
    """A study's CSV file in `system`'s units (shown_table); its path."""
    shown_table(df, system).to_csv(path, index=False)
    return Path(path)


def resolve_models(spec: str | None) -> list[str]:
    """The models named on the command line (comma-separated), all registered ones for None."""
    if not spec:
        return available_models()
    try:
        names = listed_models(spec)
    except ValueError as err:
        raise InputError("command line", "--models", str(err)) from None
    for name in names:
        try:
            load(MODELS, name)
        except UnknownPluginError as err:
            raise InputError("command line", "--models", str(err)) from None
    return names


def output_dir(out) -> Path:
    """`out` created if needed; InputError when it cannot be written."""
    path = Path(out)
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise InputError(path, "--out", err.strerror or str(err)) from None
    if not path.is_dir() or not os.access(path, os.W_OK):
        raise InputError(path, "--out", "not a writable directory")
    return path


def timed(fn, repeats: int):
    """(last result, median wall time [s]) of `fn()` over `repeats` calls after one warm-up call (numba
    compiles, caches fill)."""
    result = fn()
    times = []
    for _ in range(max(1, repeats)):
        t = time.perf_counter()
        result = fn()
        times.append(time.perf_counter() - t)
    return result, statistics.median(times)


def bundled_scene(relative: str) -> Scene:
    """A scene file under studies/ (e.g. "pc_crash/side.toml")."""
    return load_scene(STUDIES_DIR / relative)


def pose_error(a: np.ndarray, b: np.ndarray) -> tuple[float, float]:
    """Largest distance [m] and largest wrapped heading difference [deg] between two sets of poses
    (n, 3: x, y [m], heading [rad]); NaN when either is not finite."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    if a.shape != b.shape or not (np.isfinite(a).all() and np.isfinite(b).all()):
        return math.nan, math.nan
    dist = float(np.max(np.hypot(a[:, 0] - b[:, 0], a[:, 1] - b[:, 1])))
    head = float(np.max(np.abs(wrap_deg(np.degrees(a[:, 2] - b[:, 2])))))
    return dist, head


def reference_poses(scene: Scene, source: str = "pc_crash") -> np.ndarray | None:
    """A published reference's rest poses (n, 3, SI) in the scene's vehicle order, None without one."""
    ref = scene.references.get(source)
    if not ref or any(n not in ref for n in scene.vehicle_names):
        return None
    return np.array([[ref[n]["x"], ref[n]["y"], math.radians(ref[n]["heading"])] for n in scene.vehicle_names])


# ----------------------------------------------------------------- accuracy knobs
def model_schema(name: str):
    """The model's option schema (None when it declares none)."""
    return getattr(load(MODELS, name), "Options", None)


def knob_value(default, direction: str, factor: float):
    """The knob's value `factor` times its default in the finer direction (factor < 1: finer): for a
    "smaller" knob default * factor, for a "larger" one default / factor; integers rounded (at least 1
    step away from the default when the factor is not 1)."""
    value = default * factor if direction == "smaller" else default / factor
    if isinstance(default, bool):
        return default
    if isinstance(default, int):
        value = int(round(value))
        if factor != 1 and value == default:  # at least one step away from the default
            finer_up = direction == "larger"
            value += 1 if finer_up == (factor < 1) else -1
    return value


def valid_setting(schema, setting: dict) -> bool:
    try:
        schema(**setting)
        return True
    except Exception:  # pydantic ValidationError or a model validator's ValueError: out of range
        return False


def knob_values(schema, knob: str, direction: str, factors) -> list[tuple[float, object]]:
    """(factor, value) of one knob, coarse -> fine, the schema's refused values and duplicates left out."""
    default = schema.model_fields[knob].default
    out, seen = [], set()
    for f in factors:
        try:
            v = knob_value(default, direction, f)
        except TypeError:  # a knob without a numeric default cannot be scaled
            return [(1.0, default)]
        if v in seen or not valid_setting(schema, {knob: v}):
            continue
        seen.add(v)
        out.append((f, v))
    return out
