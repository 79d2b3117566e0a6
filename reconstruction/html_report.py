"""DIR/report.html of `crashlab reconstruct --out DIR` and `crashlab infer --out DIR`, and its PDF (`--pdf`).

One self-contained page (every figure embedded as a base64 data: URI; no script, style sheet, font or image
from elsewhere), rendered from the Jinja2 templates in reconstruction/templates/ with autoescape on: the case
(the study's [case]: id, analyst, date, notes, assumptions, limitations) first, then the study (scene, free
variables and their bounds, optimizer or sampler, model, evaluations counted by outcome and failures by
reason), the evidence with its sigmas, the chosen solution (Pareto row 0, or the posterior's median draw):
its impact table and speed / distance / heading against time, the Pareto set split into tables of at most
PARETO_COLUMNS_MAX columns (the rows of pareto.csv, at most PARETO_ROWS_MAX) or the posterior summary and
corner plot, the top views, the near-optimal figure, an animation of the best solution
(crashlab.tools.animation, when that module is there) and, after a [refine], the spread between the two
models with refine.md and refine.csv. The page is written once, after every file it shows exists
(reconstruction.run, reconstruction.infer). A print style sheet (@media print in templates/report.css) lays
it out on A4; write_pdf prints it to report.pdf with WeasyPrint.

Python builds plain data (numbers formatted by `num`, text as str, the only markup from `md_inline`); the
templates hold every tag. A figure named but not on disk is said so on the page ("not drawn"), never left as
a broken image.
"""
from __future__ import annotations

import base64
import datetime as _dt
import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from markupsafe import Markup, escape

from crashlab.errors import InputError
from crashlab.units import wrap_deg
from crashlab.version import package_version

from .evidence import UNITS
from .avoidance import TIME_DISTANCE_CAPTION
from .problem import variable_unit

REPORT_NAME = "report.html"
PDF_NAME = "report.pdf"
ANIMATION_NAME = "best.gif"
ANIMATION_FPS = 10  # frames per second of the embedded GIF: smooth enough, small enough
# an animation larger than this is left beside the page instead of embedded (keeps the page under 5 MB)
ANIMATION_EMBED_MAX_BYTES = 3_000_000
PARETO_ROWS_MAX = 2000  # Pareto rows shown (about 1 MB of table); the page says when pareto.csv has more
PARETO_COLUMNS_MAX = 12  # data columns per Pareto table (besides "row"): an A4 page's width at 7 pt
_MIME = {".png": "image/png", ".gif": "image/gif", ".jpg": "image/jpeg", ".jpeg": "image/jpeg",
         ".svg": "image/svg+xml"}


# ---------------------------------------------------------------- small pieces
def md_inline(text: str) -> Markup:
    """A line of summary.md's markdown as HTML: escaped, **bold** and `code` kept (nothing else is used)."""
    s = str(escape(str(text)))
    s = re.sub(r"\*\*(.+?)\*\*", r"<strong>\1</strong>", s)
    return Markup(re.sub(r"`(.+?)`", r"<code>\1</code>", s))


def wrap_name(text) -> Markup:
    """A column name that may break after '_' and '.' (long headers wrap instead of widening the table)."""
    if isinstance(text, Markup):
        return text
    return Markup(str(escape(str(text))).replace("_", "_<wbr>").replace(".", ".<wbr>"))


def num(value, digits: int = 3) -> str:
    """A table cell's number: fixed `digits` decimals within [1e-3, 1e7), else scientific; empty for NaN
    and None. The shown value is within 0.5e-3 absolute or 0.5e-3 relative of the true one (the test's
    tolerance)."""
    if value is None:
        return ""
    try:
        v = float(value)
    except (TypeError, ValueError):
        return str(value)
    if math.isnan(v):
        return ""
    if v == 0 or 1e-3 <= abs(v) < 1e7 or digits < 3:
        return f"{v:.{digits}f}"
    return f"{v:.{digits}e}"


