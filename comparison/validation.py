"""`crashlab study validation`: every model on the published tests under studies/validation.

The tests and their published quantities are listed in studies/validation/published/tests.toml (each
number with its source; studies/validation/README.md lists the sources). Every model runs every test's
scene with the scene's own parameters: one parameter set for all tests, nothing fitted per test.

Quantities (simulated side):
  delta_v        |sum of the vehicle's impact-row velocity changes| [km/h] (Outcome.impact_rows, SI)
  rebound_speed  speed right after the impact [km/h]: velocity at first contact + the summed delta-V
  post_vx        global x velocity right after the impact [km/h] (same construction)
  pdof           principal direction of force of the vehicle's largest impact row [deg]
  crush_dynamic, crush_residual   deepest contact overlap of the run [m] (Diagnostics.max_penetration;
                 0 for an impulse model, which has no contact depth)

Writes DIR/validation.csv (model, test, quantity, published, simulated, error, then unit, source, ok,
kind, vehicle) and DIR/validation.md. A run that fails (an exception, or outcome_ok False) gives rows with
simulated NaN and ok False; the study goes on.
"""
from __future__ import annotations

import csv
import math
import time
import tomllib
from pathlib import Path

from .base import STUDIES_DIR

VALIDATION_DIR = STUDIES_DIR / "validation"
TESTS_FILE = VALIDATION_DIR / "published" / "tests.toml"
COLUMNS = ["model", "test", "quantity", "published", "simulated", "error", "unit", "source", "ok", "kind",
           "vehicle"]
FULL_MODELS = ("impulse", "pymunk")  # --quick runs every test for these, QUICK_TESTS for the others
QUICK_TESTS = ("nhtsa10146",)


def load_tests(path: Path = TESTS_FILE) -> list[dict]:
    """The tests of tests.toml: dicts with id, scene (path), kind, source, quantity (list of dicts)."""
    with open(path, "rb") as fh:
        data = tomllib.load(fh)
    tests = []
    for t in data["test"]:
        tests.append({**t, "scene": path.parent.parent / t["scene"], "quantity": list(t.get("quantity", []))})
    return tests


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


def simulated_quantity(outcome, scene, quantity: str, vehicle: str) -> float:
    """One quantity of `outcome` in the study's units (km/h, deg, m); NaN when the run has none."""
    if quantity == "delta_v":
        rows = _vehicle_rows(outcome, vehicle)
        if not rows:
            return math.nan
        return 3.6 * math.hypot(sum(r["dvx"] for r in rows), sum(r["dvy"] for r in rows))
    if quantity in ("rebound_speed", "post_vx"):
        if not _vehicle_rows(outcome, vehicle):
            return math.nan
        vx, vy = _post_velocity(outcome, scene, vehicle)
        return 3.6 * (math.hypot(vx, vy) if quantity == "rebound_speed" else vx)
    if quantity == "pdof":
        rows = _vehicle_rows(outcome, vehicle)
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


def validation_rows(models: list[str], quick: bool = False, tests: list[dict] | None = None) -> list[dict]:
    """One row per (model, test, published quantity)."""
    from crashlab.scene_file import load_scene
    tests = load_tests() if tests is None else tests
    scenes = {t["id"]: load_scene(t["scene"]) for t in tests}
    rows = []
    for model in models:
        for t in tests:
            if quick and model not in FULL_MODELS and t["id"] not in QUICK_TESTS:
                continue
            scene = scenes[t["id"]]
            outcome, reason = _simulate(model, scene)
            for q in t["quantity"]:
                sim = math.nan
                if outcome is not None:
                    try:
                        sim = simulated_quantity(outcome, scene, q["name"], q["vehicle"])
                    except Exception as err:  # a broken outcome: failed cell, not a failed study
                        reason = f"{type(err).__name__}: {err}"[:200]
                pub = float(q["published"])
                ok = outcome is not None and math.isfinite(sim)
                rows.append({"model": model, "test": t["id"], "quantity": q["name"], "published": pub,
                             "simulated": sim, "error": sim - pub if ok else math.nan,
                             "unit": q.get("unit", ""), "source": t["source"], "ok": ok, "kind": t["kind"],
                             "vehicle": q["vehicle"], "_reason": reason})
    return rows


def write_csv(rows: list[dict], path: Path) -> Path:
    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=COLUMNS, extrasaction="ignore")
        w.writeheader()
        for r in rows:
            w.writerow({**r, "published": repr(float(r["published"])), "simulated": repr(float(r["simulated"])),
                        "error": repr(float(r["error"]))})
    return path


def write_markdown(rows: list[dict], path: Path, wall_time_s: float | None = None) -> Path:
    lines = ["# Validation against published tests", "",
             "One parameter set for all tests (each scene's [impact]: restitution 0.1, friction 0.3); "
             "error = simulated - published. Sources: studies/validation/README.md.", "",
             "| model | test | kind | quantity | vehicle | unit | published | simulated | error | ok |",
             "|---|---|---|---|---|---|---:|---:|---:|---|"]
    for r in rows:
        sim = _fmt(r["simulated"]) or f"NaN ({r['_reason']})" if not r["ok"] else _fmt(r["simulated"])
        lines.append(f"| {r['model']} | {r['test']} | {r['kind']} | {r['quantity']} | {r['vehicle']} | "
                     f"{r['unit']} | {_fmt(r['published'])} | {sim} | {_fmt(r['error'])} | {r['ok']} |")
    if wall_time_s is not None:
        lines += ["", f"Wall time of the study: {wall_time_s:.1f} s."]
    path.write_text("\n".join(lines) + "\n")
    return path


def run(models: list[str], out: Path, quick: bool = False, tests: list[dict] | None = None) -> Path:
    """Every model on every test (quick: all tests for impulse and pymunk, QUICK_TESTS for the others);
    writes DIR/validation.csv and DIR/validation.md and returns the CSV path."""
    from .base import output_dir
    out = output_dir(out)
    t0 = time.perf_counter()
    rows = validation_rows(models, quick=quick, tests=tests)
    path = write_csv(rows, out / "validation.csv")
    write_markdown(rows, out / "validation.md", time.perf_counter() - t0)
    return path
