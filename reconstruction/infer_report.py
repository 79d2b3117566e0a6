"""The outputs of `crashlab infer` (crashlab.reconstruction.infer): posterior.csv, summary.md, corner.png,
posterior_top_view.png (the rest outlines and CG paths of posterior draws over the measured rest poses), the
median draw's top view, time histories and time-distance diagram (median_draw.png, median_draw_time.png,
time_distance.png and .csv), with [[counterfactuals]] counterfactuals.csv and its figures
(crashlab.reconstruction.avoidance), and report.html (crashlab.reconstruction.html_report)."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from crashlab.errors import InputError
from crashlab.units import frame_in, length_axes_in, uncertain_text, unit_in, value_in

from .questions import answers, smallest

# emcee's rule: tau is reliable from a chain of 50 tau; a burn-in of a few tau forgets the start
TAU_RELIABLE = 50
BURN_TAUS = 5


def number(value, digits: int) -> str:
    """A number of summary.md and the terminal with `digits` decimals; a dash where it could not be computed (NaN:
    tau and the ESS of a chain too short for an autocorrelation estimate, chain_warnings says why)."""
    value = float(value)
    return "-" if math.isnan(value) else f"{value:.{digits}f}"


def variable_units(post) -> dict:
    """The units map (crashlab.units, shown units) of posterior.csv: each variable's file unit by its label."""
    return {v.label: v.unit for v in post.variables}


def write_posterior_csv(post, res, path: Path) -> None:
    """posterior.csv: a row per kept sample, a column per variable, log_likelihood; in the study's shown units
    (US: "V1.speed [mph]", read back by `crashlab avoid`). Every number in full (pandas' shortest repr that reads
    back to the same float): `crashlab avoid` answers on these draws what infer answered on its own."""
    import pandas as pd
    df = pd.DataFrame(res.samples, columns=res.labels)
    df["log_likelihood"] = res.log_likelihood
    frame_in(df, post.study.shown_units, variable_units(post)).to_csv(path, index=False)


def shown_row(post, values, system: str) -> np.ndarray:
    """One value per variable (file units) in `system`'s units."""
    return np.array([value_in(x, v.unit, system) for x, v in zip(values, post.variables)])


def prior_text(v, system: str) -> str:
    """A variable's prior (posterior.Variable.describe_prior) with its numbers in `system`'s units."""
    if system != "us":
        return v.describe_prior()
    lo, hi = value_in(v.lower, v.unit, system), value_in(v.upper, v.unit, system)
    if v.prior is None:
        return f"flat on [{lo:g}, {hi:g}]"
    return uncertain_text(v.prior, system).split(": ", 1)[1] + (f", within [{lo:g}, {hi:g}]" if v.free else "")


def summary_lines(post, res) -> list[str]:
    """summary.md's lines, in the study's shown units (crashlab.units)."""
    system = post.study.shown_units
    lo, med, hi = (shown_row(post, q, system) for q in res.interval())
    truth = None if res.truth is None else shown_row(post, res.truth, system)
    lines = [f"# Posterior: {post.study.spec.name or post.path.name}", "",
             f"Study `{post.path.name}`, model `{post.study.spec.model}`, sampler {res.sampler} "
             f"({res.walkers} walkers, {res.iterations} iterations of which {res.burn} burn-in discarded, "
             f"thinned by {res.thin}): {len(res.samples)} samples from {res.evaluations} model evaluations in "
             f"{res.wall_time_s:.1f} s; mean acceptance {res.acceptance:.2f}.", "",
             "## Variables (median and 90 % interval)", ""]
    head = "| variable | unit | prior | median | 5 % | 95 % | tau [it] | ESS |"
    sep = "|---|---|---|---|---|---|---|---|"
    if truth is not None:
        head += " truth (twin) | inside |"
        sep += "---|---|"
    lines += [head, sep]
    for j, v in enumerate(post.variables):
        row = (f"| {v.label} | {unit_in(v.unit, system)} | {prior_text(v, system)} | {med[j]:.3f} | {lo[j]:.3f} | "
               f"{hi[j]:.3f} | "
               f"{number(res.tau[j], 1)} | {number(res.ess[j], 0)} |")
        if truth is not None:
            row += f" {truth[j]:.3f} | {'yes' if lo[j] <= truth[j] <= hi[j] else 'NO'} |"
        lines.append(row)
    lines += ["", f"Effective sample size: walkers x kept iterations / tau, tau the integrated autocorrelation "
              f"time (emcee.autocorr.integrated_time); smallest ESS {number(smallest_ess(res), 0)}."]
    lines += chain_warnings(res)
    if post.questions:
        lines += ["", "## Questions", "", f"| question | probability | MC standard error | {QUESTION_UNITS_HEAD} |",
                  "|---|---|---|---|"]
        lines += [f"| `{q}` | {number(p, 3)} | {number(se, 3)} | {units} |"
                  for (q, p, se), units in zip(question_rows(post, res), question_units(post), strict=True)]
        lines += ["", question_note(post)]
    if res.counterfactuals:
        from .counterfactual import summary_lines as counterfactual_lines
        lines += ["", "## Counterfactuals", "", "Each kept draw (at most 2,000, a random subsample) simulated again "
                  "with the change (docs/physics.md §29; every number in counterfactuals.csv):", ""]
        lines += [f"- {line}" for line in counterfactual_lines(res.counterfactuals, system)]
    lines += ["", "## Evidence", ""]
    lines += [f"- {s}" for s in post.study.evidence_set.describe(system)]
    lines += ["", "Likelihood: Gaussian in the normalised residuals (crashlab.reconstruction.evidence); priors "
              "as in the table; a start that overlaps, misses or fails has probability 0 "
              "(crashlab.reconstruction.infer).", "",
              "Files: posterior.csv (a row per sample, a column per variable "
              + ("in SI units (km/h, m, deg as in the table)" if system != "us" else
                 "in US units, each named with its unit")
              + ", log_likelihood), "
              "corner.png" + (", posterior_top_view.png" if post.settings.draws_plotted else "")
              + "; all of it with the figures embedded: report.html."]
    return lines