@dataclass
class Table:
    """An HTML table for the templates: header and rows of cells (str, escaped when rendered, or Markup);
    columns in text_cols are left-aligned."""
    header: list
    rows: list
    id: str | None = None
    text_cols: tuple = (0,)
    caption: str | None = None
    css: str | None = None
    md_cols: tuple = ()  # columns whose cells are summary.md's inline markdown (**bold**, `code`): md_inline


@dataclass
class Figure:
    name: str
    caption: str
    uri: str | None = None  # None: not drawn
    why: str | None = None


@dataclass
class Solution:
    """The chosen solution's section: its impact table and figures."""
    title: str
    intro: str
    impacts: Table | None
    impacts_note: str = ""
    figures: list = field(default_factory=list)


_ENV = None


def environment():
    """The Jinja2 environment of the report templates (package data: reconstruction/templates), autoescaped."""
    global _ENV
    if _ENV is None:
        import jinja2
        _ENV = jinja2.Environment(loader=jinja2.PackageLoader("crashlab.reconstruction", "templates"),
                                  autoescape=True, undefined=jinja2.StrictUndefined, trim_blocks=True,
                                  lstrip_blocks=True, keep_trailing_newline=True)
        _ENV.filters["md"] = md_inline
        _ENV.filters["wrap_name"] = wrap_name
    return _ENV


def render(template: str, **context) -> str:
    return environment().get_template(template).render(**context)


def macro(name: str, *args) -> Markup:
    """One macro of templates/macros.html rendered on its own (a section the tests read alone)."""
    return Markup(getattr(environment().get_template("macros.html").module, name)(*args))


def data_uri(path: Path) -> str:
    mime = _MIME.get(path.suffix.lower(), "application/octet-stream")
    return f"data:{mime};base64," + base64.b64encode(path.read_bytes()).decode("ascii")


def figure_of(path, caption: str, why: str | None = None) -> Figure:
    """The file as a Figure embedded as a data: URI; a missing file is a Figure without one ("not drawn")."""
    path = Path(path)
    return Figure(path.name, caption, data_uri(path) if path.is_file() else None, why)


def write_page(path: Path, text: str) -> Path:
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(text, encoding="utf-8")
    tmp.replace(path)
    return path


def _page(template: str, out_dir: Path, title: str, **context) -> Path:
    stamp = _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    text = render(template, title=title, version=package_version(), stamp=stamp, **context)
    return write_page(Path(out_dir) / REPORT_NAME, text)


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
    scene = study.scene
    rows = []
    for v in scene.vehicles:
        s = v.spec
        rows.append([v.name, getattr(s, "name", "") or "", num(s.mass, 0), num(s.length, 2), num(s.width, 2),
                     num(v.x, 2), num(v.y, 2), num(math.degrees(v.heading), 1), num(v.speed * 3.6, 1), v.wheels])
    imp = scene.impact
    road = scene.road
    extra = (f"road friction {road.friction:g}" + (f", {len(road.zones)} friction zone(s)" if road.zones else "")
             + (f", {len(road.lines)} road line(s)" if getattr(road, "lines", ()) else "")
             + (f", {len(scene.barriers)} barrier(s)" if scene.barriers else "")
             + "; impact restitution " + ("of the closing speed (\"speed\")" if imp.restitution_law == "speed"
                                           else f"{imp.restitution:g}") + f", friction {imp.friction:g}"
             + ("" if imp.point is None else f", point of impact given at ({imp.point[0]:.2f}, {imp.point[1]:.2f}) m")
             + f"; duration {scene.duration:g} s")
    return {"name": scene.name, "source": scene.source, "extra": extra,
            "table": Table(["vehicle", "data", "mass [kg]", "length [m]", "width [m]", "x [m]", "y [m]",
                            "heading [deg]", "speed [km/h]", "wheels"], rows, "scene", (0, 1, 9))}


