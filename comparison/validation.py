"""`crashlab study validation`: every model on the published tests under studies/validation.

The tests and their published quantities are listed in studies/validation/published/tests.toml (each
number with its source; studies/validation/README.md lists the sources). Every model runs every test's
scene with one parameter set for all tests (the scenes' [impact] friction and laws, road friction 0.8);
nothing is fitted per test. Variants, each one constant to extend:
  IMPACT_LAWS           every [impact] law of the scene schema (read from its Literal), for the models in
                        LAW_MODELS (the others do not read it: law "-")
  RESTITUTION_VARIANTS  the [impact] restitution settings each run is repeated with
  contact               "given": the scene's own [impact] point and plane_angle (PC-Crash style, the
                        published collision position), for the models that read it (reads_collision_position);
                        "found": the model finds its own contact, from the scene as written or, for a scene
                        with a given point, from crashlab.scene.approach_scene (the cars moved back along their
                        velocities until apart); "engagement": as "found" with [impact] point = "engagement" at
                        the default engagement_depth (docs/physics.md §4), for the models that read "given"

Quantities (simulated side):
  delta_v        |sum of the vehicle's impact-row velocity changes| [km/h] (Outcome.impact_rows, SI)
  impact_delta_v |velocity change of the vehicle's first impact row| [km/h]: the first impact (contact
                 episode) alone, for tests whose published delta-V is the impact's alone
  impact_yaw_rate_change  |yaw-rate change of that row| [deg/s]
  rebound_speed  speed right after the impact [km/h]: velocity at first contact + the summed delta-V
  post_vx        global x velocity right after the impact [km/h] (same construction)
  pdof           principal direction of force of the vehicle's largest impact row [deg]
  crush_dynamic, crush_residual   deepest contact overlap of the run [m] (Diagnostics.max_penetration);
                 none for a model without a contact depth (CollisionModel.contact_depth False):
                 simulated NaN, ok None ("n/a"), neither pass nor fail
Per run also: impacts (impact rows' distinct times), slip_reversed (any impact row flagged: the slip
stops and reverses, where kudlich-slibar and brach are outside their assumptions, docs/physics.md §3) and
warnings (the Outcome's warnings, e.g. restitution = "speed" held at its end value outside the law's data,
§13b): in the CSV, numbered in validation.md, and per test and model on stderr.

Writes DIR/validation.csv (model, test, quantity, published, simulated, error, error_pct, then unit,
source, ok, kind, vehicle, law, restitution, contact, impacts, slip_reversed, warnings), DIR/validation.md and
DIR/validation_dv.png (simulated against measured delta-V of the crash tests), and the runs' warnings on stderr.
A run that fails (an exception, or outcome_ok False) gives rows with simulated NaN and ok False; the study
goes on.
"""
from __future__ import annotations

import csv
import dataclasses
import math
import time
import tomllib
import typing
from pathlib import Path

from crashlab.outcome import collision_rows
from crashlab.scene import approach_scene
from crashlab.units import unit_in

from .base import STUDIES_DIR, shown_rows

VALIDATION_DIR = STUDIES_DIR / "validation"
TESTS_FILE = VALIDATION_DIR / "published" / "tests.toml"
COLUMNS = ["model", "test", "quantity", "published", "simulated", "error", "error_pct", "unit", "source", "ok",
           "kind", "vehicle", "law", "restitution", "contact", "impacts", "slip_reversed", "warnings"]
FULL_MODELS = ("impulse", "pymunk")  # --quick runs every test for these, QUICK_TESTS for the others
QUICK_TESTS = ("nhtsa10146",)


def _schema_laws() -> tuple[str, ...]:
    from crashlab.scene_file import ImpactFile
    return typing.get_args(ImpactFile.model_fields["law"].annotation)


