"""DIR/report.html of `crashlab reconstruct --out DIR` and `crashlab infer --out DIR`: one self-contained
page (every figure embedded as a base64 data: URI; no script, style sheet, font or image from elsewhere)
with the study (scene, free variables and their bounds, optimizer or sampler, model), the evidence with its
sigmas, the Pareto set (the rows of pareto.csv, at most PARETO_ROWS_MAX) or the posterior summary and corner
plot, the top views, the near-optimal figure where one was drawn, an animation of the best solution
(crashlab.tools.animation, when that module is there) and DIR/refine.md and refine.csv when a refine step wrote
them. The page is written once, after every file it shows exists (reconstruction.run, reconstruction.infer).

Written with the standard library only (f-strings and html.escape): the page is a few tables and images.
A figure named but not on disk is said so on the page ("not drawn"), never left as a broken image.
"""
from __future__ import annotations

import base64
import datetime as _dt
import html
import math
import re
from pathlib import Path

import numpy as np

from crashlab.version import package_version

from .evidence import UNITS
from .problem import variable_unit

REPORT_NAME = "report.html"
ANIMATION_NAME = "best.gif"
ANIMATION_FPS = 10  # frames per second of the embedded GIF: smooth enough, small enough
# an animation larger than this is left beside the page instead of embedded (keeps the page under 5 MB)
ANIMATION_EMBED_MAX_BYTES = 3_000_000
PARETO_ROWS_MAX = 2000  # Pareto rows shown (about 1 MB of table); the page says so when pareto.csv has more
_MIME = {".png": "image/png", ".gif": "image/gif", ".jpg": "image/jpeg", ".jpeg": "image/jpeg",
         ".svg": "image/svg+xml"}

_STYLE = """
body{font-family:system-ui,-apple-system,"Segoe UI",Roboto,sans-serif;margin:1.5em auto;max-width:1200px;
padding:0 1em;color:#222;line-height:1.4}
h1{font-size:1.6em;border-bottom:2px solid #444;padding-bottom:.2em}
h2{font-size:1.25em;margin-top:1.6em;border-bottom:1px solid #bbb}
h3{font-size:1.05em}
table{border-collapse:collapse;font-size:.85em;margin:.5em 0}
th,td{border:1px solid #ccc;padding:.15em .45em;text-align:right;white-space:nowrap}
th{background:#f0f0f0;position:sticky;top:0}
td.text,th.text{text-align:left;white-space:normal}
.scroll{max-height:32em;overflow:auto;border:1px solid #ddd;display:inline-block;max-width:100%}
figure{margin:1em 0;display:inline-block;vertical-align:top;max-width:100%}
figure img{max-width:100%;height:auto;border:1px solid #ddd}
figcaption{font-size:.85em;color:#444;max-width:50em}
.warn{background:#fff3cd;border:1px solid #e0c060;padding:.4em .6em}
.muted{color:#666}
pre{background:#f6f6f6;padding:.6em;overflow:auto;font-size:.85em}
code{background:#f3f3f3;padding:0 .2em}
"""


# ---------------------------------------------------------------- small pieces
def esc(value) -> str:
    return html.escape(str(value), quote=True)


def md_inline(text: str) -> str:
    """A line of summary.md's markdown as HTML: escaped, **bold** and `code` kept (nothing else is used)."""
    s = esc(text)
    s = re.sub(r"\*\*(.+?)\*\*", r"<strong>\1</strong>", s)
    return re.sub(r"`(.+?)`", r"<code>\1</code>", s)


def num(value, digits: int = 3) -> str:
    """A table cell's number: fixed `digits` decimals within [1e-3, 1e7), else scientific; empty for NaN
    and None. The shown value is within 0.5e-3 absolute or 0.5e-3 relative of the true one (the test's
    tolerance)."""
    if value is None:
        return ""
    try:
        v = float(value)
    except (TypeError, ValueError):
        return esc(value)
    if math.isnan(v):
        return ""
    if v == 0 or 1e-3 <= abs(v) < 1e7:
        return f"{v:.{digits}f}"
    return f"{v:.{digits}e}"


def table(header, rows, table_id: str | None = None, text_cols=(0,), scroll: bool = False) -> str:
    """An HTML table; cells are given already as HTML (escape text with esc); columns in text_cols are
    left-aligned."""
    tid = f' id="{esc(table_id)}"' if table_id else ""

    def cls(j):
        return ' class="text"' if j in text_cols else ""
    head = "".join(f"<th{cls(j)}>{h}</th>" for j, h in enumerate(header))
    body = "\n".join("<tr>" + "".join(f"<td{cls(j)}>{c}</td>" for j, c in enumerate(r)) + "</tr>" for r in rows)
    out = f"<table{tid}>\n<thead><tr>{head}</tr></thead>\n<tbody>\n{body}\n</tbody>\n</table>"
    return f'<div class="scroll">{out}</div>' if scroll else out