def _options(d: dict) -> str:
    return ", ".join(f"{k} = {v}" for k, v in d.items()) if d else "defaults"


def free_table(variables, truth=None) -> Table:
    """The searched variables (label, unit, bounds; the twin's truth)."""
    rows = []
    for j, f in enumerate(variables):
        row = [f.label, variable_unit(f), num(f.lower), num(f.upper)]
        if truth is not None:
            row.append(num(truth[j]) if j < len(truth) else "")
        rows.append(row)
    head = ["free variable", "unit", "lower", "upper"] + (["truth (twin)"] if truth is not None else [])
    return Table(head, rows, "free", (0, 1))


def evidence_context(study) -> dict:
    """The evidence as the objectives use it: measured rest poses (thesis objective, no sigmas), or every
    item with its value and standard deviation (misfit objective)."""
    es = study.evidence_set
    ev = study.spec.evidence
    twin = ("Twin experiment: the evidence is the model's own run of the base scene"
            + ("" if ev.noise_seed is None else f", with Gaussian noise of the given sigmas (noise_seed "
               f"{ev.noise_seed})") + ".") if ev.twin else ""
    if es is None:
        rows = [[n, num(x), num(y), "not measured" if h is None else num(h, 2)]
                for n, (x, y, h) in study.evidence.items()]
        return {"twin": twin, "intro": "Measured rest poses (the thesis objective: f_<vehicle> = |r - r*| + "
                "heading_weight |dpsi| [m]; no standard deviations).",
                "table": Table(["vehicle", "x [m]", "y [m]", "heading [deg]"], rows, "evidence")}
    rows = []
    for it in es.items:
        if it.kind == "marks":
            pts = ", ".join(f"({x:.2f}, {y:.2f})" for x, y in it.points)
            rows.append([it.label, ", ".join(it.vehicles), "CG path through", pts, num(it.sigmas[0]), "m"])
            continue
        for c, v, s in zip(it.components, it.values, it.sigmas):
            rows.append([it.label, ", ".join(it.vehicles), c, num(v), num(s), UNITS.get(c, "")])
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
               "Outcome.first_contact; for a later impact the last recorded sample before it). delta-V: the "
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


def impact_table(outcome, table_id: str = "impacts") -> Table | None:
    """The impact table of a run (IMPACT_NOTE), sorted by time; None when nothing touched."""
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
        rows.append([r["vehicle"], r["other"]] + [num(v, IMPACT_DIGITS[k]) for k, v in values.items()])
    return Table(["vehicle", "other"] + list(IMPACT_DIGITS), rows, table_id, (0, 1))


def solution_context(title, intro, outcome, out_dir, figures) -> Solution | None:
    """The chosen solution's section: its impact table and figures [(file name in out_dir, caption)]."""
    if outcome is None:
        return None
    return Solution(title, intro, impact_table(outcome), IMPACT_NOTE,
                    [figure_of(Path(out_dir) / f, c) for f, c in figures])


# ---------------------------------------------------------------- animation and refine
def _animate(scene, outcome, path: Path, fps: int) -> Path:
    """crashlab.tools.animation.write_animation, imported here so that a crashlab without it still reports."""
    from crashlab.tools.animation import write_animation
    return Path(write_animation(scene, outcome, path, fps=fps))


