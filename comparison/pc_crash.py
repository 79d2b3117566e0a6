"""`crashlab study pc_crash`: every model, and every impulse law and point-of-impact placement, on the
thesis's three PC-Crash cases (studies/pc_crash), side by side against PC-Crash's rest poses.

The scenes run as written (one parameter set for the three cases; nothing tuned). Variants, each one
constant to extend (the validation study's IMPACT_LAWS and LAW_MODELS: every [impact] law of the schema,
for the models that read it):
  contact  "found": the model's own contact (impulse: the contact-zone point, docs/physics.md §4);
           "engagement": [impact] point = "engagement" at each of ENGAGEMENT_DEPTHS (m), for the models that
           read a collision position (validation.reads_collision_position; --quick: the default depth only)

One row per (case, model, law, contact, engagement depth, vehicle): rest pose, its distance [m] and heading
difference [deg] to PC-Crash's (crashlab.tools.compare.comparison_table), the vehicle's delta-V (|sum of its
impact rows' velocity changes|, km/h, and its components), the kinds of its impacts and whether any was
flagged slip_reversed (the slip at the point stops and reverses: a law other than routh is outside its
assumptions there, docs/physics.md §3). Writes DIR/pc_crash.csv and DIR/pc_crash.md (a table per case).
A run that fails gives rows with ok False and NaN numbers; the study goes on.
"""
from __future__ import annotations

import math
import time
from pathlib import Path

import pandas as pd

from crashlab.outcome import collision_rows
from crashlab.units import unit_in, value_in

from .base import STUDIES_DIR, shown_table
from .validation import IMPACT_LAWS, LAW_MODELS, reads_collision_position, variant_scene

PC_CRASH_DIR = STUDIES_DIR / "pc_crash"
CASES = ("head_on", "offset", "side")
REFERENCE = "pc_crash"
ENGAGEMENT_DEPTHS = (0.2, 0.5, 0.8)  # m; 0.5 the documented default (Campbell's crush at 50 km/h, §4)
QUICK_DEPTHS = (0.5,)
COLUMNS = ["case", "model", "law", "contact", "engagement_depth", "vehicle", "ok", "x", "y", "heading", "at_rest",
           "d_pc_crash_m", "d_pc_crash_deg", "delta_v", "dvx", "dvy", "impacts", "kinds", "slip_reversed",
           "warnings"]


def variants(model: str, quick: bool = False) -> list[dict]:
    """The runs of one model on one case: dicts law ("-": the model does not read it), contact, depth."""
    laws = IMPACT_LAWS if model in LAW_MODELS else ("-",)
    places = [("found", None)]
    if reads_collision_position(model):
        places += [("engagement", d) for d in (QUICK_DEPTHS if quick else ENGAGEMENT_DEPTHS)]
    return [{"law": law, "contact": c, "depth": d} for law in laws for c, d in places]


def case_scene(path: Path, variant: dict):
    """The scene of `path` with the variant's [impact] law and placement, set on the file's data."""
    extra = {} if variant["depth"] is None else {"point": "engagement", "engagement_depth": variant["depth"]}
    return variant_scene(path, None if variant["law"] == "-" else variant["law"], **extra)


def outcome_rows(case: str, model: str, variant: dict, scene, outcome, reason: str = "") -> list[dict]:
    """One row per vehicle of one run (outcome None: a failed run, NaN numbers)."""
    from crashlab.tools.compare import comparison_table
    base = {"case": case, "model": model, "law": variant["law"], "contact": variant["contact"],
            "engagement_depth": math.nan if variant["depth"] is None else variant["depth"]}
    if outcome is None:
        return [{**base, "vehicle": v.name, "ok": False, "warnings": reason,
                 **{k: math.nan for k in ("x", "y", "heading", "d_pc_crash_m", "d_pc_crash_deg", "delta_v",
                                          "dvx", "dvy")},
                 "at_rest": False, "impacts": 0, "kinds": "", "slip_reversed": False} for v in scene.vehicles]
    df = comparison_table(scene, {model: outcome})
    mine = df[df.source == model].set_index("vehicle")
    rows = []
    for name in outcome.names:
        imp = [r for r in outcome.impact_rows if r["vehicle"] == name]
        dvx, dvy = 3.6 * sum(r["dvx"] for r in imp), 3.6 * sum(r["dvy"] for r in imp)
        rows.append({**base, "vehicle": name, "ok": bool(outcome.outcome_ok),
                     "x": float(mine.at[name, "x"]), "y": float(mine.at[name, "y"]),
                     "heading": float(mine.at[name, "heading"]), "at_rest": bool(mine.at[name, "at_rest"]),
                     **{c: float(mine.at[name, f"d_{REFERENCE}_{u}"]) if f"d_{REFERENCE}_{u}" in mine else math.nan
                        for c, u in (("d_pc_crash_m", "m"), ("d_pc_crash_deg", "deg"))},
                     "delta_v": math.hypot(dvx, dvy) if imp else math.nan, "dvx": dvx, "dvy": dvy,
                     "impacts": len(collision_rows(imp)), "kinds": ";".join(str(r["kind"]) for r in imp),
                     "slip_reversed": any(bool(r.get("slip_reversed", False)) for r in imp),
                     "warnings": " | ".join(outcome.warnings)[:300]})
    return rows