IMPACT_LAWS = _schema_laws()   # every impulse law of the scene schema's [impact] law (a new one joins itself)
LAW_MODELS = ("impulse",)      # the models that read [impact] law (docs/physics.md §3)
# [impact] restitution of every run: the documented constant 0.1 and the law of the closing speed "speed"
# (docs/physics.md §13b); each test is run with both
RESTITUTION_VARIANTS: tuple = (0.1, "speed")
DV_QUANTITIES = ("delta_v", "impact_delta_v")  # the delta-V quantities (figure, goal check)
CRUSH_QUANTITIES = ("crush_dynamic", "crush_residual")
GOAL_PCT = {"impulse": 10.0, "multibody": 15.0, "exudyn": 15.0}  # issue 24's goal on car-to-car delta-V
FIGURE = "validation_dv.png"


def load_tests(path: Path = TESTS_FILE) -> list[dict]:
    """The tests of tests.toml: dicts with id, scene (path), kind, source, quantity (list of dicts)."""
    with open(path, "rb") as fh:
        data = tomllib.load(fh)
    tests = []
    for t in data["test"]:
        tests.append({**t, "scene": path.parent.parent / t["scene"], "quantity": list(t.get("quantity", []))})
    return tests


def variant_scene(path: Path, law: str | None = None, restitution=None, **impact):
    """The scene of `path` with [impact] law and restitution (and any other [impact] keys in `impact`) set
    as in the file's units (None: the file's own); set on the file's data, so any value the schema takes (a
    number, or a law's name) works."""
    from crashlab.scene_file import scene_from_dict
    with open(path, "rb") as fh:
        data = tomllib.load(fh)
    imp = data.setdefault("impact", {})
    if law is not None:
        imp["law"] = law
    if restitution is not None:
        imp["restitution"] = restitution
    imp.update(impact)
    return scene_from_dict(data, source=path, base_dir=path.parent)


def _vehicle_rows(outcome, name: str) -> list[dict]:
    return [r for r in outcome.impact_rows if r["vehicle"] == name]


def _post_velocity(outcome, scene, name: str) -> tuple[float, float]:
    """Global velocity right after the impacts [m/s]: at first contact (its heading and speed, or the
    start state without contact) plus the summed impact-row velocity changes."""
    i = scene.vehicle_names.index(name)
    head, speed = outcome.contact_si[i, 2], outcome.contact_si[i, 3]
    if not (math.isfinite(head) and math.isfinite(speed)):
        v = scene.vehicles[i]
        head, speed = v.heading, v.speed
    rows = _vehicle_rows(outcome, name)
    return (speed * math.cos(head) + sum(r["dvx"] for r in rows),
            speed * math.sin(head) + sum(r["dvy"] for r in rows))


def reads_collision_position(model: str) -> bool:
    """Whether the model resolves an impact at a given collision position ([impact] point and plane_angle, or
    point = "engagement": CollisionModel.collision_position, docs/physics.md §4); the others find their own
    contacts and are run from the approach alone."""
    from crashlab.registry import MODELS, load
    return load(MODELS, model).collision_position


def has_quantity(model: str, quantity: str) -> bool:
    """False when the model cannot give this quantity at all (a crush of a model without a contact depth,
    CollisionModel.contact_depth): its row of a run that succeeded is "n/a", neither pass nor fail."""
    from crashlab.registry import MODELS, load
    return quantity not in CRUSH_QUANTITIES or load(MODELS, model).contact_depth


def simulated_quantity(outcome, scene, quantity: str, vehicle: str) -> float:
    """One quantity of `outcome` in the study's units (km/h, deg, deg/s, m); NaN when the run has none."""
    rows = _vehicle_rows(outcome, vehicle)
    if quantity == "delta_v":
        if not rows:
            return math.nan
        return 3.6 * math.hypot(sum(r["dvx"] for r in rows), sum(r["dvy"] for r in rows))
    if quantity in ("impact_delta_v", "impact_yaw_rate_change"):
        if not rows:
            return math.nan
        first = min(rows, key=lambda r: r["t"])
        if quantity == "impact_delta_v":
            return 3.6 * math.hypot(first["dvx"], first["dvy"])
        return abs(math.degrees(first["d_yaw_rate"]))
    if quantity in ("rebound_speed", "post_vx"):
        if not rows:
            return math.nan
        vx, vy = _post_velocity(outcome, scene, vehicle)
        return 3.6 * (math.hypot(vx, vy) if quantity == "rebound_speed" else vx)
    if quantity == "pdof":
        if not rows:
            return math.nan
        big = max(rows, key=lambda r: math.hypot(r["dvx"], r["dvy"]))
        return math.degrees(big.get("pdof", math.nan))
    if quantity in ("crush_dynamic", "crush_residual"):
        pen = outcome.diagnostics.max_penetration
        return math.nan if pen is None else float(pen)
    raise ValueError(f"unknown quantity {quantity!r}")