def animation_context(best, out_dir: Path, what: str) -> dict:
    """best: (scene, outcome) or None. The GIF is written beside the page (ANIMATION_NAME) and embedded;
    "animation unavailable" with the reason when crashlab.tools.animation is missing or fails."""
    ctx = {"what": what, "figure": None, "css": "muted", "text": ""}
    if best is None:
        return ctx | {"text": "animation unavailable: no solution to animate."}
    scene, outcome = best
    try:
        path = _animate(scene, outcome, Path(out_dir) / ANIMATION_NAME, ANIMATION_FPS)
    except ImportError as err:
        return ctx | {"text": f"animation unavailable: crashlab.tools.animation cannot be imported ({err})."}
    except Exception as err:  # noqa: BLE001 - the tables and figures stand without it
        return ctx | {"css": "warn", "text": f"animation unavailable: {type(err).__name__}: {err}"}
    size = path.stat().st_size if path.is_file() else 0
    if size > ANIMATION_EMBED_MAX_BYTES:
        return ctx | {"text": f"{path.name} ({size / 1e6:.1f} MB) is larger than the "
                      f"{ANIMATION_EMBED_MAX_BYTES / 1e6:g} MB embedded at most; it is beside this page."}
    return ctx | {"figure": figure_of(path, f"{what} ({ANIMATION_FPS} frames per second): outlines with headings, "
                                      "CG paths, impacts flashed, time stamp (on paper: its first frame).")}


def animation_section(best, out_dir: Path, what: str) -> Markup:
    return macro("animation_section", animation_context(best, out_dir, what))


def spread_table(refined, evidence: dict) -> Table | None:
    """The spread between the search model and the refine model (a [refine]'s RefineResult): per candidate and
    vehicle, both models' rest poses at the same start, the distance between them and the heading difference."""
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
            rows.append([str(int(r["candidate"])), str(r["row"]), n,
                         num(r[f"search_rest_{n}_x"], 2), num(r[f"search_rest_{n}_y"], 2), num(ha, 1),
                         num(r[f"refine_rest_{n}_x"], 2), num(r[f"refine_rest_{n}_y"], 2), num(hb, 1),
                         num(r[f"model_gap_{n}"], 2), num(wrap_deg(hb - ha) if np.isfinite(ha - hb) else math.nan, 1),
                         "" if m is None else f"{m[0]:.2f}, {m[1]:.2f}" + ("" if m[2] is None else f", {m[2]:.1f}")])
    head = ["candidate", "row", "vehicle", f"{a} x [m]", f"{a} y [m]", f"{a} heading [deg]", f"{b} x [m]",
            f"{b} y [m]", f"{b} heading [deg]", "distance apart [m]", f"heading {b} - {a} [deg]",
            "measured x, y [m], heading [deg]"]
    return Table(head, rows, "spread", (2, 11))


def refine_context(out_dir: Path, refined=None, evidence=None) -> dict | None:
    """The spread between the models (refined: the RefineResult, when there is one), DIR/refine.md (as text)
    and DIR/refine.csv (as a table); None when there is none of them (the report is written once, after the
    refine step)."""
    md, csv = Path(out_dir) / "refine.md", Path(out_dir) / "refine.csv"
    ctx = {"spread": spread_table(refined, evidence or {}) if refined is not None else None, "md": None,
           "csv": None, "error": None, "spread_intro": ""}
    if ctx["spread"] is not None:
        t = refined.table
        gaps = [c for c in t.columns if c.startswith("model_gap_")]
        worst = ", ".join(f"{c[len('model_gap_'):]} {t[c].max():.2f} m" for c in gaps if np.isfinite(t[c]).any())
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
            ctx["csv"] = Table(list(df.columns), [[num(v) if isinstance(v, (int, float, np.number)) else str(v)
                                                   for v in r] for r in df.itertuples(index=False)], "refine", ())
        except Exception as err:  # noqa: BLE001 - an unreadable refine.csv is named, not fatal
            ctx["error"] = f"refine.csv could not be read ({type(err).__name__})."
    if not any(ctx[k] is not None for k in ("spread", "md", "csv", "error")):
        return None
    return ctx


def refine_section(out_dir: Path, refined=None, evidence=None) -> str:
    ctx = refine_context(out_dir, refined, evidence)
    return "" if ctx is None else str(macro("refine_section", ctx))