def data_uri(path: Path) -> str:
    mime = _MIME.get(path.suffix.lower(), "application/octet-stream")
    return f"data:{mime};base64," + base64.b64encode(path.read_bytes()).decode("ascii")


def figure(path: Path, caption: str) -> str:
    """The file embedded as a data: URI with its caption; a missing file is said so."""
    path = Path(path)
    if not path.is_file():
        return f'<p class="muted">{esc(path.name)}: not drawn.</p>'
    return (f'<figure><img src="{data_uri(path)}" alt="{esc(path.name)}" data-file="{esc(path.name)}">'
            f"<figcaption>{esc(path.name)}: {md_inline(caption)}</figcaption></figure>")


def page(title: str, sections: list[str]) -> str:
    stamp = _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    return ("<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
            f"<title>{esc(title)}</title>\n<style>{_STYLE}</style>\n</head>\n<body>\n<h1>{esc(title)}</h1>\n"
            f'<p class="muted">crashlab {esc(package_version())}, written {stamp}. Every figure is embedded in '
            "this one file.</p>\n" + "\n".join(s for s in sections if s) + "\n</body>\n</html>\n")


def write_page(path: Path, text: str) -> Path:
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(text, encoding="utf-8")
    tmp.replace(path)
    return path


# ---------------------------------------------------------------- the study and the evidence
def _scene_section(study) -> str:
    scene = study.scene
    rows = []
    for v in scene.vehicles:
        s = v.spec
        rows.append([esc(v.name), esc(getattr(s, "name", "") or ""), num(s.mass, 0), num(s.length, 2),
                     num(s.width, 2), num(v.x, 2), num(v.y, 2), num(math.degrees(v.heading), 1),
                     num(v.speed * 3.6, 1), esc(v.wheels)])
    imp = scene.impact
    extra = (f"road friction {scene.road.friction:g}" + (f", {len(scene.road.zones)} friction zone(s)"
                                                          if scene.road.zones else "")
             + (f", {len(scene.barriers)} barrier(s)" if scene.barriers else "")
             + "; impact restitution " + ("of the closing speed (\"speed\")" if imp.restitution_law == "speed"
                                           else f"{imp.restitution:g}") + f", friction {imp.friction:g}"
             + ("" if imp.point is None else f", point of impact given at ({imp.point[0]:.2f}, {imp.point[1]:.2f}) m")
             + f"; duration {scene.duration:g} s")
    return (f"<h3>Scene: {esc(scene.name)}</h3>\n<p>File <code>{esc(scene.source)}</code>; {esc(extra)}. "
            "The start states below are the base scene's; the free variables replace theirs.</p>\n"
            + table(["vehicle", "data", "mass [kg]", "length [m]", "width [m]", "x [m]", "y [m]",
                     "heading [deg]", "speed [km/h]", "wheels"], rows, text_cols=(0, 1, 9)))


def _options(d: dict) -> str:
    return ", ".join(f"{esc(k)} = {esc(v)}" for k, v in d.items()) if d else "defaults"


def _free_section(variables, truth=None) -> str:
    """The searched variables (label, unit, bounds; the twin's truth) as a table."""
    rows = []
    for j, f in enumerate(variables):
        row = [esc(f.label), esc(variable_unit(f)), num(f.lower), num(f.upper)]
        if truth is not None:
            row.append(num(truth[j]) if j < len(truth) else "")
        rows.append(row)
    head = ["free variable", "unit", "lower", "upper"] + (["truth (twin)"] if truth is not None else [])
    return table(head, rows, table_id="free", text_cols=(0, 1))


