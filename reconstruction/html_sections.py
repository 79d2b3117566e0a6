"""The sections both report pages show (crashlab.reconstruction.html_report, html_posterior), as data for the
templates: the case, the scene, the free variables, the evidence, the chosen solution's impact table and
figures, and the spread between the models after a [refine]."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from crashlab.units import unit_in, value_in, wrap_deg

from .evidence import UNITS
from .html_page import Solution, Table, figure_of, macro, num
from .problem import variable_unit


# ---------------------------------------------------------------- the case, the study and the evidence
def case_context(spec):
    """The study's [case] for the template: (label, text) rows, assumptions and limitations; None without."""
    case = getattr(spec, "case", None)
    if case is None:
        return None
    fields = [(label, value) for label, value in (("case", case.id), ("analyst", case.analyst),
                                                  ("date", case.date), ("notes", case.notes)) if value]
    return {"fields": fields, "assumptions": list(case.assumptions), "limitations": list(case.limitations)}


def scene_context(study) -> dict:
    """The base scene: its vehicles' data and start states, road and impact, in the study's shown units."""
    scene, system = study.scene, study.shown_units
    rows = []

    def shown(value, unit, digits):
        return num(value_in(value, unit, system), digits)
    for v in scene.vehicles:
        s = v.spec
        rows.append([v.name, getattr(s, "name", "") or "", shown(s.mass, "kg", 0), shown(s.length, "m", 2),
                     shown(s.width, "m", 2), shown(v.x, "m", 2), shown(v.y, "m", 2), num(math.degrees(v.heading), 1),
                     shown(v.speed * 3.6, "km/h", 1), v.wheels])
    imp = scene.impact
    road = scene.road
    extra = (f"road friction {road.friction:g}" + (f", {len(road.zones)} friction zone(s)" if road.zones else "")
             + (f", {len(road.lines)} road line(s)" if getattr(road, "lines", ()) else "")
             + (f", {len(scene.barriers)} barrier(s)" if scene.barriers else "")
             + "; impact restitution " + ("of the closing speed (\"speed\")" if imp.restitution_law == "speed"
                                           else f"{imp.restitution:g}") + f", friction {imp.friction:g}"
             + ("" if imp.point is None else f", point of impact given at ({value_in(imp.point[0], 'm', system):.2f}, "
                f"{value_in(imp.point[1], 'm', system):.2f}) {unit_in('m', system)}")
             + f"; duration {scene.duration:g} s")
    return {"name": scene.name, "source": scene.source, "extra": extra,
            "table": Table(["vehicle", "data", f"mass [{unit_in('kg', system)}]", f"length [{unit_in('m', system)}]",
                            f"width [{unit_in('m', system)}]", f"x [{unit_in('m', system)}]",
                            f"y [{unit_in('m', system)}]", "heading [deg]", f"speed [{unit_in('km/h', system)}]",
                            "wheels"], rows, "scene", (0, 1, 9))}


def _options(d: dict) -> str:
    return ", ".join(f"{k} = {v}" for k, v in d.items()) if d else "defaults"


def free_table(variables, truth=None, system: str = "si") -> Table:
    """The searched variables (label, unit, bounds; the twin's truth), in `system`'s units."""
    rows = []
    for j, f in enumerate(variables):
        u = variable_unit(f)
        row = [f.label, unit_in(u, system), num(value_in(f.lower, u, system)), num(value_in(f.upper, u, system))]
        if truth is not None:
            row.append(num(value_in(truth[j], u, system)) if j < len(truth) else "")
        rows.append(row)
    head = ["free variable", "unit", "lower", "upper"] + (["truth (twin)"] if truth is not None else [])
    return Table(head, rows, "free", (0, 1))


def evidence_context(study) -> dict:
    """The evidence as the objectives use it: measured rest poses (thesis objective, no sigmas), or every
    item with its value and standard deviation (misfit objective), in the study's shown units."""
    system = study.shown_units
    m = unit_in("m", system)
    es = study.evidence_set
    ev = study.spec.evidence
    twin = ("Twin experiment: the evidence is the model's own run of the base scene"
            + ("" if ev.noise_seed is None else f", with Gaussian noise of the given sigmas (noise_seed "
               f"{ev.noise_seed})") + ".") if ev.twin else ""
    if es is None:
        rows = [[n, num(value_in(x, "m", system)), num(value_in(y, "m", system)),
                 "not measured" if h is None else num(h, 2)] for n, (x, y, h) in study.evidence.items()]
        return {"twin": twin, "intro": "Measured rest poses (the thesis objective: f_<vehicle> = |r - r*| + "
                f"heading_weight |dpsi| [{m}]; no standard deviations).",
                "table": Table(["vehicle", f"x [{m}]", f"y [{m}]", "heading [deg]"], rows, "evidence")}
    rows = []
    for it in es.items:
        if it.kind == "marks":
            pts = ", ".join(f"({value_in(x, 'm', system):.2f}, {value_in(y, 'm', system):.2f})" for x, y in it.points)
            rows.append([it.label, ", ".join(it.vehicles), "CG path through", pts,
                         num(value_in(it.sigmas[0], "m", system)), m])
            continue
        for c, v, s in zip(it.components, it.values, it.sigmas):
            u = UNITS.get(c, "")
            rows.append([it.label, ", ".join(it.vehicles), c, num(value_in(v, u, system)), num(value_in(s, u, system)),
                         unit_in(u, system)])
    return {"twin": twin, "intro": "Every item with its standard deviation (sigma). Objectives: f_<vehicle> = "
            "sqrt(sum (residual / sigma)^2) over the items that concern the vehicle [sigma]; log-likelihood = -0.5 "
            "sum (residual / sigma)^2 over all items, each once.",
            "table": Table(["item", "vehicles", "component", "value", "sigma", "unit"], rows, "evidence",
                           (0, 1, 2, 3, 5))}