# ---------------------------------------------------------------- crashlab reconstruct
_KNOWN = ("f_", "dheading_", "misfit_", "log_likelihood", "rest_", "contact_")
_PARETO_GROUPS = (("the start (free variables)", lambda c, free: c in free or (not free and not c.startswith(_KNOWN))),
                  ("objectives and rest-heading errors", lambda c, free: c.startswith(("f_", "dheading_"))),
                  ("misfit of every evidence item", lambda c, free: c.startswith("misfit_") or c == "log_likelihood"),
                  ("rest poses", lambda c, free: c.startswith("rest_")),
                  ("state at first contact", lambda c, free: c.startswith("contact_")))


def pareto_column_groups(columns, free=()) -> list[tuple[str, list[str]]]:
    """pareto.csv's columns in tables of at most PARETO_COLUMNS_MAX: by kind (start, objectives, misfits, rest
    poses, first contact, anything else), whole kinds packed together while they fit, a larger kind split."""
    columns, free = list(columns), set(free)
    kinds, seen = [], set()
    for title, test in _PARETO_GROUPS:
        cols = [c for c in columns if c not in seen and test(c, free)]
        seen |= set(cols)
        if cols:
            kinds.append((title, cols))
    rest = [c for c in columns if c not in seen]
    if rest:
        kinds.append(("other columns", rest))
    tables: list[tuple[list[str], list[str]]] = []
    for title, cols in kinds:
        for k in range(0, len(cols), PARETO_COLUMNS_MAX):
            part = cols[k:k + PARETO_COLUMNS_MAX]
            if tables and k == 0 and len(tables[-1][1]) + len(part) <= PARETO_COLUMNS_MAX:
                tables[-1][0].append(title)
                tables[-1][1].extend(part)
            else:
                tables.append(([title + (" (continued)" if k else "")], list(part)))
    return [(", ".join(t), cols) for t, cols in tables]


def pareto_table_html(pareto, free=()) -> Markup:
    """The Pareto set as tables (ids "pareto", "pareto-2", ...), each with the column "row" (0 = best) and at
    most PARETO_COLUMNS_MAX of pareto.csv's columns, together every column in its order; at most
    PARETO_ROWS_MAX rows (the page says when there are more)."""
    shown = pareto.head(PARETO_ROWS_MAX)
    tables = []
    for j, (title, cols) in enumerate(pareto_column_groups(pareto.columns, free)):
        rows = [[str(k)] + [num(v) for v in r] for k, r in enumerate(shown[cols].itertuples(index=False))]
        tables.append(Table(["row"] + cols, rows, "pareto" if j == 0 else f"pareto-{j + 1}", (),
                            f"Pareto set: {title}"))
    cut = (f"The first {len(shown)} of {len(pareto)} rows are shown; every row is in pareto.csv."
           if len(pareto) > len(shown) else None)
    return macro("pareto_tables", tables, cut)


def evaluations_table(problem, failure_reasons=None, evaluations=None) -> tuple[Table, str]:
    """Every evaluation counted by what became of it: feasible, infeasible (vehicles overlapping at the start,
    no contact) and failed runs by reason (failure_reasons: {reason: count}, crashlab.reconstruction.report
    .failure_counts); and a sentence saying what the counts mean."""
    from .report import evaluation_counts
    counts = evaluation_counts(problem)
    total = counts["total"] or int(evaluations or 0)
    reasons = dict(failure_reasons or {})
    failed = sum(reasons.values()) if reasons else counts["failed"]
    rows = [["feasible (run ok, no overlap at the start, the vehicles collide)", str(counts["feasible"])],
            ["infeasible: vehicles overlap at the start", str(counts["overlap"])],
            ["infeasible: no contact (the vehicles miss each other)", str(counts["no_contact"])],
            ["failed runs", str(failed)]]
    rows += [[f"failed: {r}", str(c)] for r, c in reasons.items()]
    note = (f"{total} evaluations. Infeasible starts are counted where the run succeeded; a failed run is "
            "counted once under its reason (numbers in a reason replaced by N; every failed evaluation with its "
            "start in failures.csv).")
    return Table(["evaluations by outcome", "count"], rows, "evaluations", (0,)), note


