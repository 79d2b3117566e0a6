"""Stability study (`crashlab study stability`): seeded random two-vehicle crashes, every model at its default
setting and at coarser-than-default settings of its accuracy knobs, each run judged by the physics guard.

The scene space (one scene per seed; `draw(seed)` rebuilds the scene of a CSV row from its `seed`):

  speed_kmh        5-200 km/h, uniform: the speed of V1 (heading 0); V2 drives at half of it
  angle_deg        0-180 deg, uniform: V2's heading against V1's (0 rear-end, 90 side, 180 head-on)
  mass_ratio       0.25-4, log-uniform: V1's mass over V2's; masses 1,400 kg x sqrt(ratio) and 1,400 kg /
                   sqrt(ratio) (700-2,800 kg; vehicle mass overrides, inertias scaled with the mass); the body
                   by mass: clio below 1,200 kg, saloon to 2,000 kg, suv above
  offset_m         -1 to 1 m, uniform: V1's path beside the crossing point
  restitution      0-0.5, impact_friction 0.1-0.6, road_friction 0.3-1.0, uniform
  wheels           each vehicle's wheel state, any of crashlab.scene.WHEEL_STATES ("V1/V2")

The vehicles are placed as `crashlab stress` places them ((crashlab.tools.stress)): both CGs due at the crossing point
0.4 s after the start (later, up to 4 s, where the outlines would overlap at the start); a draw whose
vehicles cannot start apart within 4 s (slow, nearly parallel) is skipped, so seeds have gaps. Duration
10 s, stopping at rest. The same seeded sample serves every model and setting (a coarse setting runs a
prefix of it), so rows of one seed compare.

Settings: the default ("{}") and, for each accuracy knob (crashlab.options.accuracy_knobs), the default made
coarser by x 2, x 4 and x 8 (the full run also x 16 and x 32; a step or a tolerance multiplied, an iteration
count divided), one knob at a time, within the option's declared range. --quick coarsens the step-size knob
only (the model's first accuracy knob with unit s, else its first knob); the full run coarsens every knob.

Per run (DIR/stability.csv, one row per run): ok (the Outcome's outcome_ok), violation (the guard's kinds,
Outcome.violations, joined by "|"), failure (a run not ok without a violation: its warnings, as a population
gives them, crashlab.population.outcome_reason: the first alone could be a note beside the reason; a model that
raises: "exception: Type: message"), step_collapse, wall_time_s, seed. A step collapse is a run whose
warnings say the step hit a limit (the step limit, the shortest step) or whose error control rejected at
least as many steps as it accepted (Diagnostics rejected_steps >= steps); it is reported, and it is a
failure only where the model says so.

Figures: DIR/stability_<model>.png, speed x angle bins at the default setting, colour = share of runs not ok
(the count in each cell). Summary: DIR/stability_summary.csv, per model at its default: runs, runs not ok,
violations by kind, failures, step collapses, median wall time, and its largest stable step (the coarsest
value of its step-size knob such that it and every finer tested value had zero violations and failures on
the scenes they all ran, the coarse settings' prefix of the sample; ">=" when it is the coarsest value
tested: the limit lies beyond); DIR/stability_settings.csv, the same per model and setting.

Size (runs at the default / per coarse setting): --quick impulse 200/100, pymunk 40/16, multibody 10/4,
exudyn 4/2, a plugin 10/4: 1 min 40 s for the four on 2 cores (measured); the full run impulse 2,000/500,
pymunk 200/40, multibody 40/10, exudyn 16/4, a plugin 100/20, every knob (about 20 minutes).
"""
from __future__ import annotations

import json
import math
import re
import time
from pathlib import Path

import numpy as np

from crashlab.options import accuracy_knobs, describe
from crashlab.population import outcome_reason
from crashlab.registry import get_model
from crashlab.scene import WHEEL_STATES
from crashlab.tools.stress import crash_scene as stress_scene  # the placement `crashlab stress` uses
from crashlab.units import unit_in, value_in