# ---------------------------------------------------------------- the chosen solution: impacts, time histories
# printed digits of the impact table's columns (the test compares every cell with the Outcome to these)
IMPACT_DIGITS = {"t [s]": 3, "speed at impact [km/h]": 1, "delta-V [km/h]": 1, "EES [km/h]": 1, "PDOF [deg]": 0,
                 "PDOF [clock]": 0, "energy dissipated [kJ]": 1, "of it this vehicle's [kJ]": 1}
IMPACT_NOTE = ("One row per impact and vehicle, from the simulation's impact rows (crashlab Outcome.impacts). "
               "Speed at impact: the vehicle's speed when it touched the other (the state at first contact, "
               "Outcome.first_contact; for a later impact the last recorded sample before it). Struck side: the "
               "vehicle's front, rear, left or right side the impact struck, whose crush structure takes its share "
               "of the energy. delta-V: the "
               "magnitude of the vehicle's velocity change in the impact; EES: the energy equivalent speed of the "
               "energy the vehicle absorbed; PDOF: principal direction of force, deg counter-clockwise from straight "
               "ahead, and as the SAE J224 clock (12 from ahead, 3 from the right); energy dissipated: kinetic "
               "energy lost in the impact (both vehicles), and this vehicle's share of it (docs/physics.md §21). An "
               "empty cell: the model does not give that number.")


def speed_at_impact(outcome, i: int, t_impact: float) -> float:
    """km/h: vehicle i's speed when an impact at t_impact began: the state at first contact for the vehicle's
    first impact, else the last trajectory sample before t_impact (NaN without one)."""
    first = [r["t"] for r in outcome.impact_rows if r["vehicle"] == outcome.names[i]]
    if first and abs(t_impact - min(first)) < 1e-12 and np.isfinite(outcome.contact_si[i, 3]):
        return float(outcome.contact_si[i, 3]) * 3.6
    tr = (outcome.trajectories or {}).get(outcome.names[i])
    if tr is None or not len(tr["t"]):
        return math.nan
    k = int(np.searchsorted(np.asarray(tr["t"], dtype=float), t_impact, side="left")) - 1
    return math.nan if k < 0 else float(math.hypot(tr["vx"][k], tr["vy"][k])) * 3.6


# the impact table's column as shown in US units: (header, unit of the value given, digits)
IMPACT_US = {"speed at impact [km/h]": ("speed at impact [mph]", "km/h", 1),
             "delta-V [km/h]": ("delta-V [mph]", "km/h", 1), "EES [km/h]": ("EES [mph]", "km/h", 1),
             "energy dissipated [kJ]": ("energy dissipated [ft-lbf]", "J", 0),
             "of it this vehicle's [kJ]": ("of it this vehicle's [ft-lbf]", "J", 0)}


def impact_table(outcome, table_id: str = "impacts", system: str = "si") -> Table | None:
    """The impact table of a run (IMPACT_NOTE), sorted by time; None when nothing touched. In US units with
    system "us" (IMPACT_US: the energies in ft-lbf)."""
    if not outcome.outcome_ok or not outcome.impact_rows:
        return None
    df = outcome.impacts
    crush = [r.get("crush_energy", math.nan) for r in outcome.impact_rows]
    df = df.assign(crush_energy=crush).sort_values(["t", "vehicle"], kind="stable")
    rows = []
    for _, r in df.iterrows():
        i = outcome.names.index(r["vehicle"])
        values = {"t [s]": r["t"], "speed at impact [km/h]": speed_at_impact(outcome, i, r["t"]),
                  "delta-V [km/h]": r["delta_v"], "EES [km/h]": r["ees"], "PDOF [deg]": r["pdof"],
                  "PDOF [clock]": r["pdof_clock"], "energy dissipated [kJ]": r["energy"] / 1e3,
                  "of it this vehicle's [kJ]": r["crush_energy"] / 1e3}
        rows.append([r["vehicle"], r["other"], r["side"]] + [_impact_cell(k, v, system) for k, v in values.items()])
    head = [IMPACT_US[k][0] if system == "us" and k in IMPACT_US else k for k in IMPACT_DIGITS]
    return Table(["vehicle", "other", "struck side"] + head, rows, table_id, (0, 1, 2))