def write_reconstruction_report(study, result, out_dir, figures, near_figure=None, near=None, tol=None,
                                best=None, warnings=(), notes=(), failure_reasons=None, time_figure=None,
                                time_distance_figure=None) -> Path:
    """DIR/report.html of a reconstruction. figures: [(file name in out_dir, caption)] top views; best:
    (scene, outcome) of the first Pareto row, for its impact table and the animation; time_figure: the file
    name of its speed / distance / heading against time, time_distance_figure its time-distance diagram;
    near: the near-optimal table (its variable ranges
    shown), tol its bound; warnings: lines shown highlighted under the Pareto set; failure_reasons: {reason:
    count} of the failed evaluations."""
    out_dir = Path(out_dir)
    problem, info, spec = result.problem, result.algorithm_info, study.spec
    opt = spec.optimizer
    truth = problem.base_values() if spec.evidence.twin else None
    sigma = problem.evidence_set is not None
    funit = "sigma" if sigma else "m"
    run = (f"{result.evaluations} evaluations (search {info['search_evaluations']}, least-squares polish "
           f"{info['polish_evaluations']} of a budget of {info['polish_budget']}), failed {result.failed}, "
           f"feasible fraction {result.feasible_fraction:.1%}, wall time {result.wall_time_s:.1f} s")
    study_ctx = {"path": study.path, "model": spec.model, "model_options": _options(spec.model_options),
                 "optimizer": info["optimizer"],
                 "optimizer_text": f"population {info.get('pop_size', opt.pop_size)}, "
                                   f"{info.get('generations', opt.generations)} generations, seed {opt.seed}; "
                                   f"options: {_options(opt.options)}",
                 "mode": study.mode, "run": run,
                 "mode_text": f", heading_weight {problem.heading_weight:g} m/deg" if study.mode == "thesis" else ""}
    evaluations, evaluations_note = evaluations_table(problem, failure_reasons, result.evaluations)
    pareto = result.pareto
    names = list(problem.objective_names)
    free = [f.label for f in problem.free]
    pareto_intro = (f"The rows of pareto.csv, in its order, its columns in tables of at most {PARETO_COLUMNS_MAX}: "
                    f"free variables (file units), objectives f_<vehicle> [{funit}], dheading_<vehicle> (simulated "
                    "minus measured rest heading [deg], wrapped to -180..180; empty where none was measured), "
                    + ("the misfit of every evidence item [sigma] and the log-likelihood, " if sigma else "")
                    + "rest poses and the state at first contact (m, deg, km/h). Row 0 is the chosen solution "
                    "above and is animated below.")
    objectives_figure = (figure_of(out_dir / "objectives.png", f"every feasible evaluation (grey) and the "
                                   f"non-dominated ones (red), objectives [{funit}].") if len(names) >= 2 else None)
    near_ctx = None
    if near is not None:
        near_ctx = {"tol": f"{tol:g} {funit}", "count": len(near), "table": None, "figure": None}
        if len(near):
            near_ctx["table"] = Table(["variable", "unit", "min", "max"],
                                      [[f.label, variable_unit(f), num(near[f.label].min()), num(near[f.label].max())]
                                       for f in problem.free], "near", (0, 1))
            if near_figure:
                near_ctx["figure"] = figure_of(out_dir / near_figure, "the first two free variables of these "
                                               f"starts, coloured by their largest objective [{funit}].")
    solution = None
    if best is not None:
        solution = solution_context(
            "The chosen solution: Pareto row 0", "The start of the smallest sum of objectives, simulated again "
            f"with `{spec.model}`: every impact, and each vehicle's speed, distance travelled and heading against "
            "time.", best[1], out_dir,
            ([(time_figure, "speed, distance travelled along the CG path and heading (continuous) against time; "
               "dashed: the impacts.")] if time_figure else [])
            + ([(time_distance_figure, TIME_DISTANCE_CAPTION)] if time_distance_figure else []))
    return _page("reconstruction.html", out_dir, f"Reconstruction: {spec.name or study.path.stem}",
                 case=case_context(spec), study=study_ctx, evaluations=evaluations,
                 evaluations_note=evaluations_note, free=free_table(problem.free, truth), scene=scene_context(study),
                 evidence=evidence_context(study), solution=solution, n_pareto=len(pareto),
                 pareto_intro=pareto_intro, warnings=list(warnings),
                 pareto_html=pareto_table_html(pareto, free) if len(pareto) else "",
                 objectives_figure=objectives_figure, near=near_ctx,
                 tops=[figure_of(out_dir / f, c) for f, c in figures],
                 animation=animation_context(best, out_dir, "Pareto row 0 (the smallest sum of objectives)"),
                 refine=refine_context(out_dir, getattr(result, "refine", None), study.evidence),
                 notes=list(notes))