def _simulate(model_name: str, scene):
    """(outcome or None, reason) of one run; never raises."""
    from crashlab.registry import get_model
    try:
        outcome = get_model(model_name).simulate(scene)
    except Exception as err:  # a model that fails on a cell is recorded as failed for that cell
        return None, f"{type(err).__name__}: {err}".splitlines()[0][:200]
    if not outcome.outcome_ok:
        return None, "; ".join(outcome.warnings)[:200] or "outcome_ok False"
    return outcome, ""


def _fmt(x: float, nd: int = 3) -> str:
    return "" if x is None or not math.isfinite(x) else f"{x:.{nd}f}"


def runs(model: str, test: dict) -> list[dict]:
    """The variants one model runs on one test: dicts law ("-": the model does not read it), restitution,
    contact ("given" / "found")."""
    laws = IMPACT_LAWS if model in LAW_MODELS else ("-",)
    with open(test["scene"], "rb") as fh:
        has_point = "point" in tomllib.load(fh).get("impact", {})
    given = reads_collision_position(model)
    contacts = ("given", "found") if has_point and given else ("found",)
    contacts += ("engagement",) if given else ()
    return [{"law": law, "restitution": e, "contact": c}
            for law in laws for e in RESTITUTION_VARIANTS for c in contacts]


def validation_rows(models: list[str], quick: bool = False, tests: list[dict] | None = None) -> list[dict]:
    """One row per (model, variant, test, published quantity)."""
    tests = load_tests() if tests is None else tests
    rows = []
    for model in models:
        for t in tests:
            if quick and model not in FULL_MODELS and t["id"] not in QUICK_TESTS:
                continue
            for run_ in runs(model, t):
                scene = variant_scene(t["scene"], None if run_["law"] == "-" else run_["law"], run_["restitution"])
                if run_["contact"] in ("found", "engagement"):
                    # built here (not left to the model's base class): the quantities are read against this scene,
                    # and the runs carry no approach warning
                    scene = approach_scene(scene)
                if run_["contact"] == "engagement":
                    scene = scene.replace(impact=dataclasses.replace(scene.impact, engagement=True))
                outcome, reason = _simulate(model, scene)
                impacts = 0 if outcome is None else len({r["t"] for r in collision_rows(outcome.impact_rows)})
                reversed_ = outcome is not None and any(r.get("slip_reversed", False) for r in outcome.impact_rows)
                warnings = () if outcome is None else tuple(dict.fromkeys(str(w) for w in outcome.warnings))
                for q in t["quantity"]:
                    sim, why = math.nan, reason
                    if outcome is not None and not has_quantity(model, q["name"]):  # (a failed run: failed rows)
                        why = f"n/a: the {model} model has no contact depth"
                    elif outcome is not None:
                        try:
                            sim = simulated_quantity(outcome, scene, q["name"], q["vehicle"])
                        except Exception as err:  # a broken outcome: failed cell, not a failed study
                            why = f"{type(err).__name__}: {err}"[:200]
                    pub = float(q["published"])
                    # None: the model has no such quantity (n/a), neither pass nor fail
                    ok = None if why.startswith("n/a") else outcome is not None and math.isfinite(sim)
                    err = sim - pub if ok else math.nan
                    rows.append({"model": model, "test": t["id"], "quantity": q["name"], "published": pub,
                                 "simulated": sim, "error": err,
                                 "error_pct": 100.0 * err / abs(pub) if ok and pub != 0 else math.nan,
                                 "unit": q.get("unit", ""), "source": t["source"], "ok": ok, "kind": t["kind"],
                                 "vehicle": q["vehicle"], "law": run_["law"], "restitution": run_["restitution"],
                                 "contact": run_["contact"], "impacts": impacts, "slip_reversed": reversed_,
                                 "warnings": warnings, "car_to_car": len(scene.vehicles) > 1, "_reason": why})
    return rows