def _impact_cell(header: str, value, system: str) -> str:
    """An impact table's cell: IMPACT_DIGITS of the SI value, or its US value (IMPACT_US)."""
    if system != "us" or header not in IMPACT_US:
        return num(value, IMPACT_DIGITS[header])
    _, unit, digits = IMPACT_US[header]
    return num(value_in(value * (1e3 if unit == "J" else 1.0), unit, system), digits)  # (kJ -> J)


def solution_context(title, intro, outcome, out_dir, figures, system: str = "si") -> Solution | None:
    """The chosen solution's section: its impact table (in `system`'s units) and figures [(file name in out_dir,
    caption)]."""
    if outcome is None:
        return None
    return Solution(title, intro, impact_table(outcome, system=system), IMPACT_NOTE,
                    [figure_of(Path(out_dir) / f, c) for f, c in figures])


# ---------------------------------------------------------------- refine
def spread_table(refined, evidence: dict, system: str = "si") -> Table | None:
    """The spread between the search model and the refine model (a [refine]'s RefineResult): per candidate and
    vehicle, both models' rest poses at the same start, the distance between them and the heading difference;
    lengths in `system`'s units."""
    t = getattr(refined, "table", None)
    if t is None or not len(t):
        return None
    a, b = refined.search_model, refined.model
    names = sorted({c[len("model_gap_"):] for c in t.columns if c.startswith("model_gap_")},
                   key=lambda n: list(t.columns).index(f"model_gap_{n}"))
    rows = []
    for _, r in t.iterrows():
        for n in names:
            ha, hb = r[f"search_rest_{n}_heading"], r[f"refine_rest_{n}_heading"]
            m = evidence.get(n)

            def length(v):
                return num(value_in(v, "m", system), 2)
            rows.append([str(int(r["candidate"])), str(r["row"]), n,
                         length(r[f"search_rest_{n}_x"]), length(r[f"search_rest_{n}_y"]), num(ha, 1),
                         length(r[f"refine_rest_{n}_x"]), length(r[f"refine_rest_{n}_y"]), num(hb, 1),
                         length(r[f"model_gap_{n}"]), num(wrap_deg(hb - ha) if np.isfinite(ha - hb) else math.nan, 1),
                         "" if m is None else f"{length(m[0])}, {length(m[1])}" + ("" if m[2] is None else
                                                                                 f", {m[2]:.1f}")])
    u = unit_in("m", system)
    head = ["candidate", "row", "vehicle", f"{a} x [{u}]", f"{a} y [{u}]", f"{a} heading [deg]", f"{b} x [{u}]",
            f"{b} y [{u}]", f"{b} heading [deg]", f"distance apart [{u}]", f"heading {b} - {a} [deg]",
            f"measured x, y [{u}], heading [deg]"]
    return Table(head, rows, "spread", (2, 11))


def refine_context(out_dir: Path, refined=None, evidence=None, system: str = "si") -> dict | None:
    """The spread between the models (refined: the RefineResult, when there is one), DIR/refine.md (as text)
    and DIR/refine.csv (as a table); None when there is none of them (the report is written once, after the
    refine step)."""
    md, csv = Path(out_dir) / "refine.md", Path(out_dir) / "refine.csv"
    ctx = {"spread": spread_table(refined, evidence or {}, system) if refined is not None else None, "md": None,
           "csv": None, "error": None, "spread_intro": ""}
    if ctx["spread"] is not None:
        t = refined.table
        gaps = [c for c in t.columns if c.startswith("model_gap_")]
        worst = ", ".join(f"{c[len('model_gap_'):]} {value_in(t[c].max(), 'm', system):.2f} {unit_in('m', system)}"
                          for c in gaps if np.isfinite(t[c]).any())
        ctx["spread_intro"] = (f"Each candidate ({refined.source}, best first) simulated with both models from the "
                               f"same start: `{refined.search_model}` (the search's) and `{refined.model}` (the "
                               f"refine model). The models' rest positions lie at most {worst or '-'} apart over "
                               f"the {len(t)} candidate(s): an uncertainty of the choice of model, which the "
                               "evidence's sigmas do not contain.")
    if md.is_file():
        ctx["md"] = md.read_text(encoding="utf-8", errors="replace")
    if csv.is_file():
        import pandas as pd
        try:
            df = pd.read_csv(csv)
            ctx["csv"] = Table(list(df.columns), [[_cell(v) for v in r] for r in df.itertuples(index=False)],
                               "refine", ())
        except Exception as err:  # noqa: BLE001 - an unreadable refine.csv is named, not fatal
            ctx["error"] = f"refine.csv could not be read ({type(err).__name__})."
    if not any(ctx[k] is not None for k in ("spread", "md", "csv", "error")):
        return None
    return ctx


def _cell(v) -> str:
    """A cell of refine.csv as shown: an integer (candidate, row, refine_evaluations) as one, a float by num,
    text as it is."""
    if isinstance(v, (int, np.integer)) and not isinstance(v, (bool, np.bool_)):
        return str(int(v))
    return num(v) if isinstance(v, (float, np.floating)) else str(v)


def refine_section(out_dir: Path, refined=None, evidence=None) -> str:
    ctx = refine_context(out_dir, refined, evidence)
    return "" if ctx is None else str(macro("refine_section", ctx))