# ---------------------------------------------------------------- crashlab infer
def write_posterior_report(post, res, out_dir, warnings=(), best=None, notes=(), questions=(), median=None,
                           median_figures=(), counterfactuals=(), counterfactual_figures=()) -> Path:
    """DIR/report.html of a posterior: the study, the sampler, the evidence, the variables' medians and 90 %
    intervals, the questions, the corner plot, the median draw (median: (scene, outcome, draw index);
    median_figures: [(file name, caption)]) with its impact table, the draws' top view and the animation of
    `best` (scene, outcome: the draw of largest log-likelihood); questions: (question, probability, standard
    error) rows; counterfactuals: counterfactual.answer's rows, counterfactual_figures their [(file name,
    caption)]."""
    out_dir = Path(out_dir)
    study, s = post.study, post.settings
    run = (f"sampler {res.sampler} ({res.walkers} walkers, {res.iterations} iterations of which {res.burn} burn-in "
           f"discarded, thinned by {res.thin}, seed {s.seed}): {len(res.samples)} samples from {res.evaluations} "
           f"model evaluations in {res.wall_time_s:.1f} s; mean acceptance {res.acceptance:.2f}")
    lo, med, hi = res.interval()
    truth = res.truth
    head = ["variable", "unit", "prior", "lower", "upper", "median", "5 %", "95 %", "tau [it]", "ESS"]
    if truth is not None:
        head += ["truth (twin)", "inside"]
    rows = []
    for j, v in enumerate(post.variables):
        r = [v.label, v.unit, v.describe_prior(), num(v.lower), num(v.upper), num(med[j]), num(lo[j]), num(hi[j]),
             num(res.tau[j], 1), num(res.ess[j], 0)]
        if truth is not None:
            r += [num(truth[j]), "yes" if lo[j] <= truth[j] <= hi[j] else "**NO**"]
        rows.append(r)
    qtable = (Table(["question", "probability", "MC standard error"],
                    [[f"`{q}`", num(p), num(se)] for q, p, se in questions], "questions", md_cols=(0,))
              if questions else None)
    ctable = None
    if counterfactuals:
        names = post.study.scene.vehicle_names
        ctable = Table(["counterfactual", "draws", "failed", "avoided", "90 % interval"]
                       + [f"{n} impact speed, median [km/h]" for n in names]
                       + ["miss distance, median (5-95 %) [m]", "time gap, median (5-95 %) [s]"],
                       [[r["name"], str(r["draws"]), str(r["failed"]), num(r["p_avoided"]),
                         f"{num(r['p_avoided_5'])}-{num(r['p_avoided_95'])}"]
                        + [num(r[f"{n}.impact_speed_50"], 1) for n in names]
                        + [_median_range(r, "miss_distance", 2), _median_range(r, "time_gap", 2)]
                        for r in counterfactuals], "counterfactuals")
    corner = figure_of(out_dir / "corner.png", "the posterior's one- and two-variable marginals (each axis in its "
                       "variable's unit); dashed: 5, 50 and 95 % quantiles"
                       + ("; lines: the twin's truth" if truth is not None else "") + ".")
    solution = None
    if median is not None:
        scene, outcome, k = median
        solution = solution_context(
            "The median draw", f"The posterior draw nearest the median of every variable (draw {k} of "
            "posterior.csv; distance in units of each variable's 90 % interval), simulated again with "
            f"`{study.spec.model}`: " + ", ".join(f"{lab} = {res.samples[k, j]:.3f}" for j, lab in
                                                  enumerate(res.labels)) + ".",
            outcome, out_dir, list(median_figures))
    tops = (figure_of(out_dir / "posterior_top_view.png", "rest outlines and CG paths of posterior draws over the "
                      "measured rest poses (thick).") if s.draws_plotted else None)
    return _page("posterior.html", out_dir, f"Posterior: {study.spec.name or post.path.name}",
                 case=case_context(study.spec),
                 study={"path": post.path, "model": study.spec.model,
                        "model_options": _options(study.spec.model_options), "run": run},
                 scene=scene_context(study), evidence=evidence_context(study),
                 posterior=Table(head, rows, "posterior", (0, 1, 2), md_cols=(len(head) - 1,)),
                 warnings=list(warnings), questions=qtable, counterfactuals=ctable,
                 counterfactual_figures=[figure_of(out_dir / f, c) for f, c in counterfactual_figures],
                 corner=corner, solution=solution, tops=tops,
                 animation=animation_context(best, out_dir, "the posterior draw of largest log-likelihood"),
                 refine=refine_context(out_dir, getattr(res, "refine", None), study.evidence), notes=list(notes))