from .base import knob_values, model_schema, output_dir, write_table

SPEED = (5.0, 200.0)  # km/h, V1
V2_SHARE = 0.5  # V2's speed over V1's
ANGLE = (0.0, 180.0)  # deg
MASS_RATIO = (0.25, 4.0)  # V1 / V2, log-uniform
MASS_MEAN = 1400.0  # kg, the geometric mean of the two masses
OFFSET = (-1.0, 1.0)  # m
RESTITUTION = (0.0, 0.5)
IMPACT_FRICTION = (0.1, 0.6)
ROAD_FRICTION = (0.3, 1.0)
BODIES = ((1200.0, "clio"), (2000.0, "saloon"), (math.inf, "suv"))  # (mass below [kg], vehicle)
FACTORS = (2, 4, 8)  # --quick
FULL_FACTORS = (2, 4, 8, 16, 32)  # the full run, where the declared range allows
# runs at the default, runs per coarse setting
QUICK_RUNS = {"impulse": (200, 100), "pymunk": (40, 16), "multibody": (10, 4), "exudyn": (4, 2)}
FULL_RUNS = {"impulse": (2000, 500), "pymunk": (200, 40), "multibody": (40, 10), "exudyn": (16, 4)}
PLUGIN_RUNS = {True: (10, 4), False: (100, 20)}  # quick, full
COLLAPSE_WARNING = re.compile(r"step limit|shortest step|step collapsed", re.IGNORECASE)
SPEED_BINS = (5.0, 50.0, 100.0, 150.0, 200.0)  # km/h
ANGLE_BINS = (0.0, 45.0, 90.0, 135.0, 180.0)  # deg
PARAMS = ("speed_kmh", "angle_deg", "mass_ratio", "offset_m", "restitution", "impact_friction", "road_friction",
          "wheels")
COLUMNS = ("model", "setting", *PARAMS, "ok", "violation", "failure", "step_collapse", "wall_time_s", "seed")


# ---------------------------------------------------------------- scenes
def _body(mass: float) -> str:
    return next(kind for limit, kind in BODIES if mass < limit)


def draw(seed: int):
    """(parameters, scene) of one seed; the scene is None where the vehicles cannot start apart."""
    rng = np.random.default_rng(seed)
    p = {"speed_kmh": float(rng.uniform(*SPEED)), "angle_deg": float(rng.uniform(*ANGLE)),
         "mass_ratio": float(math.exp(rng.uniform(*np.log(MASS_RATIO)))), "offset_m": float(rng.uniform(*OFFSET)),
         "restitution": float(rng.uniform(*RESTITUTION)), "impact_friction": float(rng.uniform(*IMPACT_FRICTION)),
         "road_friction": float(rng.uniform(*ROAD_FRICTION))}
    wheels = [str(rng.choice(WHEEL_STATES)) for _ in range(2)]
    p["wheels"] = "/".join(wheels)
    m1, m2 = MASS_MEAN * math.sqrt(p["mass_ratio"]), MASS_MEAN / math.sqrt(p["mass_ratio"])
    v1 = {"kind": _body(m1), "mass": m1, "speed": p["speed_kmh"], "wheels": wheels[0]}
    v2 = {"kind": _body(m2), "mass": m2, "speed": V2_SHARE * p["speed_kmh"], "wheels": wheels[1]}
    impact = {"restitution": p["restitution"], "friction": p["impact_friction"]}
    scene = stress_scene(f"stability {seed}", v1, v2, p["angle_deg"], p["offset_m"], impact, p["road_friction"],
                         False)
    return p, scene


def sample(n: int, seed: int = 0) -> list[tuple[int, dict, object]]:
    """The first n drawable scenes from `seed` on: (seed, parameters, scene)."""
    out, k = [], seed
    while len(out) < n:
        p, scene = draw(k)
        if scene is not None:
            out.append((k, p, scene))
        k += 1
    return out