def smallest_ess(res) -> float:
    """The smallest ESS of the variables; NaN when one of them has none (infer._autocorr)."""
    return smallest(res.ess)


def chain_warnings(res) -> list[str]:
    """Warnings (markdown) when the chain is short against its autocorrelation time (emcee), or too short to
    estimate it at all (one line: tau and the ESS are then shown as a dash)."""
    out = []
    kept_iters = res.iterations - res.burn
    if np.isnan(res.tau).any():
        why = "fewer than 2" if kept_iters < 2 else "a walker did not move in them"
        out.append(f"**Warning**: {kept_iters} kept iterations are too few samples for an autocorrelation estimate "
                   f"({why}): tau and the ESS of {', '.join(np.asarray(res.labels)[np.isnan(res.tau)])} cannot be "
                   "computed (shown as -); raise --samples.")
    if not np.isfinite(res.tau).any():
        return out  # nothing to compare the chain with
    tmax = float(np.nanmax(res.tau))
    if res.sampler == "emcee" and not kept_iters >= TAU_RELIABLE * tmax:
        out.append(f"**Warning**: {kept_iters} kept iterations are fewer than {TAU_RELIABLE} tau "
                   f"({TAU_RELIABLE * tmax:.0f}): tau and the ESS are rough; raise --samples.")
    if res.sampler == "emcee" and not res.burn >= BURN_TAUS * tmax:
        out.append(f"**Warning**: the burn-in ({res.burn} iterations) is shorter than {BURN_TAUS} tau "
                   f"({BURN_TAUS * tmax:.0f}): raise [infer] burn.")
    return out


def question_rows(post, res) -> list[tuple[str, float, float]]:
    """(the question's name (its expression where it has none) with the note of draws where it is undefined,
    probability over the defined draws, Monte Carlo standard error from the smallest ESS of its variables). A
    question's numbers are in the study file's units: a study written in US units asks of draws in US units."""
    samples = np.array([shown_row(post, row, post.study.spec.units) for row in res.samples]) \
        if post.study.spec.units == "us" else res.samples
    return [(a.name + (f" ({a.note})" if a.note else ""), a.probability, a.standard_error)
            for a in answers(post.questions, res.labels, samples, res.ess)]


QUESTION_UNITS_HEAD = "its variables' units (the study file's)"


def question_units(post) -> list[str]:
    """Per question (post.questions' order): the variables it reads, each with its unit in the study file's
    units ("V1.speed in km/h", "road.friction (no unit)"): the units its numbers are in (question_rows), whatever
    --units shows."""
    system = post.study.spec.units
    units = {v.label: unit_in(v.unit, system) for v in post.variables}
    return [", ".join(f"{n} in {units[n]}" if units.get(n) not in (None, "", "-") else f"{n} (no unit)"
                      for n in q.names) or "-" for q in post.questions]


def question_note(post) -> str:
    """The note under the questions' table (summary.md, report.html): a question's numbers are in the study
    file's units, as written, not in the shown units (--units) of the tables around it."""
    system = post.study.spec.units
    used = dict.fromkeys(unit_in(v.unit, system) for v in post.variables
                         if any(v.label in q.names for q in post.questions) and v.unit not in ("", "-"))
    return (f"A question is answered as written, its numbers in the study file's units (units = \"{system}\""
            + (f": {', '.join(used)}" if used else "") + ") whatever --units shows; the last column gives each "
            "variable it reads with that unit.")