def scene_rows(case: str, path: Path, models: list[str], quick: bool = False) -> list[dict]:
    """Every model in every variant on the scene file `path`."""
    rows = []
    for model in models:
        for var in variants(model, quick):
            scene = case_scene(path, var)
            outcome, reason = _simulate_any(model, scene)
            rows += outcome_rows(case, model, var, scene, outcome, reason)
    return rows


def _simulate_any(model: str, scene):
    """(outcome, reason): a run that ends not ok keeps its outcome (its poses show where it stopped)."""
    from crashlab.registry import get_model
    try:
        return get_model(model).simulate(scene), ""
    except Exception as err:  # recorded as failed for this cell, as the validation study does
        return None, f"{type(err).__name__}: {err}".splitlines()[0][:200]


def _fmt(x, nd=2) -> str:
    return "" if x is None or not isinstance(x, (int, float)) or not math.isfinite(x) else f"{x:.{nd}f}"


def write_csv(rows: list[dict], path: Path, system: str = "si") -> Path:
    """pc_crash.csv (COLUMNS) in `system`'s units (base.write_table: x, y, distances and delta-V in ft and mph
    in "us", each column named with its unit)."""
    shown_table(pd.DataFrame(rows, columns=COLUMNS), system).to_csv(path, index=False, na_rep="nan")
    return path


def markdown(rows: list[dict], system: str = "si") -> str:
    """A table per case: one line per (model, law, contact), both vehicles side by side, in `system`'s units."""
    m, kmh = unit_in("m", system), unit_in("km/h", system)
    rows = [{**r, **{k: value_in(r[k], u, system) for k, u in (("d_pc_crash_m", "m"), ("delta_v", "km/h"),
                                                                 ("engagement_depth", "m"))}} for r in rows]
    lines = ["# PC-Crash cases: every model, impulse law and point-of-impact placement", "",
             f"Rest-pose distance [{m}] and heading difference [deg] to PC-Crash's (thesis Tables 3.10, 3.12, "
             f"3.14), delta-V [{kmh}] of each vehicle (sum of its impact rows), the impacts' kinds and whether any "
             "impact was flagged slip_reversed (the slip stops and reverses: kudlich-slibar and brach are outside "
             "their assumptions there, docs/physics.md §3). contact: \"found\" = the model's own contact "
             "(impulse: contact-zone point), \"engagement d\" = [impact] point = \"engagement\" with "
             f"engagement_depth d [{m}]. One parameter set for the three cases (the scene files); nothing tuned.",
             ""]
    keyed = {}
    for r in rows:
        key = (r["case"], r["model"], r["law"], r["contact"], r["engagement_depth"])
        keyed.setdefault(key, []).append(r)
    for case in dict.fromkeys(r["case"] for r in rows):
        lines += [f"## {case}", "",
                  f"| model | law | contact | V1 dist {m} | V1 dhead deg | V2 dist {m} | V2 dhead deg | "
                  f"dV V1 {kmh} | dV V2 {kmh} | kinds | slip_reversed | ok |",
                  "|---|---|---|---:|---:|---:|---:|---:|---:|---|---|---|"]
        for key, rs in keyed.items():
            if key[0] != case:
                continue
            by = {r["vehicle"]: r for r in rs}
            v1, v2 = (by.get(n, {}) for n in ("V1", "V2"))
            contact = key[3] if key[3] != "engagement" else f"engagement {rs[0]['engagement_depth']:.3g}"
            kinds = ";".join(dict.fromkeys(k for r in rs for k in str(r["kinds"]).split(";") if k))
            lines.append(f"| {key[1]} | {key[2]} | {contact} | {_fmt(v1.get('d_pc_crash_m'))} | "
                         f"{_fmt(v1.get('d_pc_crash_deg'), 1)} | {_fmt(v2.get('d_pc_crash_m'))} | "
                         f"{_fmt(v2.get('d_pc_crash_deg'), 1)} | {_fmt(v1.get('delta_v'))} | "
                         f"{_fmt(v2.get('delta_v'))} | {kinds} | {any(r['slip_reversed'] for r in rs)} | "
                         f"{all(r['ok'] for r in rs)} |")
        lines.append("")
    return "\n".join(lines)


def run(models: list[str], out: Path, quick: bool = False, cases=CASES, system: str = "si") -> Path:
    """Every model on every case in its variants; writes DIR/pc_crash.csv and DIR/pc_crash.md (in `system`'s
    units) and returns the CSV path."""
    from .base import output_dir
    out = output_dir(out)
    t0 = time.perf_counter()
    rows = []
    for case in cases:
        rows += scene_rows(case, PC_CRASH_DIR / f"{case}.toml", models, quick)
    path = write_csv(rows, out / "pc_crash.csv", system)
    wall = time.perf_counter() - t0
    (out / "pc_crash.md").write_text(markdown(rows, system) + f"\nWall time of the study: {wall:.1f} s.\n")
    return path