def evidence_section(study) -> str:
    """The evidence as the objectives use it: measured rest poses (thesis objective, no sigmas), or every
    item with its value and standard deviation (misfit objective)."""
    es = study.evidence_set
    ev = study.spec.evidence
    twin = ("<p>Twin experiment: the evidence is the model's own run of the base scene"
            + ("" if ev.noise_seed is None else f", with Gaussian noise of the given sigmas (noise_seed "
               f"{ev.noise_seed})") + ".</p>\n") if ev.twin else ""
    if es is None:
        rows = [[esc(n), num(x), num(y), "not measured" if h is None else num(h, 2)]
                for n, (x, y, h) in study.evidence.items()]
        return ("<h2>Evidence</h2>\n" + twin + "<p>Measured rest poses (the thesis objective: "
                "f_&lt;vehicle&gt; = |r - r*| + heading_weight |dpsi| [m]; no standard deviations).</p>\n"
                + table(["vehicle", "x [m]", "y [m]", "heading [deg]"], rows, table_id="evidence"))
    unit = UNITS  # crashlab.reconstruction.evidence: one unit table
    rows = []
    for it in es.items:
        if it.kind == "marks":
            pts = ", ".join(f"({x:.2f}, {y:.2f})" for x, y in it.points)
            rows.append([esc(it.label), esc(", ".join(it.vehicles)), "CG path through", esc(pts),
                         num(it.sigmas[0]), "m"])
            continue
        for c, v, s in zip(it.components, it.values, it.sigmas):
            rows.append([esc(it.label), esc(", ".join(it.vehicles)), esc(c), num(v), num(s), esc(unit.get(c, ""))])
    return ("<h2>Evidence</h2>\n" + twin + "<p>Every item with its standard deviation (sigma). Objectives: "
            "f_&lt;vehicle&gt; = sqrt(sum (residual / sigma)^2) over the items that concern the vehicle; "
            "log-likelihood = -0.5 sum (residual / sigma)^2 over all items, each once.</p>\n"
            + table(["item", "vehicles", "component", "value", "sigma", "unit"], rows, table_id="evidence",
                    text_cols=(0, 1, 2, 3, 5)))


# ---------------------------------------------------------------- animation and refine
def _animate(scene, outcome, path: Path, fps: int) -> Path:
    """crashlab.tools.animation.write_animation, imported here so that a crashlab without it still reports."""
    from crashlab.tools.animation import write_animation
    return Path(write_animation(scene, outcome, path, fps=fps))


def animation_section(best, out_dir: Path, what: str) -> str:
    """best: (scene, outcome) or None. The GIF is written beside the page (ANIMATION_NAME) and embedded;
    "animation unavailable" with the reason when crashlab.tools.animation is missing or fails."""
    head = f"<h2>Animation of {esc(what)}</h2>\n"
    if best is None:
        return head + '<p class="muted">animation unavailable: no solution to animate.</p>'
    scene, outcome = best
    try:
        path = _animate(scene, outcome, out_dir / ANIMATION_NAME, ANIMATION_FPS)
    except ImportError as err:
        return head + (f'<p class="muted">animation unavailable: crashlab.tools.animation cannot be imported '
                       f"({esc(err)}).</p>")
    except Exception as err:  # noqa: BLE001 - the tables and figures stand without it
        return head + f'<p class="warn">animation unavailable: {esc(type(err).__name__)}: {esc(err)}</p>'
    size = path.stat().st_size if path.is_file() else 0
    if size > ANIMATION_EMBED_MAX_BYTES:
        return head + (f'<p class="muted">{esc(path.name)} ({size / 1e6:.1f} MB) is larger than the '
                       f"{ANIMATION_EMBED_MAX_BYTES / 1e6:g} MB embedded at most; it is beside this page.</p>")
    return head + figure(path, f"{what} ({ANIMATION_FPS} frames per second): outlines with headings, CG paths, "
                         "impacts flashed, time stamp.")


def refine_section(out_dir: Path) -> str:
    """DIR/refine.md (as text) and DIR/refine.csv (as a table); empty when neither file is there (the
    report is written once, after the refine step)."""
    parts = []
    md, csv = Path(out_dir) / "refine.md", Path(out_dir) / "refine.csv"
    if md.is_file():
        parts.append(f"<pre>{esc(md.read_text(encoding='utf-8', errors='replace'))}</pre>")
    if csv.is_file():
        import pandas as pd
        try:
            df = pd.read_csv(csv)
            parts.append(table([esc(c) for c in df.columns],
                               [[num(v) if isinstance(v, (int, float, np.number)) else esc(v) for v in r]
                                for r in df.itertuples(index=False)], table_id="refine", text_cols=(),
                               scroll=True))
        except Exception as err:  # noqa: BLE001 - an unreadable refine.csv is named, not fatal
            parts.append(f'<p class="warn">refine.csv could not be read: {esc(type(err).__name__)}: '
                         f"{esc(err)}</p>")
    return ("<h2>Refinement</h2>\n" + "\n".join(parts)) if parts else ""


def _notes(notes) -> str:
    if not notes:
        return ""
    return "<h2>Notes</h2>\n<ul>" + "".join(f"<li>{md_inline(n)}</li>" for n in notes) + "</ul>"