def best_draw(post, res):
    """(scene, outcome) of the sample of largest log-likelihood, or None (no finite one, or its run fails)."""
    from crashlab.execution import model_for
    ok = np.isfinite(res.log_likelihood)
    if not ok.any():
        return None
    k = int(np.flatnonzero(ok)[np.argmax(res.log_likelihood[ok])])
    scene = post.setter(res.samples[k])
    outcome = model_for(post.study.spec.model, post.study.spec.model_options).simulate(scene)
    return (scene, outcome) if outcome.outcome_ok else None


def median_draw_index(res) -> int | None:
    """The posterior draw nearest the median of every variable, the distance measured in units of each
    variable's 90 % interval (a draw, so a start the posterior holds; a component-wise median of a two-mode
    posterior may lie between the modes). None without samples."""
    if not len(res.samples):
        return None
    lo, med, hi = res.interval()
    width = np.where(hi - lo > 0, hi - lo, 1.0)
    ok = np.isfinite(res.log_likelihood)
    d = np.sum(((res.samples - med) / width) ** 2, axis=1)
    d = np.where(ok, d, np.inf) if ok.any() else d
    return int(np.argmin(d))


def median_draw(post, res, out: Path):
    """(scene, outcome, draw index) of the median draw (median_draw_index) simulated again with the study's
    model, and the figures drawn of it [(file name, caption)]; (None, notes) when it cannot be run."""
    from crashlab.execution import model_for
    from crashlab.tools.plotting import time_histories, top_view
    k = median_draw_index(res)
    if k is None:
        return None, [], []
    scene = post.setter(res.samples[k])
    outcome = model_for(post.study.spec.model, post.study.spec.model_options).simulate(scene)
    figures, notes = [], []
    system = post.study.shown_units  # the figures' axes in the shown units (crashlab.units)
    import matplotlib.pyplot as plt
    for name, draw, caption in (
            ("median_draw_time.png", lambda p: time_histories(scene, outcome, p, title="Median draw: speed, "
                                                              "distance travelled and heading against time",
                                                              system=system),
             "speed, distance travelled along the CG path and heading (continuous) against time; dashed: the "
             "impacts."),
            ("median_draw.png", lambda p: top_view(scene, outcome, p, title="Median draw",
                                                   measured=post.study.evidence, system=system),
             "start dotted, first contact dashed, rest solid, measured rest pose thick and pale.")):
        try:
            draw(out / name)
            figures.append((name, caption))
        except Exception as err:  # noqa: BLE001 - the tables stand without the figure
            notes.append(f"{name} could not be drawn ({type(err).__name__} in the plotting library).")
        finally:
            plt.close("all")
    return (scene, outcome, k), figures, notes


def corner_plot(res, path: Path, units=None, system: str = "si") -> None:
    """The corner plot of the samples, axes labelled with their units (US units with system "us")."""
    import matplotlib
    matplotlib.use("Agg")
    import corner
    import matplotlib.pyplot as plt
    units = units or [""] * len(res.labels)
    samples = np.column_stack([value_in(res.samples[:, j], u, system) for j, u in enumerate(units)]) \
        if len(res.samples) else res.samples
    truths = None if res.truth is None else [value_in(t, u, system) for t, u in zip(res.truth, units)]
    # corner refuses a variable with no spread (e.g. every draw at one bound): give it a hair of one
    span = np.ptp(samples, axis=0)
    if np.any(span == 0):
        samples = samples + np.where(span == 0, 1e-9, 0.0) * np.arange(len(samples))[:, None] / len(samples)
    labels = [f"{lab} [{unit_in(u, system)}]" if u else lab for lab, u in zip(res.labels, units)]
    fig = corner.corner(samples, labels=labels, titles=list(res.labels),  # axes with units, short titles
                        truths=truths,
                        quantiles=[0.05, 0.5, 0.95], show_titles=True, title_fmt=".2f",
                        quiet=True)  # few samples: points, no contours, without corner's log line
    fig.savefig(path, dpi=80)
    plt.close(fig)