def write_csv(rows: list[dict], path: Path, system: str = "si") -> Path:
    """validation.csv, each row's published, simulated and error in `system`'s unit (base.shown_rows: its unit
    column says which)."""
    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=COLUMNS, extrasaction="ignore")
        w.writeheader()
        for r in shown_rows(rows, system):
            w.writerow({**r, **{k: repr(float(r[k])) for k in ("published", "simulated", "error", "error_pct")},
                        "warnings": "\n".join(r.get("warnings", ()))})  # one a line; ok None: "" (n/a)
    return path


def _shown_ok(ok) -> str:
    return "n/a" if ok is None else str(ok)


def run_warnings(rows: list[dict]) -> list[dict]:
    """Per test and model, each kind of warning its runs gave (crashlab.warning_groups: numbers that differ
    between the runs as their range), the number of runs that gave it, of how many, and the variants (law,
    restitution, contact) that gave it: dicts test, model, warning, runs, of, variants."""
    from crashlab.warning_groups import group
    per_run = {}  # (test, model) -> {variant: warnings}; a run's warnings are on each of its rows
    for r in rows:
        per_run.setdefault((r["test"], r["model"]), {})[(r["law"], r["restitution"], r["contact"])] = \
            r.get("warnings", ())
    out = []
    for (test, model), runs_ in per_run.items():
        variants = list(runs_)
        for text, which in group(runs_.values()):
            out.append({"test": test, "model": model, "warning": text, "runs": len(which), "of": len(runs_),
                        "variants": [variants[k] for k in which]})
    return out


def print_warnings(rows: list[dict], file=None) -> None:
    """The runs' warnings (run_warnings) on `file` (stderr): one line per test, model and kind."""
    import sys
    file = file or sys.stderr
    for w in run_warnings(rows):
        print(f"validation warning: {w['test']}, {w['model']}, {w['runs']} of {w['of']} runs: {w['warning']}",
              file=file)


def goal_rows(rows: list[dict]) -> list[dict]:
    """Per model and variant: the largest |error %| of delta-V over the car-to-car crash tests, against the
    issue's goal (GOAL_PCT; no goal for the other models)."""
    out = {}
    for r in rows:
        if r["kind"] != "crash test" or r["quantity"] not in DV_QUANTITIES or not r["car_to_car"]:
            continue
        key = (r["model"], r["law"], r["restitution"], r["contact"])
        g = out.setdefault(key, {"model": r["model"], "law": r["law"], "restitution": r["restitution"],
                                 "contact": r["contact"], "worst_pct": 0.0, "tests": set(), "failed": 0})
        g["tests"].add(r["test"])
        if not r["ok"]:
            g["failed"] += 1
        else:
            g["worst_pct"] = max(g["worst_pct"], abs(r["error_pct"]))
    for g in out.values():
        goal = GOAL_PCT.get(g["model"])
        g["goal_pct"] = goal
        g["met"] = None if goal is None else (g["failed"] == 0 and g["worst_pct"] <= goal)
    return list(out.values())