# ---------------------------------------------------------------- settings
def step_knob(name: str) -> str | None:
    """The model's step-size knob: its first accuracy knob with unit s, else its first accuracy knob."""
    rows = [r for r in describe(model_schema(name)) if r["accuracy"]]
    timed = [r["name"] for r in rows if r["unit"] == "s"]
    return (timed or [r["name"] for r in rows] or [None])[0]


def coarse_settings(name: str, knobs: list[str] | None = None, factors=FACTORS) -> list[tuple[str, int, dict]]:
    """(knob, factor, setting) for each knob (all accuracy knobs for None) made coarser by each factor,
    keeping only settings inside the option's declared range (base.knob_values, as the work-precision study)."""
    schema = model_schema(name)
    directions = accuracy_knobs(schema)
    return [(knob, f, {knob: value}) for knob in (directions if knobs is None else knobs)
            for f, value in knob_values(schema, knob, directions[knob], factors) if f != 1]


# ---------------------------------------------------------------- runs
def step_collapse(out) -> bool:
    """A warning about a step limit or the shortest step, or at least as many rejected as accepted steps."""
    if any(COLLAPSE_WARNING.search(w) for w in out.warnings):
        return True
    d = out.diagnostics
    return bool(d.steps and d.rejected_steps is not None and d.rejected_steps >= d.steps)


def run_setting(name: str, setting: dict, scenes) -> list[dict]:
    """One row per scene of `scenes` ((seed, parameters, scene)) for model `name` at `setting`."""
    rows = []
    label = json.dumps(setting, sort_keys=True)
    model = get_model(name, **setting)
    for seed, params, scene in scenes:
        t0 = time.perf_counter()
        try:
            out = model.simulate(scene)
            ok, violation = out.outcome_ok, "|".join(out.violations)
            failure = "" if ok or violation else outcome_reason(out)
            collapse = step_collapse(out)
        except Exception as err:  # a model that raises fails this run; the study goes on
            ok, violation, collapse = False, "", False
            failure = f"exception: {type(err).__name__}: {str(err).splitlines()[0] if str(err) else ''}"[:300]
        rows.append({"model": name, "setting": label, **params, "ok": bool(ok), "violation": violation,
                     "failure": failure, "step_collapse": collapse, "wall_time_s": time.perf_counter() - t0,
                     "seed": seed})
    return rows


def warm_up(name: str, scene) -> None:
    """One short run (compilers, caches), not recorded."""
    import dataclasses
    try:
        get_model(name).simulate(dataclasses.replace(scene, duration=0.3))
    except Exception:  # the recorded runs will say what is wrong
        pass


def runs_for(name: str, quick: bool) -> tuple[int, int]:
    return (QUICK_RUNS if quick else FULL_RUNS).get(name, PLUGIN_RUNS[quick])


def measure(models, runs, all_knobs: bool, factors=FACTORS, seed: int = 0, log=print):
    """The rows of every run: `runs(model) -> (runs at the default, runs per coarse setting)`."""
    import pandas as pd
    counts = {m: runs(m) for m in models}
    scenes = sample(max(max(c) for c in counts.values()), seed)
    rows = []
    for m in models:
        n_default, n_coarse = counts[m]
        knob = step_knob(m)
        settings = [(None, 1, {})]
        if knob is not None:
            settings += coarse_settings(m, None if all_knobs else [knob], factors)
        warm_up(m, scenes[0][2])
        t0 = time.perf_counter()
        for _, _, setting in settings:
            rows += run_setting(m, setting, scenes[:n_default if not setting else n_coarse])
        log(f"stability: {m}: {len(settings)} settings, {time.perf_counter() - t0:.1f} s")
    return pd.DataFrame(rows, columns=list(COLUMNS))