def top_view_draws(post, res, path: Path, n: int, seed: int = 0) -> int:
    """Rest outlines and CG paths of n posterior draws (one colour per vehicle), measured rest poses thick;
    returns the number of draws drawn (a draw whose run fails is left out)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from crashlab.execution import model_for
    from crashlab.scene import vehicle_outline
    from crashlab.tools.plotting import draw_barriers, draw_road, scale_bar

    rng = np.random.default_rng(seed)
    pick = rng.choice(len(res.samples), size=min(n, len(res.samples)), replace=False) if len(res.samples) else []
    model = model_for(post.study.spec.model, post.study.spec.model_options)
    fig, ax = plt.subplots(figsize=(8, 6))
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    draw_road(ax, post.study.scene.road)
    draw_barriers(ax, post.study.scene.barriers)
    drawn = 0
    for k in pick:
        try:
            scene = post.setter(res.samples[k])
            o = model.simulate(scene)
        except Exception:  # noqa: BLE001 - a draw that cannot be run is left out of the figure
            continue
        if not o.outcome_ok:
            continue
        drawn += 1
        for i, v in enumerate(scene.vehicles):
            c = colours[i % len(colours)]
            x, y, h = o.rest_si[i]
            poly = np.vstack([vehicle_outline(v, x, y, h)] * 1)
            poly = np.vstack([poly, poly[:1]])
            ax.plot(poly[:, 0], poly[:, 1], color=c, lw=0.8, alpha=0.35)
            tr = (o.trajectories or {}).get(v.name)
            if tr and len(tr.get("x", ())):
                ax.plot(tr["x"], tr["y"], color=c, lw=0.5, alpha=0.3)
    for i, v in enumerate(post.study.scene.vehicles):
        c = colours[i % len(colours)]
        ev = post.study.evidence.get(v.name)
        if ev is None:
            continue
        x, y, h = ev
        if h is None:
            ax.plot([x], [y], "x", color=c, ms=12, mew=3)
        else:
            poly = vehicle_outline(v, x, y, math.radians(h))
            poly = np.vstack([poly, poly[:1]])
            ax.plot(poly[:, 0], poly[:, 1], color=c, lw=3.5, alpha=0.5, label=f"{v.name} measured rest")
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    length_axes_in(ax, post.study.shown_units)
    ax.set_title(f"{drawn} posterior draws: rest outlines and CG paths")
    scale_bar(ax, post.study.shown_units)
    ax.legend(loc="best", fontsize=8)
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return drawn


def write_outputs(post, res, out: Path) -> dict:
    """posterior.csv, summary.md, corner.png, posterior_top_view.png; returns the keyword arguments of
    html_report.write_posterior_report (warnings, the draw of largest log-likelihood to animate, notes,
    question rows), which the caller writes once every file it shows exists."""
    out = Path(out)
    try:
        write_posterior_csv(post, res, out / "posterior.csv")
        if res.counterfactuals:
            from .counterfactual import write_csv
            write_csv(res.counterfactuals, out / "counterfactuals.csv", post.study.shown_units)
        (out / "summary.md").write_text("\n".join(summary_lines(post, res)) + "\n")
        corner_plot(res, out / "corner.png", [v.unit for v in post.variables], post.study.shown_units)
        if post.settings.draws_plotted:
            top_view_draws(post, res, out / "posterior_top_view.png", post.settings.draws_plotted)
        notes = []
        try:
            best = best_draw(post, res)
        except Exception as err:  # noqa: BLE001 - the report stands without its animation
            best = None
            notes.append(f"the draw of largest log-likelihood could not be run again ({type(err).__name__}).")
        try:
            median, median_figures, more = median_draw(post, res, out)
            notes += more
        except Exception as err:  # noqa: BLE001 - the report stands without the median draw's section
            median, median_figures = None, []
            notes.append(f"the median draw could not be run again ({type(err).__name__}).")
        if median is not None:  # the avoidance diagram of the median draw (docs/physics.md §29)
            from .avoidance import TIME_DISTANCE_CAPTION, write_time_distance
            name, more = write_time_distance(median[1], out, "Median draw: distance to the point of impact and "
                                             "speed against time", post.study.shown_units)
            notes += more
            if name:
                median_figures = list(median_figures) + [(name, TIME_DISTANCE_CAPTION)]
        counterfactual_figures = []
        if res.answers:
            from .avoidance import write_counterfactual_figures
            counterfactual_figures, more = write_counterfactual_figures(res.answers, post.study.scene.vehicle_names,
                                                                        out, post.study.shown_units)
            notes += more
        # a model's warnings of the median draw's run (e.g. restitution = "speed" outside its data, docs/physics.md
        # §13b): the batch evaluations keep none, so the draw run again says them, here, in report.html and on the CLI
        res.model_warnings = [str(w) for w in (getattr(median[1], "warnings", ()) or ())] if median is not None else []
        if res.model_warnings:
            with open(out / "summary.md", "a") as fh:
                fh.write("\n".join(["", "## Warnings of the median draw's run", ""]
                                   + [f"- {w}" for w in res.model_warnings]) + "\n")
        return dict(warnings=chain_warnings(res) + [f"**Warning** (the median draw's run): {w}"
                                                    for w in res.model_warnings],
                    best=best, notes=notes, median=median,
                    median_figures=median_figures, questions=question_rows(post, res) if post.questions else [],
                    counterfactuals=res.counterfactuals or [], counterfactual_figures=counterfactual_figures)
    except OSError as err:
        raise InputError(out, "--out", err.strerror or str(err)) from None
