"""DIR/report.html of `crashlab infer --out DIR` (the page: crashlab.reconstruction.html_report's docstring;
the pieces: html_page, html_sections): the study, the sampler, the evidence, the posterior's medians and 90 %
intervals, the questions, the counterfactuals, the corner plot, the median draw, the draws' top view and an
animation."""
from __future__ import annotations

import math
from pathlib import Path

from crashlab.units import unit_in, value_in

from .html_page import Table, figure_of, num, write_report_page
from .html_report import animation_context
from .html_sections import _options, case_context, evidence_context, refine_context, scene_context, solution_context


def write_posterior_report(post, res, out_dir, warnings=(), best=None, notes=(), questions=(), median=None,
                           median_figures=(), counterfactuals=(), counterfactual_figures=()) -> Path:
    """DIR/report.html of a posterior: the study, the sampler, the evidence, the variables' medians and 90 %
    intervals, the questions, the corner plot, the median draw (median: (scene, outcome, draw index);
    median_figures: [(file name, caption)]) with its impact table, the draws' top view and the animation of
    `best` (scene, outcome: the draw of largest log-likelihood); questions: (question, probability, standard
    error) rows; counterfactuals: counterfactual.answer's rows, counterfactual_figures their [(file name,
    caption)]."""
    from .infer_report import QUESTION_UNITS_HEAD, prior_text, question_note, question_units, shown_row
    out_dir = Path(out_dir)
    study, s = post.study, post.settings
    system = study.shown_units  # every number on the page in these units (crashlab.units, shown units)
    run = (f"sampler {res.sampler} ({res.walkers} walkers, {res.iterations} iterations of which {res.burn} burn-in "
           f"discarded, thinned by {res.thin}, seed {s.seed}): {len(res.samples)} samples from {res.evaluations} "
           f"model evaluations in {res.wall_time_s:.1f} s; mean acceptance {res.acceptance:.2f}")
    lo, med, hi = (shown_row(post, q, system) for q in res.interval())
    truth = None if res.truth is None else shown_row(post, res.truth, system)
    head = ["variable", "unit", "prior", "lower", "upper", "median", "5 %", "95 %", "tau [it]", "ESS"]
    if truth is not None:
        head += ["truth (twin)", "inside"]
    rows = []
    for j, v in enumerate(post.variables):
        r = [v.label, unit_in(v.unit, system), prior_text(v, system), num(value_in(v.lower, v.unit, system)),
             num(value_in(v.upper, v.unit, system)), num(med[j]), num(lo[j]), num(hi[j]), num(res.tau[j], 1) or "-",
             num(res.ess[j], 0) or "-"]  # a dash: too short a chain to estimate them (chain_warnings)
        if truth is not None:
            r += [num(truth[j]), "yes" if lo[j] <= truth[j] <= hi[j] else "**NO**"]
        rows.append(r)
    qtable = (Table(["question", "probability", "MC standard error", QUESTION_UNITS_HEAD],
                    [[f"`{q}`", num(p) or "-", num(se) or "-", units]
                     for (q, p, se), units in zip(questions, question_units(post), strict=True)], "questions",
                    text_cols=(0, 3), caption=question_note(post), md_cols=(0,))
              if questions else None)
    ctable = None
    if counterfactuals:
        names = post.study.scene.vehicle_names
        ctable = Table(["counterfactual", "draws", "failed", "avoided", "90 % interval"]
                       + [f"{n} impact speed, median [{unit_in('km/h', system)}]" for n in names]
                       + [f"miss distance, median (5-95 %) [{unit_in('m', system)}]", "time gap, median (5-95 %) [s]"],
                       [[r["name"], str(r["draws"]), str(r["failed"]), num(r["p_avoided"]),
                         f"{num(r['p_avoided_5'])}-{num(r['p_avoided_95'])}"]
                        + [num(value_in(r[f"{n}.impact_speed_50"], "km/h", system), 1) for n in names]
                        + [_median_range(r, "miss_distance", 2, value_in(1.0, "m", system)),
                           _median_range(r, "time_gap", 2)]
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
            f"`{study.spec.model}`: " + ", ".join(f"{v.label} = {x:.3f} {unit_in(v.unit, system)}".rstrip(" -")
                                                  for v, x in zip(post.variables, shown_row(post, res.samples[k],
                                                                                            system))) + ".",
            outcome, out_dir, list(median_figures), system)
    tops = (figure_of(out_dir / "posterior_top_view.png", "rest outlines and CG paths of posterior draws over the "
                      "measured rest poses (thick).") if s.draws_plotted else None)
    return write_report_page("posterior.html", out_dir, f"Posterior: {study.spec.name or post.path.name}",
                 case=case_context(study.spec),
                 study={"path": post.path, "model": study.spec.model,
                        "model_options": _options(study.spec.model_options), "run": run},
                 scene=scene_context(study), evidence=evidence_context(study),
                 posterior=Table(head, rows, "posterior", (0, 1, 2), md_cols=(len(head) - 1,)),
                 warnings=list(warnings), questions=qtable, counterfactuals=ctable,
                 counterfactual_figures=[figure_of(out_dir / f, c) for f, c in counterfactual_figures],
                 corner=corner, solution=solution, tops=tops,
                 animation=animation_context(best, out_dir, "the posterior draw of largest log-likelihood",
                                             system),
                 refine=refine_context(out_dir, getattr(res, "refine", None), study.evidence, system),
                 notes=list(notes))


def _median_range(row, what, digits, scale: float = 1.0) -> str:
    """"median (5 % to 95 %)" of counterfactual row's `what` (times scale: a unit shown); empty when not
    measured."""
    m = row.get(f"{what}_50", math.nan)
    if not math.isfinite(m):
        return ""
    return (f"{num(m * scale, digits)} ({num(row[f'{what}_5'] * scale, digits)} to "
            f"{num(row[f'{what}_95'] * scale, digits)})")
