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

Here: the reconstruction's page (the Pareto tables, the evaluations by outcome), the animation both pages
embed and the PDF. The pieces: html_page (tables, figures, rendering: Python builds plain data, the templates
hold every tag), html_sections (the sections both pages show); the posterior's page: html_posterior.
"""
from __future__ import annotations

from pathlib import Path

from markupsafe import Markup

from crashlab.errors import InputError
from crashlab.units import frame_in, shown_name, unit_in, value_in

from .avoidance import TIME_DISTANCE_CAPTION
from .html_page import REPORT_NAME, Table, figure_of, macro, num, write_report_page  # noqa: F401 (crashlab.cli: REPORT_NAME)
from .html_sections import (
    _options,
    case_context,
    evidence_context,
    free_table,
    refine_context,
    scene_context,
    solution_context,
)
from .problem import variable_unit

PDF_NAME = "report.pdf"
ANIMATION_NAME = "best.gif"
ANIMATION_FPS = 10  # frames per second of the embedded GIF: smooth enough, small enough
# an animation larger than this is left beside the page instead of embedded (keeps the page under 5 MB)
ANIMATION_EMBED_MAX_BYTES = 3_000_000
PARETO_ROWS_MAX = 2000  # Pareto rows shown (about 1 MB of table); the page says when pareto.csv has more
PARETO_COLUMNS_MAX = 12  # data columns per Pareto table (besides "row"): an A4 page's width at 7 pt


# ---------------------------------------------------------------- animation
def _animate(scene, outcome, path: Path, fps: int, system: str = "si") -> Path:
    """crashlab.tools.animation.write_animation, imported here so that a crashlab without it still reports."""
    from crashlab.tools.animation import write_animation
    return Path(write_animation(scene, outcome, path, fps=fps, system=system))


def animation_context(best, out_dir: Path, what: str, system: str = "si") -> dict:
    """best: (scene, outcome) or None. The GIF is written beside the page (ANIMATION_NAME) and embedded;
    "animation unavailable" with the reason when crashlab.tools.animation is missing or fails."""
    ctx = {"what": what, "figure": None, "css": "muted", "text": ""}
    if best is None:
        return ctx | {"text": "animation unavailable: no solution to animate."}
    scene, outcome = best
    try:
        path = _animate(scene, outcome, Path(out_dir) / ANIMATION_NAME, ANIMATION_FPS, system)
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
    from .problem import evaluation_counts
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
    from .report import pareto_units
    out_dir = Path(out_dir)
    problem, info, spec = result.problem, result.algorithm_info, study.spec
    system = study.shown_units  # every number on the page in these units (crashlab.units, shown units)
    opt = spec.optimizer
    truth = problem.base_values() if spec.evidence.twin else None
    sigma = problem.evidence_set is not None
    funit = "sigma" if sigma else unit_in("m", system)
    run = (f"{result.evaluations} evaluations (search {info['search_evaluations']}, least-squares polish "
           f"{info['polish_evaluations']} of a budget of {info['polish_budget']}), failed {result.failed}, "
           f"feasible fraction {result.feasible_fraction:.1%}, wall time {result.wall_time_s:.1f} s")
    study_ctx = {"path": study.path, "model": spec.model, "model_options": _options(spec.model_options),
                 "optimizer": info["optimizer"],
                 "optimizer_text": f"population {info.get('pop_size', opt.pop_size)}, "
                                   f"{info.get('generations', opt.generations)} generations, seed {opt.seed}; "
                                   f"options: {_options(opt.options)}",
                 "mode": study.mode, "run": run,
                 "mode_text": f", heading_weight {value_in(problem.heading_weight, 'm/deg', system):g} "
                              f"{unit_in('m/deg', system)}" if study.mode == "thesis" else ""}
    evaluations, evaluations_note = evaluations_table(problem, failure_reasons, result.evaluations)
    units = pareto_units(problem)
    pareto = frame_in(result.pareto, system, units)
    names = list(problem.objective_names)
    free = [shown_name(f.label, units[f.label], system) for f in problem.free]
    pareto_intro = (f"The rows of pareto.csv, in its order, its columns in tables of at most {PARETO_COLUMNS_MAX}: "
                    f"free variables ({'file units' if system != 'us' else 'US units'}), objectives f_<vehicle> "
                    f"[{funit}], dheading_<vehicle> (simulated "
                    "minus measured rest heading [deg], wrapped to -180..180; empty where none was measured), "
                    + ("the misfit of every evidence item [sigma] and the log-likelihood, " if sigma else "")
                    + "rest poses and the state at first contact ("
                    + ", ".join(unit_in(u, system) for u in ("m", "deg", "km/h")) + "). Row 0 is the chosen solution "
                    "above and is animated below.")
    objectives_figure = (figure_of(out_dir / "objectives.png", f"every feasible evaluation (grey) and the "
                                   f"non-dominated ones (red), objectives [{funit}].") if len(names) >= 2 else None)
    near_ctx = None
    if near is not None:
        near_ctx = {"tol": f"{value_in(tol, 'm' if not sigma else '', system):g} {funit}", "count": len(near),
                    "table": None, "figure": None}
        if len(near):
            near_ctx["table"] = Table(["variable", "unit", "min", "max"],
                                      [[f.label, unit_in(variable_unit(f), system),
                                        num(value_in(near[f.label].min(), variable_unit(f), system)),
                                        num(value_in(near[f.label].max(), variable_unit(f), system))]
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
            + ([(time_distance_figure, TIME_DISTANCE_CAPTION)] if time_distance_figure else []), system)
    return write_report_page("reconstruction.html", out_dir, f"Reconstruction: {spec.name or study.path.stem}",
                 case=case_context(spec), study=study_ctx, evaluations=evaluations,
                 evaluations_note=evaluations_note, free=free_table(problem.free, truth, system),
                 scene=scene_context(study),
                 evidence=evidence_context(study), solution=solution, n_pareto=len(pareto),
                 pareto_intro=pareto_intro, warnings=list(warnings),
                 pareto_html=pareto_table_html(pareto, free) if len(pareto) else "",
                 objectives_figure=objectives_figure, near=near_ctx,
                 tops=[figure_of(out_dir / f, c) for f, c in figures],
                 animation=animation_context(best, out_dir, "Pareto row 0 (the smallest sum of objectives)", system),
                 refine=refine_context(out_dir, getattr(result, "refine", None), study.evidence, system),
                 notes=list(notes))


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
