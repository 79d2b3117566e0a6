"""Work-precision study (`crashlab study workprecision`): wall time against error for every model's
accuracy knobs, in the manner of DifferentialEquations.jl's work-precision diagrams.

For each model and scene (the three PC-Crash cases, the rigid-wall impact, the three-vehicle chain
collision of studies/comparison/three_vehicles.toml; `--quick`: side and rigid_wall) every accuracy knob
the model declares (crashlab.options.accuracy_knobs: name -> the direction that makes it finer) is swept
from coarse to fine around its default, the other knobs at their defaults: default x 4, x 2, x 1, / 2,
/ 4, / 8 in the finer direction (`--quick`: x 2 .. / 4); integers rounded; a value the option's schema
refuses (its declared range) is skipped. A model whose default run of a scene takes longer than
SLOW_RUN_S gets one refinement fewer on that scene (exudyn on the PC-Crash cases).

- Numerical error: the rest poses against the model's own converged result, every knob at its finest
  swept value at once. Its convergence is shown by a further refinement (every knob one step finer):
  that difference is `converged_check_m` / `converged_check_deg` of DIR/workprecision_converged.csv.
  When the converged run fails, the next coarser all-knob setting that runs is the reference instead
  (its factor is in the side table).
- Reference error (error_kind "reference"): the same rest poses against published ones where the scene
  has them (PC-Crash, `[reference.pc_crash]`).
- Error = comparison.base.pose_error: the largest position distance over the vehicles [m] and the
  largest heading difference [deg].
- Wall time: comparison.base.timed, the median of 3 runs after a warm-up (`--quick`: 1 run). The
  converged run and its check are timed once, without a warm-up.

Time on this 2-core machine (shared): `--quick`, all four models 2 min 21 s (exudyn 80 s of it). The
full run: impulse, pymunk and multibody 8 min 34 s (measured); exudyn about 24 min (estimated from its
quick cells: about 100 default runs' worth per PC-Crash case and on three_vehicles), so about 35 min.

A failed run (outcome_ok False, or an exception) is a row with error NaN and ok False; the study goes on.

Outputs: DIR/workprecision.csv (the contract: model, scene, setting, wall_time_s, error_m, error_deg,
error_kind; then knob, is_default, ok), DIR/workprecision_converged.csv (per model and scene: the
converged setting, its wall time, its check), and DIR/workprecision_<scene>.png: log wall time against
log numerical error, one line per model and knob through its default (a star); an x marks each model's
converged run at the height of its check, the floor below which the curve says nothing: an error below it
(a knob's finest value when the other knobs barely matter is almost the converged setting itself) is
drawn at the floor with an open marker. An error of exactly 0 is left out.

Convergence (measured with `--quick`; the side table of each run has the numbers): where
converged_check_m is not well below a model's errors, the bottom of that model's curve is not resolved.
- Converged: pymunk on side (check 0.19 mm against 5.7 mm at the default, dt decides; iterations and
  collision_slop change nothing); multibody and exudyn on rigid_wall (check below 0.002 mm).
- Not converged below about 2 mm: impulse on side (dt / 4 against dt / 8 differ by 1.6 mm, as much as
  the default's error 1.7 mm: its rest poses settle at the millimetre in the stop at v_rest); pymunk on
  rigid_wall (check 0.6 mm, default 1.2 mm).
- At the floor: multibody on side (check 0.07 mm, default 0.03 mm; its rtol/atol curves scatter between
  0.002 and 0.5 mm: the adaptive step's noise, not a trend); exudyn on side with `--quick` (finest step
  / 2: check 0.31 mm against 0.61 mm at the default, a factor 2 resolved).
"""
from __future__ import annotations

import json
import math
import time
from pathlib import Path

import numpy as np
import pandas as pd

from crashlab.errors import InputError
from crashlab.options import accuracy_knobs
from crashlab.registry import get_model
from crashlab.units import unit_in, value_in

from .base import (
    bundled_scene,
    knob_value,
    knob_values,
    model_schema,
    output_dir,
    pose_error,
    reference_poses,
    timed,
    valid_setting,
    write_table,
)

SCENES = {
    "head_on": "pc_crash/head_on.toml",
    "offset": "pc_crash/offset.toml",
    "side": "pc_crash/side.toml",
    "rigid_wall": "validation/rigid_wall.toml",
    "three_vehicles": "comparison/three_vehicles.toml",
}
QUICK_SCENES = ("side", "rigid_wall")
# multipliers of the default in the direction that makes a knob finer, coarse -> fine (1: the default)
FACTORS = (4.0, 2.0, 1.0, 0.5, 0.25, 0.125)
QUICK_FACTORS = (2.0, 1.0, 0.5, 0.25)
SLOW_RUN_S = 1.0  # a default run slower than this [s] drops the finest factor on that scene
REPEATS, QUICK_REPEATS = 3, 1