def side_by_side(rows: list[dict]) -> list[str]:
    """Markdown lines: per model that runs more than one (law, contact, restitution) variant, the error % of every
    (test, quantity, vehicle) in one column per variant ("*": an impact flagged slip_reversed; "fail": the
    run failed); nothing for a model with one variant."""
    lines = []
    for model in dict.fromkeys(r["model"] for r in rows):
        mine = [r for r in rows if r["model"] == model]
        cols = list(dict.fromkeys((r["law"], r["contact"], r["restitution"]) for r in mine))
        if len(cols) < 2:
            continue
        cells = {(r["test"], r["quantity"], r["vehicle"], (r["law"], r["contact"], r["restitution"])): r
                 for r in mine}
        heads = " | ".join(f"{law} {contact} e {e}" for law, contact, e in cols)
        lines += ["", f"## {model}: every law and contact side by side (error %)", "",
                  f"| test | quantity | vehicle | published | {heads} |",
                  "|---|---|---|---:|" + "---:|" * len(cols)]
        for key in dict.fromkeys((r["test"], r["quantity"], r["vehicle"]) for r in mine):
            vals = []
            for c in cols:
                r = cells.get((*key, c))
                if r is None:
                    vals.append("")
                elif r["ok"] is None:
                    vals.append("n/a")
                elif not r["ok"]:
                    vals.append("fail")
                else:
                    vals.append(_fmt(r["error_pct"], 1) + ("*" if r.get("slip_reversed") else ""))
            pub = next(r["published"] for r in mine if (r["test"], r["quantity"], r["vehicle"]) == key)
            lines.append(f"| {key[0]} | {key[1]} | {key[2]} | {_fmt(pub)} | " + " | ".join(vals) + " |")
    return lines


def write_markdown(rows: list[dict], path: Path, wall_time_s: float | None = None) -> Path:
    lines = ["# Validation against published tests", "",
             "One parameter set for all tests (each scene's [impact]: friction 0.3, exact-restitution force law; "
             "road 0.8; restitution as the column says); error = simulated - published. Sources: "
             "studies/validation/README.md. law: the impulse law (\"-\": the model does not read it); contact: "
             "\"given\" = at the published point of impact, \"found\" = the model finds its own contact; "
             "\"engagement\" = [impact] point = \"engagement\" (default depth); impacts: impact rows (contact "
             "episodes) of the run; rev: an impact flagged slip_reversed; warnings: the run's warnings, listed "
             "below the table; ok n/a: the model has no such quantity (a crush without a contact depth), "
             "neither pass nor fail.", "",
             "| model | law | e | contact | test | quantity | vehicle | unit | published | simulated | error | "
             "error % | impacts | rev | warnings | ok |",
             "|---|---|---|---|---|---|---|---|---:|---:|---:|---:|---:|---|---|---|"]
    warned = run_warnings(rows)
    for r in rows:
        if r["ok"] is None:
            sim = r["_reason"]
        else:
            sim = _fmt(r["simulated"]) if r["ok"] else f"NaN ({r['_reason']})"
        variant = (r["law"], r["restitution"], r["contact"])
        marks = ", ".join(f"W{k + 1}" for k, w in enumerate(warned)
                          if (w["test"], w["model"]) == (r["test"], r["model"]) and variant in w["variants"])
        lines.append(f"| {r['model']} | {r['law']} | {r['restitution']} | {r['contact']} | {r['test']} | "
                     f"{r['quantity']} | {r['vehicle']} | {r['unit']} | {_fmt(r['published'])} | {sim} | "
                     f"{_fmt(r['error'])} | {_fmt(r['error_pct'], 1)} | {r['impacts']} | "
                     f"{'yes' if r.get('slip_reversed') else ''} | {marks} | {_shown_ok(r['ok'])} |")
    if warned:
        lines += ["", "## Warnings of the runs (per test and model; numbers that differ between the runs as their "
                  "range)", ""]
        lines += [f"- W{k + 1}: {w['test']}, {w['model']}, {w['runs']} of {w['of']} runs: {w['warning']}"
                  for k, w in enumerate(warned)]
    lines += side_by_side(rows)
    goals = goal_rows(rows)
    if goals:
        lines += ["", "## Car-to-car delta-V against the goal (largest |error %| over the tests run)", "",
                  "| model | law | e | contact | tests | worst error % | goal % | met |",
                  "|---|---|---|---|---|---:|---:|---|"]
        for g in goals:
            worst = f"{g['worst_pct']:.1f}" + (f" ({g['failed']} failed)" if g["failed"] else "")
            goal = "" if g["goal_pct"] is None else f"{g['goal_pct']:.0f}"
            met = "" if g["met"] is None else str(g["met"])
            lines.append(f"| {g['model']} | {g['law']} | {g['restitution']} | {g['contact']} | "
                         f"{', '.join(sorted(g['tests']))} | {worst} | {goal} | {met} |")
    if wall_time_s is not None:
        lines += ["", f"Wall time of the study: {wall_time_s:.1f} s."]
    path.write_text("\n".join(lines) + "\n")
    return path


