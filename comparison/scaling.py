"""Scaling: the cost of a simulation against the size of the work, 2 to 32 vehicles of which one pair
collides (the PC-Crash side collision, studies/pc_crash/side.toml) while the others stand parked (speed 0)
or drive far apart, with each model's broad phase and sleeping on and off where it has them; and the import
time of `crashlab models` and of each model's first use. The evidence for "skip what a scene does not need".

Scenes (`scene`): the side collision's two Clios at the origin, the other n - 2 Clios (the library's "clio")
on a grid 12 m x 10 m starting 30 m beside the crash (no overlaps, far outside every broad phase's reach),
heading +x: "parked" at 0 km/h, "driving" at 50 km/h in parallel lanes (they never approach each other or
the crash). Duration DURATION = 4 s (the colliding pair is at rest by 2.3 s in every model; a parked scene
ends when everything sleeps, a driving scene lasts the duration), stop_at_rest as in side.toml.

Variants: "parked", "driving", and "<base>/no-sleep", "<base>/no-broad-phase" where a model can switch the
mechanism off (OFF_SWITCHES: the study options `sleeping`, `broad_phase` of a model's option schema, found
for plugins too; multibody's sleeping off is its t_sleep = 1e9 s). A mechanism a model does not have or
cannot switch is a row with ok = "n/a" and the reason in `note` (NOT_SWITCHABLE). Sleeping off: a vehicle at
rest is integrated at every step and the run lasts the duration; wall_per_sim_second separates the two
savings (fewer vehicles integrated, an earlier end).

Timing: each model instance is warmed up on the 2-vehicle scene (numba, multibody's settling cache); a cell
that runs under CHEAP_S is timed by comparison.base.timed (median of repeats after a warm-up), a longer one
once. Outputs: DIR/scaling.csv (the contract: model, n_vehicles, variant, wall_time_s; then t_end_s,
wall_per_sim_second, ok, steps, note), DIR/scaling_ratio.csv (per model and variant: wall time of the
largest scene against the 2-vehicle one), DIR/scaling_import.csv (what, model, seconds, numba_cache, note)
and DIR/scaling.png (log-log wall time against vehicles, one line per model and variant).

--quick: 2, 8, 32 vehicles (exudyn 2 and 8: a 32-vehicle exudyn run takes about a minute), import times
with the numba cache as found; the full run: 2, 4, 8, 16, 32 for every model and the first use also with an
empty numba cache (compilation).
"""
from __future__ import annotations

import math
import os
import subprocess
import sys
import tempfile
import time
import tomllib
from pathlib import Path

import pandas as pd

from crashlab.registry import get_model

from .base import STUDIES_DIR, output_dir, timed

SIZES = (2, 4, 8, 16, 32)
SIZES_QUICK = (2, 8, 32)
MAX_QUICK = {"exudyn": 8}  # slow models: largest scene in --quick
DURATION = 4.0  # s
GRID_DX, GRID_DY, GRID_Y0, GRID_COLUMNS = 12.0, 10.0, 30.0, 6  # m: where the other vehicles stand
DRIVING_KMH = 50.0
CHEAP_S = 0.5  # s: cells faster than this are timed as a median of repeats
REPEATS, REPEATS_QUICK = 5, 3
COLUMNS = ["model", "n_vehicles", "variant", "wall_time_s", "t_end_s", "wall_per_sim_second", "ok", "steps", "note"]
IMPORT_COLUMNS = ["what", "model", "seconds", "numba_cache", "note"]
RATIO_COLUMNS = ["model", "variant", "n_small", "n_large", "wall_small_s", "wall_large_s", "ratio",
                 "ratio_per_sim_second"]