COLUMNS = ["model", "scene", "setting", "wall_time_s", "error_m", "error_deg", "error_kind"]
EXTRA_COLUMNS = ["knob", "is_default", "ok"]
CONVERGED_COLUMNS = ["model", "scene", "factor", "setting", "wall_time_s", "ok", "check_setting",
                     "check_wall_time_s", "check_ok", "converged_check_m", "converged_check_deg"]


# ----------------------------------------------------------------------------------- settings
def all_knobs(schema, knobs: dict, factor: float) -> dict:
    """Every knob at `factor` at once (a knob whose value the schema refuses stays at its finest valid
    value of the factors down to 1)."""
    setting = {}
    for knob, direction in knobs.items():
        default = schema.model_fields[knob].default
        f = factor
        while True:
            try:
                v = knob_value(default, direction, f)
            except TypeError:
                v = default
                break
            if valid_setting(schema, {**setting, knob: v}) or f >= 1:
                break
            f *= 2
        if v != default:
            setting[knob] = v
    return setting


def setting_json(setting: dict) -> str:
    return json.dumps(setting, sort_keys=True)


# ----------------------------------------------------------------------------------- runs
def check_knobs(models) -> None:
    """InputError for a model that declares no accuracy knob (nothing to sweep)."""
    for name in models:
        if not accuracy_knobs(model_schema(name)):
            raise InputError("command line", "--models", f"model {name!r} declares no accuracy knobs "
                             "(options with accuracy='smaller'/'larger'): nothing to sweep")


def _simulate(name: str, setting: dict, scene, repeats: int | None):
    """(rest poses or None, wall time [s], ok): timed (warm-up, median) when repeats is given, else once."""
    try:
        model = get_model(name, **setting)
        if repeats is None:
            t = time.perf_counter()
            out = model.simulate(scene)
            wall = time.perf_counter() - t
        else:
            out, wall = timed(lambda: model.simulate(scene), repeats)
    except Exception:  # noqa: BLE001 - a model that fails on a cell is recorded as failed
        return None, math.nan, False
    ok = bool(out.outcome_ok) and np.isfinite(out.rest_si).all()
    return (np.array(out.rest_si, float) if ok else None), wall, ok


def sweep(name: str, scene_key: str, scene, factors=FACTORS, repeats: int = REPEATS, knobs=None,
          slow_run_s: float | None = SLOW_RUN_S, log=None):
    """One model on one scene: (rows of workprecision.csv, the row of workprecision_converged.csv).

    `knobs`: the knobs to sweep (default: every accuracy knob of the model); the converged result always
    sets every accuracy knob to the finest factor."""
    schema = model_schema(name)
    all_k = accuracy_knobs(schema)
    swept = {k: d for k, d in all_k.items() if knobs is None or k in knobs}
    ref = reference_poses(scene, "pc_crash")
    factors = sorted(set(factors) | {1.0}, reverse=True)

    t0 = time.perf_counter()
    runs = []  # (knob, factor, setting, rest, wall, ok)
    rest, wall, ok = _simulate(name, {}, scene, repeats)
    runs.append(("", 1.0, {}, rest, wall, ok))
    if slow_run_s is not None and ok and wall > slow_run_s and len([f for f in factors if f < 1]) > 1:
        factors = factors[:-1]
    for knob, direction in swept.items():
        for f, v in knob_values(schema, knob, direction, factors):
            if f == 1.0:
                continue
            setting = {knob: v}
            rest_k, wall_k, ok_k = _simulate(name, setting, scene, repeats)
            runs.append((knob, f, setting, rest_k, wall_k, ok_k))

    # the converged result: every knob at the finest factor (or the next coarser that runs), checked
    # by one refinement further
    finest = min(factors)
    conv = {"model": name, "scene": scene_key, "factor": math.nan, "setting": "", "wall_time_s": math.nan,
            "ok": False, "check_setting": "", "check_wall_time_s": math.nan, "check_ok": False,
            "converged_check_m": math.nan, "converged_check_deg": math.nan}
    reference = None
    f = finest
    while f <= 1.0 and all_k:
        setting = all_knobs(schema, all_k, f)
        rest_c, wall_c, ok_c = _simulate(name, setting, scene, None)
        conv.update(factor=f, setting=setting_json(setting), wall_time_s=wall_c, ok=ok_c)
        if ok_c:
            reference = rest_c
            break
        f *= 2
    if reference is not None:
        check = all_knobs(schema, all_k, f / 2)
        rest_x, wall_x, ok_x = _simulate(name, check, scene, None)
        conv.update(check_setting=setting_json(check), check_wall_time_s=wall_x, check_ok=ok_x)
        if ok_x:
            m, deg = pose_error(rest_x, reference)
            conv.update(converged_check_m=m, converged_check_deg=deg)

    rows = []
    for knob, _f, setting, rest, wall, ok in runs:
        base = {"model": name, "scene": scene_key, "setting": setting_json(setting), "wall_time_s": wall,
                "knob": knob, "is_default": not setting, "ok": ok}
        kinds = [("numerical", reference)] + ([("reference", ref)] if ref is not None else [])
        for kind, target in kinds:
            m, deg = (pose_error(rest, target) if ok and target is not None else (math.nan, math.nan))
            rows.append({**base, "error_m": m, "error_deg": deg, "error_kind": kind})
    if log:
        log(f"workprecision: {name} on {scene_key}: {len(runs)} settings, "
            f"{time.perf_counter() - t0:.1f} s, converged check {conv['converged_check_m']:.3g} m")
    return rows, conv