# ---------------------------------------------------------------- crashlab reconstruct
def pareto_table_html(pareto) -> str:
    """The Pareto table (id "pareto"): a column "row" (0 = best) and every column of pareto.csv, at most
    PARETO_ROWS_MAX rows (the page says when there are more)."""
    shown = pareto.head(PARETO_ROWS_MAX)
    rows = [[str(k)] + [num(v) for v in r] for k, r in enumerate(shown.itertuples(index=False))]
    out = table(["row"] + [esc(c) for c in pareto.columns], rows, table_id="pareto", text_cols=(), scroll=True)
    if len(pareto) > len(shown):
        out += (f'\n<p class="warn">The first {len(shown)} of {len(pareto)} rows are shown; every row is in '
                "pareto.csv.</p>")
    return out


def write_reconstruction_report(study, result, out_dir, figures, near_figure=None, near=None, tol=None,
                                best=None, warnings=(), notes=(), failure_reasons=None) -> Path:
    """DIR/report.html of a reconstruction. figures: [(file name in out_dir, caption)] top views; best:
    (scene, outcome) of the first Pareto row, for the animation; near: the near-optimal table (its
    variable ranges shown), tol its bound; warnings: lines shown highlighted under the Pareto set;
    failure_reasons: {reason: count} of the failed evaluations."""
    out_dir = Path(out_dir)
    problem, info, spec = result.problem, result.algorithm_info, study.spec
    title = f"Reconstruction: {spec.name or study.path.stem}"
    opt = spec.optimizer
    truth = problem.base_values() if spec.evidence.twin else None
    run = (f"{result.evaluations} evaluations (search {info['search_evaluations']}, least-squares polish "
           f"{info['polish_evaluations']} of a budget of {info['polish_budget']}), failed {result.failed}, "
           f"feasible fraction {result.feasible_fraction:.1%}, wall time {result.wall_time_s:.1f} s")
    study_html = ("<h2>Study</h2>\n"
                  f"<p>Study file <code>{esc(study.path)}</code>; model <code>{esc(spec.model)}</code> "
                  f"(options: {_options(spec.model_options)}); optimizer <code>{esc(info['optimizer'])}</code> "
                  f"(population {info.get('pop_size', opt.pop_size)}, {info.get('generations', opt.generations)} "
                  f"generations, seed {opt.seed}; options: {_options(opt.options)}); objective "
                  f"<code>{esc(study.mode)}</code>"
                  + (f", heading_weight {problem.heading_weight:g} m/deg" if study.mode == "thesis" else "")
                  + ".</p>\n" + f"<p>Run: {esc(run)}.</p>\n")
    if failure_reasons:
        study_html += ("<p>Failed evaluations by reason (every one in failures.csv): "
                       + esc("; ".join(f"{c} x {r}" for r, c in list(failure_reasons.items())[:5])) + "</p>\n")
    study_html += _free_section(problem.free, truth) + "\n" + _scene_section(study)

    pareto = result.pareto
    names = list(problem.objective_names)
    funit = "m" if problem.evidence_set is None else "normalised misfit"
    sec = [f"<h2>Pareto set ({len(pareto)} solutions, sorted by the sum of objectives)</h2>"]
    if len(pareto):
        sec.append(f"<p>The rows of pareto.csv, in its order and with its columns: free variables (file units), "
                   f"objectives f_&lt;vehicle&gt; [{esc(funit)}], dheading_&lt;vehicle&gt; (simulated minus "
                   "measured rest heading [deg], wrapped to -180..180; empty where none was measured), "
                   + ("the misfit of every evidence item and the log-likelihood, " if problem.evidence_set
                      is not None else "")
                   + "rest poses and the state at first contact (m, deg, km/h). Row 0 is animated below.</p>")
        sec += [f'<p class="warn">{md_inline(w)}</p>' for w in warnings]
        sec.append(pareto_table_html(pareto))
    else:
        sec.append("<p>No feasible solution.</p>")
    sec.append(figure(out_dir / "objectives.png", f"every feasible evaluation (grey) and the non-dominated "
                      f"ones (red), objectives [{funit}], log axes.") if len(names) >= 2 else "")

    near_html = ""
    if near is not None:
        unit = " m" if problem.evidence_set is None else " (normalised misfit)"
        near_html = f"<h2>Starts that explain the evidence within {tol:g}{esc(unit)} ({len(near)} evaluated)</h2>\n"
        if len(near):
            cols = [f.label for f in problem.free]
            near_html += ("<p>Every objective at most the bound (<code>[objective] near_optimal</code>); all in "
                          "near_optimal.csv. The evidence cannot tell these starts apart; their range is only what the "
                          "search tried, at least what the evidence leaves open, not an uncertainty interval (that "
                          "is the posterior: crashlab infer).</p>\n"
                          + table(["variable", "min", "max"], [[esc(c), num(near[c].min()), num(near[c].max())]
                                                               for c in cols], table_id="near"))
            if near_figure:
                near_html += "\n" + figure(out_dir / near_figure, "the first two free variables of these starts, "
                                           "coloured by their largest objective.")
        else:
            near_html += "<p>None: no evaluated start explains every vehicle's rest pose that well.</p>"

    tops = "<h2>Top views</h2>\n"
    tops += ("<p>Start dotted, first contact dashed, rest solid, measured rest pose thick and pale, heading "
             "arrows in each vehicle's colour.</p>\n" + "\n".join(figure(out_dir / f, c) for f, c in figures)
             if figures else '<p class="muted">No top view drawn.</p>')
    sections = [study_html, evidence_section(study), "\n".join(s for s in sec if s), near_html, tops,
                animation_section(best, out_dir, "Pareto row 0 (the smallest sum of objectives)"),
                refine_section(out_dir), _notes(notes)]
    return write_page(out_dir / REPORT_NAME, page(title, sections))