def write_figure(rows: list[dict], path: Path, unit: str = "km/h") -> Path | None:
    """Simulated against measured delta-V of every crash test (every model and variant; the rows' values in
    `unit`), with the 1:1 line and a +-10 % band; None when there is no such row."""
    pts = [r for r in rows if r["ok"] and r["kind"] == "crash test" and r["quantity"] in DV_QUANTITIES]
    if not pts:
        return None
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    tests = sorted({r["test"] for r in pts})
    # a marker per model, law and contact; the restitution by the fill: open 0.1, filled "speed" (§13b)
    variants = sorted({(r["model"], r["law"], r["contact"]) for r in pts})
    markers = "osD^v<>PXh*pd8H+x1234"  # distinct for up to 21 variants (the full run has 13)
    colours = plt.get_cmap("tab10")
    top = 1.1 * max(max(r["published"], r["simulated"]) for r in pts)
    fig, ax = plt.subplots(figsize=(10.5, 6.5))
    ax.fill_between([0, top], [0, 0.9 * top], [0, 1.1 * top], color="0.85", label="+-10 %")
    ax.plot([0, top], [0, top], color="k", lw=1, label="1:1")
    for k, var in enumerate(variants):
        model, law, contact = var
        marker = markers[k % len(markers)]
        for e in sorted({str(r["restitution"]) for r in pts}):
            sel = [r for r in pts if (r["model"], r["law"], r["contact"], str(r["restitution"])) == (*var, e)]
            edge = [colours(tests.index(r["test"]) % 10) for r in sel]
            ax.scatter([r["published"] for r in sel], [r["simulated"] for r in sel], marker=marker, s=45,
                       facecolors=edge if e == "speed" else "none", edgecolors=edge, alpha=0.6 if e == "speed" else 1)
        ax.scatter([], [], marker=marker, facecolors="none", edgecolors="k",  # legend: the variant's marker
                   label=f"{model}" + ("" if law == "-" else f" {law}") + f", {contact}")
    ax.scatter([], [], marker="o", facecolors="none", edgecolors="k", label="open: restitution 0.1")
    ax.scatter([], [], marker="o", color="k", alpha=0.6, label='filled: restitution "speed"')
    for j, t in enumerate(tests):  # legend: the tests' colours
        ax.scatter([], [], color=colours(j % 10), marker="s", label=t)
    ax.set_xlim(0, top)
    ax.set_ylim(0, top)
    ax.set_aspect("equal")
    ax.set_xlabel(f"measured delta-V [{unit}]")
    ax.set_ylabel(f"simulated delta-V [{unit}]")
    ax.set_title("Validation: simulated against measured delta-V (each vehicle of each crash test)")
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.02, 1.0))  # beside the axes: it hid points
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def run(models: list[str], out: Path, quick: bool = False, tests: list[dict] | None = None,
        system: str = "si") -> Path:
    """Every model on every test (quick: all tests for impulse and pymunk, QUICK_TESTS for the others),
    each in its variants (runs); writes DIR/validation.csv, DIR/validation.md and DIR/validation_dv.png (in
    `system`'s units: each row's published, simulated and error by its unit, base.shown_rows) and returns the
    CSV path."""
    from .base import output_dir
    out = output_dir(out)
    t0 = time.perf_counter()
    rows = validation_rows(models, quick=quick, tests=tests)
    print_warnings(rows)
    path = write_csv(rows, out / "validation.csv", system)
    shown = shown_rows(rows, system)
    write_figure(shown, out / FIGURE, unit_in("km/h", system))
    write_markdown(shown, out / "validation.md", time.perf_counter() - t0)
    return path