def study(models, scene_keys, factors=FACTORS, repeats: int = REPEATS, knobs=None,
          slow_run_s: float | None = SLOW_RUN_S, log=None) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Every model on every scene: (workprecision table, converged table)."""
    rows, convs = [], []
    for key in scene_keys:
        scene = bundled_scene(SCENES[key])
        for name in models:
            r, c = sweep(name, key, scene, factors, repeats, knobs, slow_run_s, log)
            rows += r
            convs.append(c)
    df = pd.DataFrame(rows, columns=COLUMNS + EXTRA_COLUMNS)
    return df, pd.DataFrame(convs, columns=CONVERGED_COLUMNS)


# ----------------------------------------------------------------------------------- outputs
def plot(df: pd.DataFrame, conv: pd.DataFrame, scene_key: str, path: Path, system: str = "si") -> Path:
    """The work-precision diagram of one scene: log wall time against log numerical error (in m, or ft with
    system "us")."""
    # the errors in the shown unit (the columns keep their names here)
    df = df.assign(error_m=value_in(df.error_m, "m", system))
    conv = conv.assign(converged_check_m=value_in(conv.converged_check_m, "m", system))
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    d = df[(df.scene == scene_key) & (df.error_kind == "numerical")]
    fig, ax = plt.subplots(figsize=(7.5, 5))
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    markers = "osD^vP<>h"
    for i, (name, g) in enumerate(d.groupby("model", sort=False)):
        color = colors[i % len(colors)]
        c = conv[(conv.scene == scene_key) & (conv.model == name)]
        floor = float(c.converged_check_m.iloc[0]) if len(c) else math.nan
        floor = floor if np.isfinite(floor) and floor > 0 else 0.0
        default = g[g.is_default]
        directions = accuracy_knobs(model_schema(name))
        for j, knob in enumerate(k for k in g.knob.unique() if isinstance(k, str) and k):
            line = pd.concat([g[g.knob == knob], default])
            schema_default = model_schema(name).model_fields[knob].default
            value = [json.loads(st).get(knob, schema_default) for st in line.setting]
            sign = -1 if directions.get(knob) == "smaller" else 1  # coarse -> fine
            line = line.iloc[np.argsort([sign * v for v in value], kind="stable")]
            line = line[line.ok & (line.error_m > 0)]
            if not len(line):
                continue
            err = np.maximum(line.error_m.to_numpy(), floor)  # below the check: not resolved
            marker = markers[j % len(markers)]
            ax.plot(line.wall_time_s, err, color=color, marker=marker, ms=4, lw=1,
                    ls="-" if j == 0 else (0, (4, 1 + j)), label=f"{name}: {knob}")
            low = line.error_m.to_numpy() < floor
            if low.any():
                ax.plot(line.wall_time_s[low], err[low], marker, color="white", mec=color, ms=6, zorder=4)
        default = default[default.ok & (default.error_m > 0)]
        if len(default):
            ax.plot(default.wall_time_s, np.maximum(default.error_m, floor), "*", color=color, ms=15, mec="k",
                    zorder=5)
        if floor > 0:
            ax.plot(c.wall_time_s, [floor], "x", color=color, ms=9, mew=2)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("wall time per simulation [s]")
    ax.set_ylabel(f"numerical error: largest rest-position distance\nto the converged result [{unit_in('m', system)}]")
    ax.set_title(f"work-precision: {scene_key}. Star: default; x: the converged run's check (one step finer), "
                 "open: error below it, drawn at it", fontsize=8)
    ax.grid(alpha=0.3, which="both")
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def write(df: pd.DataFrame, conv: pd.DataFrame, out: Path, system: str = "si") -> Path:
    """workprecision.csv and workprecision_converged.csv in `system`'s units (base.write_table: error_m ->
    error_ft in "us"), a figure per scene; the CSV's path."""
    out = Path(out)
    path = write_table(df, out / "workprecision.csv", system)
    write_table(conv, out / "workprecision_converged.csv", system)
    for key in df.scene.unique():
        plot(df, conv, key, out / f"workprecision_{key}.png", system)
    return path


def run(models: list[str], out: Path, quick: bool = False, system: str = "si") -> Path:
    """`crashlab study workprecision`: the sweep of every model's accuracy knobs; returns the CSV path."""
    check_knobs(models)
    out = output_dir(out)
    scenes = QUICK_SCENES if quick else tuple(SCENES)
    df, conv = study(models, scenes, QUICK_FACTORS if quick else FACTORS,
                     QUICK_REPEATS if quick else REPEATS, log=lambda msg: print(msg, flush=True))
    return write(df, conv, out, system)