# ---------------------------------------------------------------- crashlab infer
def write_posterior_report(post, res, out_dir, warnings=(), best=None, notes=(), questions=()) -> Path:
    """DIR/report.html of a posterior: the study, the sampler, the evidence, the variables' medians and 90 %
    intervals, the questions, the corner plot, the draws' top view and the animation of `best` (scene,
    outcome: the draw of largest log-likelihood); questions: (question, probability, standard error) rows."""
    out_dir = Path(out_dir)
    study, s = post.study, post.settings
    title = f"Posterior: {study.spec.name or post.path.name}"
    run = (f"sampler {res.sampler} ({res.walkers} walkers, {res.iterations} iterations of which {res.burn} burn-in "
           f"discarded, thinned by {res.thin}, seed {s.seed}): {len(res.samples)} samples from {res.evaluations} "
           f"model evaluations in {res.wall_time_s:.1f} s; mean acceptance {res.acceptance:.2f}")
    study_html = ("<h2>Study</h2>\n"
                  f"<p>Study file <code>{esc(post.path)}</code>; model <code>{esc(study.spec.model)}</code> "
                  f"(options: {_options(study.spec.model_options)}); {esc(run)}.</p>\n")
    lo, med, hi = res.interval()
    truth = res.truth
    head = ["variable", "unit", "prior", "lower", "upper", "median", "5 %", "95 %", "tau [it]", "ESS"]
    if truth is not None:
        head += ["truth (twin)", "inside"]
    rows = []
    for j, v in enumerate(post.variables):
        r = [esc(v.label), esc(v.unit), esc(v.describe_prior()), num(v.lower), num(v.upper), num(med[j]),
             num(lo[j]), num(hi[j]), num(res.tau[j], 1), num(res.ess[j], 0)]
        if truth is not None:
            r += [num(truth[j]), "yes" if lo[j] <= truth[j] <= hi[j] else "<strong>NO</strong>"]
        rows.append(r)
    post_html = ["<h2>Posterior (median and 90 % interval)</h2>",
                 "<p>Free variables first, then the uncertain parameters. ESS: walkers x kept iterations / tau, tau "
                 "the integrated autocorrelation time. Every sample is in posterior.csv.</p>",
                 table(head, rows, table_id="posterior", text_cols=(0, 1, 2))]
    post_html += [f'<p class="warn">{md_inline(w)}</p>' for w in warnings]
    if questions:
        post_html += ["<h3>Questions</h3>",
                      table(["question", "probability", "MC standard error"],
                            [[f"<code>{esc(q)}</code>", num(p), num(se)] for q, p, se in questions],
                            table_id="questions")]
    post_html.append(figure(out_dir / "corner.png", "the posterior's one- and two-variable marginals; dashed: 5, "
                            "50 and 95 % quantiles" + ("; lines: the twin's truth" if truth is not None else "") + "."))
    tops = ""
    if s.draws_plotted:
        tops = ("<h2>Top view of posterior draws</h2>\n"
                + figure(out_dir / "posterior_top_view.png", "rest outlines and CG paths of posterior draws over "
                         "the measured rest poses (thick)."))
    sections = [study_html + _scene_section(study), evidence_section(study),
                "\n".join(post_html), tops,
                animation_section(best, out_dir, "the posterior draw of largest log-likelihood"),
                refine_section(out_dir), _notes(notes)]
    return write_page(out_dir / REPORT_NAME, page(title, sections))