# ---------------------------------------------------------------- summaries
def _kinds(df) -> dict:
    kinds: dict = {}
    for v in df.violation:
        for k in filter(None, v.split("|")):
            kinds[k] = kinds.get(k, 0) + 1
    return kinds


def _cell(df) -> dict:
    kinds = _kinds(df)
    return {"runs": len(df), "not_ok": int((~df.ok).sum()),
            "violation_rate": float((df.violation != "").mean()) if len(df) else math.nan,
            "violations": "|".join(f"{k}:{n}" for k, n in sorted(kinds.items())),
            "failures": int((df.failure != "").sum()), "step_collapses": int(df.step_collapse.sum()),
            "median_wall_time_s": float(df.wall_time_s.median()) if len(df) else math.nan}


def settings_table(df):
    """Per model and setting: runs, runs not ok, violation rate and kinds, failures, step collapses, time."""
    import pandas as pd
    rows = []
    for (m, s), g in df.groupby(["model", "setting"], sort=False):
        rows.append({"model": m, "setting": s, **_cell(g)})
    return pd.DataFrame(rows)


def largest_stable_step(df, name: str) -> tuple[float, int]:
    """(value, scenes): the coarsest tested value of the model's step-size knob such that it and every finer
    tested value ran with zero violations and failures on the scenes they all ran and the default ran
    clean (a coarse setting runs a prefix of the default's sample; a scene that fails at the default fails
    for another reason than the step, and is counted in the default's violations); NaN when no scene is
    left."""
    knob = step_knob(name)
    if knob is None:
        return math.nan, 0
    default = model_schema(name).model_fields[knob].default
    finer_is_smaller = accuracy_knobs(model_schema(name))[knob] == "smaller"
    values = {default: df[(df.model == name) & (df.setting == "{}")]}
    for s, g in df[df.model == name].groupby("setting"):
        d = json.loads(s)
        if list(d) == [knob]:
            values[d[knob]] = g
    base = values[default]
    clean = set(base.seed[(base.violation.fillna("") == "") & (base.failure.fillna("") == "")])
    common = set.intersection(clean, *(set(g.seed) for g in values.values()))
    if not common:
        return math.nan, 0
    best = math.nan
    for v in sorted(values, reverse=not finer_is_smaller):
        g = values[v][values[v].seed.isin(common)]
        if not len(g) or (g.violation != "").any() or (g.failure != "").any():
            break
        best = v
    return best, len(common)


def summary_table(df):
    """Per model at its default setting, with its largest stable step."""
    import pandas as pd
    rows = []
    for m in dict.fromkeys(df.model):
        g = df[(df.model == m) & (df.setting == "{}")]
        knob = step_knob(m)
        coarse = df[(df.model == m) & (df.setting != "{}")]
        stable, scenes = largest_stable_step(df, m)
        tested = [json.loads(x)[knob] for x in coarse.setting.unique() if knob and list(json.loads(x)) == [knob]]
        default = model_schema(m).model_fields[knob].default if knob else math.nan
        coarsest = (max if accuracy_knobs(model_schema(m))[knob] == "smaller" else min)(
            tested, default=default) if knob else math.nan
        rows.append({"model": m, **_cell(g), "step_knob": knob or "",
                     "default_step": default,
                     "largest_stable_step": stable,
                     "coarsest_tested_step": coarsest, "stable_step_scenes": scenes,
                     "coarse_settings": coarse.setting.nunique(), "coarse_runs": len(coarse),
                     "coarse_not_ok": int((~coarse.ok).sum())})
    return pd.DataFrame(rows)