# option values that switch a mechanism off, by model (plugins: the study options of their schema)
OFF_SWITCHES = {"multibody": {"sleeping": {"t_sleep": 1e9}}}
STUDY_OPTIONS = {"sleeping": {"sleeping": False}, "broad_phase": {"broad_phase": False}}
NOT_SWITCHABLE = {
    ("pymunk", "broad_phase"): "Chipmunk's broad phase (bounding-box tree) is built into the engine: always on",
    ("multibody", "broad_phase"): "needs a switch in crashlab.models.common.chassis_contact.contacts (skip the "
                                  "circle, height and OBB gates) passed through multibody's cfg",
    ("exudyn", "broad_phase"): "needs a switch in crashlab.models.common.chassis_contact.contacts (skip the "
                               "circle, height and OBB gates) passed through exudyn's _contact_loads",
    ("exudyn", "sleeping"): "no per-vehicle sleeping: exudyn's solver integrates every body at every step "
                            "(t_sleep only ends the run once every chassis is still)",
}
MECHANISMS = (("sleeping", "no-sleep"), ("broad_phase", "no-broad-phase"))


# ---------------------------------------------------------------- scenes
def scene_dict(n: int, base: str = "parked", duration: float = DURATION) -> dict:
    """The side collision with n - 2 more Clios on a grid beside it, parked or driving (file units)."""
    if n < 2:
        raise ValueError("n >= 2: one colliding pair")
    side = tomllib.loads((STUDIES_DIR / "pc_crash" / "side.toml").read_text())
    d = {k: v for k, v in side.items() if k != "reference"}
    d["name"] = f"side collision + {n - 2} {base}"
    d["duration"] = duration
    speed = 0.0 if base == "parked" else DRIVING_KMH
    d["vehicles"] = list(side["vehicles"]) + [
        {"name": f"{base[0].upper()}{q + 1}", "vehicle": "clio", "x": -30.0 + GRID_DX * (q % GRID_COLUMNS),
         "y": GRID_Y0 + GRID_DY * (q // GRID_COLUMNS), "heading": 0.0, "speed": speed}
        for q in range(n - 2)]
    return d


def scene(n: int, base: str = "parked", duration: float = DURATION):
    from crashlab.scene import start_overlaps
    from crashlab.scene_file import scene_from_dict
    s = scene_from_dict(scene_dict(n, base, duration), source=f"<scaling {n} {base}>")
    assert not start_overlaps(s), "scaling scene: vehicles overlap at the start"
    return s


# ---------------------------------------------------------------- variants
def switches(name: str) -> dict:
    """mechanism -> (options that switch it off, or None) and the reason when None."""
    from crashlab.registry import MODELS, load
    fields = getattr(getattr(load(MODELS, name), "Options", None), "model_fields", {})
    out = {}
    for mech, _ in MECHANISMS:
        if mech in OFF_SWITCHES.get(name, {}):
            out[mech] = (OFF_SWITCHES[name][mech], "")
        elif mech in fields:
            out[mech] = (STUDY_OPTIONS[mech], "")
        else:
            out[mech] = (None, NOT_SWITCHABLE.get((name, mech), f"the model has no option {mech!r}"))
    return out


def variants(name: str) -> list[tuple[str, str, dict | None, str]]:
    """(variant, base scene, options or None for n/a, note) of a model."""
    sw = switches(name)
    out = []
    for base in ("parked", "driving"):
        out.append((base, base, {}, ""))
        for mech, label in MECHANISMS:
            opts, why = sw[mech]
            out.append((f"{base}/{label}", base, opts, why))
    return out


def sizes_for(name: str, quick: bool) -> tuple[int, ...]:
    sizes = SIZES_QUICK if quick else SIZES
    if quick and name in MAX_QUICK:
        sizes = tuple(n for n in sizes if n <= MAX_QUICK[name])
    return sizes


# ---------------------------------------------------------------- timing
def measure(model, sc, repeats: int) -> dict:
    """One cell: wall time per simulation (timed when cheap, else one run), t_end, steps, ok."""
    try:
        t = time.perf_counter()
        out = model.simulate(sc)
        wall = time.perf_counter() - t
        if wall < CHEAP_S:
            out, wall = timed(lambda: model.simulate(sc), repeats)
    except Exception as err:  # a failed cell is recorded, the study goes on
        return {"wall_time_s": math.nan, "t_end_s": math.nan, "wall_per_sim_second": math.nan, "ok": False,
                "steps": math.nan, "note": f"{type(err).__name__}: {err}"[:200]}
    d = out.diagnostics
    t_end = float(d.get("t_end", math.nan) if hasattr(d, "get") else math.nan)
    ok = bool(out.outcome_ok)
    return {"wall_time_s": wall, "t_end_s": t_end,
            "wall_per_sim_second": wall / t_end if t_end and t_end > 0 else math.nan, "ok": ok,
            "steps": d.get("steps", math.nan), "note": "" if ok else "; ".join(out.warnings)[:200]}


def model_rows(name: str, quick: bool, sizes=None, variant_names=None, repeats=None) -> list[dict]:
    """The rows of scaling.csv for one model (sizes, variants: a subset for tests)."""
    sizes = sizes or sizes_for(name, quick)
    repeats = repeats or (REPEATS_QUICK if quick else REPEATS)
    rows = []
    scenes = {}
    for variant, base, opts, why in variants(name):
        if variant_names is not None and variant not in variant_names:
            continue
        if opts is None:
            rows += [{"model": name, "n_vehicles": n, "variant": variant, "wall_time_s": math.nan,
                      "t_end_s": math.nan, "wall_per_sim_second": math.nan, "ok": "n/a", "steps": math.nan,
                      "note": f"n/a: {why}"} for n in sizes]
            continue
        try:
            model = get_model(name, **opts)
            model.simulate(scene(2, base))  # warm-up: compilation, caches of this instance
        except Exception as err:
            rows += [{"model": name, "n_vehicles": n, "variant": variant, "wall_time_s": math.nan,
                      "t_end_s": math.nan, "wall_per_sim_second": math.nan, "ok": False, "steps": math.nan,
                      "note": f"{type(err).__name__}: {err}"[:200]} for n in sizes]
            continue
        for n in sizes:
            sc = scenes.setdefault((n, base), scene(n, base))
            rows.append({"model": name, "n_vehicles": n, "variant": variant, **measure(model, sc, repeats)})
    return rows


def ratios(df: pd.DataFrame) -> pd.DataFrame:
    """Per model and variant: wall time (and per simulated second) of the largest scene against the smallest."""
    out = []
    ran = df[df["ok"].astype(str) == "True"]
    for (model, variant), g in ran.groupby(["model", "variant"], sort=False):
        g = g.sort_values("n_vehicles")
        if len(g) < 2:
            continue
        a, b = g.iloc[0], g.iloc[-1]
        out.append({"model": model, "variant": variant, "n_small": int(a.n_vehicles), "n_large": int(b.n_vehicles),
                    "wall_small_s": a.wall_time_s, "wall_large_s": b.wall_time_s,
                    "ratio": b.wall_time_s / a.wall_time_s,
                    "ratio_per_sim_second": b.wall_per_sim_second / a.wall_per_sim_second})
    return pd.DataFrame(out, columns=RATIO_COLUMNS)


# ---------------------------------------------------------------- import time
_FIRST_USE = r"""
import time, json, os, sys
t0 = time.perf_counter()
import crashlab
t1 = time.perf_counter()
cache = os.environ.get("NUMBA_CACHE_DIR", "")
name = sys.argv[1]
files = sum(len(os.listdir(os.path.join(cache, d))) for d in (os.listdir(cache) if os.path.isdir(cache) else ())
            if d.startswith(name + "_") or d.startswith("common_"))  # numba's folders: <package>_<hash>
from crashlab.comparison.scaling import scene
sc = scene(2, "parked")
t2 = time.perf_counter()
m = crashlab.get_model(name)
out = m.simulate(sc)
t3 = time.perf_counter()
print(json.dumps({"import": t1 - t0, "first_use": t3 - t2, "cache_files": files, "ok": bool(out.outcome_ok)}))
"""


def _python(code: str, *args, env=None, timeout=900) -> tuple[float, str]:
    t = time.perf_counter()
    r = subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True, env=env,
                       timeout=timeout)
    wall = time.perf_counter() - t
    if r.returncode != 0:
        raise RuntimeError((r.stderr.strip().splitlines() or ["failed"])[-1])
    return wall, r.stdout


def import_rows(models: list[str], quick: bool) -> list[dict]:
    import json
    rows = []
    base = min(_python("pass")[0] for _ in range(3))
    rows.append({"what": "python startup", "model": "", "seconds": base, "numba_cache": "",
                 "note": "python -c pass, best of 3 (included in the next row)"})
    t = min(_python("import crashlab; crashlab.available_models()")[0] for _ in range(3))
    rows.append({"what": "crashlab models", "model": "", "seconds": t, "numba_cache": "",
                 "note": "python -c 'import crashlab; crashlab.available_models()', best of 3, interpreter "
                         "start included"})
    states = [("as found", None)] if quick else [("as found", None), ("empty", "cold")]
    for name in models:
        for label, cold in states:
            env = dict(os.environ)
            tmp = None
            if cold:
                tmp = tempfile.TemporaryDirectory(prefix="crashlab-numba-")
                env["NUMBA_CACHE_DIR"] = tmp.name
            try:
                _, text = _python(_FIRST_USE, name, env=env)
                r = json.loads(text.strip().splitlines()[-1])
                state = "empty (compiles)" if cold else ("warm" if r["cache_files"] else "empty (compiles)")
                rows.append({"what": "first use", "model": name, "seconds": r["first_use"], "numba_cache": state,
                             "note": f"get_model + simulate the 2-vehicle scene in a fresh process, after "
                                     f"import crashlab ({r['import']:.2f} s); {r['cache_files']} numba cache "
                                     f"files of the model and the common layer before"
                                     + ("" if r["ok"] else "; the run failed")})
            except Exception as err:
                rows.append({"what": "first use", "model": name, "seconds": math.nan, "numba_cache": label,
                             "note": f"failed: {err}"[:200]})
            finally:
                if tmp is not None:
                    tmp.cleanup()
    return rows


# ---------------------------------------------------------------- figure
def figure(df: pd.DataFrame, path: Path) -> Path:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    styles = {"": "-", "no-sleep": "--", "no-broad-phase": ":"}
    fig, axes = plt.subplots(1, 2, figsize=(12, 5), sharey=True)
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    models = list(dict.fromkeys(df["model"]))
    ran = df[df["ok"].astype(str) == "True"]
    for ax, base in zip(axes, ("parked", "driving")):
        for mi, model in enumerate(models):
            for (variant,), g in ran[ran["model"] == model].groupby(["variant"], sort=False):
                if variant.split("/")[0] != base:
                    continue
                switch = variant.split("/")[1] if "/" in variant else ""
                g = g.sort_values("n_vehicles")
                ax.loglog(g["n_vehicles"], g["wall_time_s"], styles.get(switch, "-."), marker="o", ms=3,
                          color=colours[mi % len(colours)], label=f"{model} {variant}")
        ns = sorted(set(df["n_vehicles"].dropna().astype(int)))
        ax.set_xticks(ns, [str(n) for n in ns])
        ax.minorticks_off()
        ax.set_xlabel("vehicles (one colliding pair)")
        ax.set_title(f"the others {base}")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    axes[0].set_ylabel("wall time per simulation [s]")
    fig.suptitle(f"Scaling: side collision + parked or driving Clios, {DURATION:g} s "
                 "(dashed: sleeping off, dotted: broad phase off)")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


# ---------------------------------------------------------------- the study
def run(models: list[str], out, quick: bool, system: str = "si") -> Path:
    """scaling.csv, scaling_ratio.csv, scaling_import.csv and scaling.png; the CSV's path. Its numbers are
    times and counts: the same in every `system`."""
    out = output_dir(out)
    rows = []
    for name in models:
        rows += model_rows(name, quick)
    df = pd.DataFrame(rows, columns=COLUMNS)
    path = out / "scaling.csv"
    df.to_csv(path, index=False)
    ratios(df).to_csv(out / "scaling_ratio.csv", index=False)
    pd.DataFrame(import_rows(models, quick), columns=IMPORT_COLUMNS).to_csv(out / "scaling_import.csv", index=False)
    figure(df, out / "scaling.png")
    return path


def rows_frame(rows: list[dict]) -> pd.DataFrame:
    """Rows of scaling.csv as its frame (exact columns)."""
    return pd.DataFrame(rows, columns=COLUMNS)