def _median_range(row, what, digits) -> str:
    """"median (5 % to 95 %)" of counterfactual row's `what`; empty when not measured."""
    m = row.get(f"{what}_50", math.nan)
    if not math.isfinite(m):
        return ""
    return f"{num(m, digits)} ({num(row[f'{what}_5'], digits)} to {num(row[f'{what}_95'], digits)})"


# ---------------------------------------------------------------- PDF
PDF_LIBRARY = "WeasyPrint"
PDF_INSTALL = ("pip install weasyprint (it needs the Pango library: Debian/Ubuntu apt-get install libpango-1.0-0 "
               "libpangoft2-1.0-0; macOS brew install pango)")


def pdf_writer():
    """weasyprint.HTML, or the reason it cannot be used (ImportError: not installed; OSError: Pango missing)."""
    try:
        from weasyprint import HTML
    except (ImportError, OSError) as err:
        return None, f"{type(err).__name__}: {err}".splitlines()[0]
    return HTML, None


def check_pdf(source, out_dir) -> None:
    """InputError (key --pdf) unless a PDF can be written: --out given and WeasyPrint usable. Called before a
    run, so a missing library does not cost the search."""
    if not out_dir:
        raise InputError(source, "--pdf", "needs --out DIR (the PDF is DIR/report.pdf, printed from DIR/report.html)")
    html, why = pdf_writer()
    if html is None:
        raise InputError(source, "--pdf", f"{PDF_LIBRARY} cannot be loaded ({why}): {PDF_INSTALL}")


def write_pdf(html_path) -> Path:
    """report.pdf beside report.html: the same page through its print style sheet (A4), with WeasyPrint."""
    html_path = Path(html_path)
    html, why = pdf_writer()
    if html is None:
        raise InputError(html_path, "--pdf", f"{PDF_LIBRARY} cannot be loaded ({why}): {PDF_INSTALL}")
    pdf = html_path.with_name(PDF_NAME)
    tmp = pdf.with_name(pdf.name + ".tmp")
    html(filename=str(html_path), media_type="print").write_pdf(str(tmp))
    tmp.replace(pdf)
    return pdf