def heatmap(df, name: str, path: Path, system: str = "si") -> Path:
    """Speed x angle bins at the default setting, colour = share of runs not ok, count in each cell; the speed
    axis in `system`'s unit (km/h, or mph in "us": the bins' edges converted)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    g = df[(df.model == name) & (df.setting == "{}")]
    ns, na = len(SPEED_BINS) - 1, len(ANGLE_BINS) - 1
    total, bad = np.zeros((ns, na)), np.zeros((ns, na))
    i = np.clip(np.searchsorted(SPEED_BINS, g.speed_kmh, side="right") - 1, 0, ns - 1)
    j = np.clip(np.searchsorted(ANGLE_BINS, g.angle_deg, side="right") - 1, 0, na - 1)
    np.add.at(total, (i, j), 1)
    np.add.at(bad, (i, j), (~g.ok).to_numpy(dtype=float))
    share = np.where(total > 0, bad / np.maximum(total, 1), np.nan)
    fig, ax = plt.subplots(figsize=(5.5, 4.2))
    cmap = plt.get_cmap("Reds").with_extremes(bad="0.85")
    speed_bins = value_in(np.asarray(SPEED_BINS, dtype=float), "km/h", system)
    im = ax.pcolormesh(ANGLE_BINS, speed_bins, np.ma.masked_invalid(share), cmap=cmap, vmin=0, vmax=1)
    for a in range(ns):
        for b in range(na):
            if total[a, b]:
                ax.text((ANGLE_BINS[b] + ANGLE_BINS[b + 1]) / 2, (speed_bins[a] + speed_bins[a + 1]) / 2,
                        f"{int(bad[a, b])}/{int(total[a, b])}", ha="center", va="center", fontsize=9,
                        color="white" if share[a, b] > 0.5 else "black")
    ax.set_xlabel("impact angle [deg] (0 rear-end, 180 head-on)")
    ax.set_ylabel(f"speed of V1 [{unit_in('km/h', system)}]")
    ax.set_xticks(ANGLE_BINS)
    ax.set_yticks(speed_bins, [f"{v:.3g}" for v in speed_bins])
    ax.set_title(f"{name} at its default: runs not ok ({int((~g.ok).sum())} of {len(g)})")
    fig.colorbar(im, ax=ax, label="share not ok")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _describe(row) -> str:
    rate = f"{row.violation_rate:.1%}" if row.runs else "-"
    at_least = ">= " if row.largest_stable_step == row.coarsest_tested_step else ""
    step = (f"largest stable {row.step_knob} {at_least}{row.largest_stable_step:g} (default {row.default_step:g}, "
            f"coarsest tested {row.coarsest_tested_step:g}, judged on {row.stable_step_scenes} scenes; "
            f"{row.coarse_runs} coarse runs, {row.coarse_not_ok} not ok)") if row.step_knob else "no accuracy knobs"
    return (f"  {row.model}: {row.runs} runs at the default, {row.not_ok} not ok, violations {rate} "
            f"({row.violations or 'none'}), failures {row.failures}, step collapses {row.step_collapses}, "
            f"median {row.median_wall_time_s:.3g} s/run; {step}")


def study(models, out, runs, all_knobs: bool, factors=FACTORS, seed: int = 0, log=print, system: str = "si") -> Path:
    """Measure, write stability.csv (in `system`'s units: base.write_table, speed_kmh -> speed_mph and
    offset_m -> offset_ft in "us"), the heat maps and the summaries into `out`; returns the CSV's path."""
    out = output_dir(out)
    df = measure(models, runs, all_knobs, factors, seed, log)
    path = write_table(df, out / "stability.csv", system)
    settings_table(df).to_csv(out / "stability_settings.csv", index=False)
    summary = summary_table(df)
    summary.to_csv(out / "stability_summary.csv", index=False)
    for m in models:
        heatmap(df, m, out / f"stability_{m}.png", system)
    log("stability summary (default settings):")
    for row in summary.itertuples():
        log(_describe(row))
    return path


def run(models: list[str], out: Path, quick: bool, system: str = "si") -> Path:
    return study(models, out, lambda m: runs_for(m, quick), all_knobs=not quick,
                 factors=FACTORS if quick else FULL_FACTORS, system=system)
