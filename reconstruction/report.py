"""What a reconstruction reports: the Pareto table, failures.csv, objectives.png, top views of chosen
solutions, summary.md, report.html (crashlab.reconstruction.html_report), and the result object with its
JSON form.

The tables come first; a figure that cannot be drawn is named in summary.md instead of ending the run.
"""
from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pandas as pd

from crashlab.population import Population
from crashlab.units import frame_in, json_number, ms_to_kmh, rad_to_deg, unit_in, value_in, wrap_deg

from .evidence import log_likelihood_of
from .problem import evaluation_counts, infeasible_sentence, objective_unit
from .search_figures import near_optimal_figure, objectives_figure

DUPLICATE_TOL = 1e-6  # Pareto rows whose every free variable lies this close (share of its bound width) are one
HEADING_WARN_DEG = 15.0  # deg: a rest heading this far off is plain on any site sketch or photo
SUMMARY_ROWS = 15  # Pareto rows in summary.md (every row: pareto.csv, report.html)


class ReconstructionResult:
    """What Study.run returns: the Pareto table, counts, wall time, the problem (its archive holds every
    evaluation) and facts about the search (algorithm_info)."""

    def __init__(self, pareto, evaluations, failed, feasible_fraction, wall_time_s, problem, algorithm_info):
        self.pareto, self.evaluations, self.failed = pareto, evaluations, failed
        self.feasible_fraction, self.wall_time_s = feasible_fraction, wall_time_s
        self.problem, self.algorithm_info = problem, algorithm_info

    def to_json_dict(self) -> dict:
        """The result as JSON, with its "units" map (pareto_units and the rest poses' keys: crashlab.units.json_in
        shows it in US units)."""
        p = self.problem
        items = []
        for _, row in self.pareto.iterrows():
            items.append({"start": {f.label: float(row[f.label]) for f in p.free},
                          "objectives": {f"f_{n}": float(row[f"f_{n}"]) for n in p.objective_names},
                          "rest": {n: {**{k: float(row[f"rest_{n}_{k}"]) for k in ("x", "y", "heading")},
                                       "dheading": json_number(row[f"dheading_{n}"], None)} for n in p.names},
                          **({} if p.evidence_set is None else {
                              "misfit": {c: float(row[c]) for c in misfit_columns(p)},
                              "log_likelihood": float(row["log_likelihood"])})})
        arch = p.archive_arrays()
        reasons = failure_counts(arch["reason"][~arch["ok"]]) if len(arch["X"]) else {}
        return {"pareto": items, "evaluations": self.evaluations, "failed": self.failed,
                "failure_reasons": reasons, "feasible_fraction": self.feasible_fraction,
                "wall_time_s": round(self.wall_time_s, 3), **self.algorithm_info,
                "units": pareto_units(p) | {"x": "m", "y": "m", "heading": "deg", "dheading": "deg",
                                            "wall_time_s": "s"}}


def pareto_units(problem) -> dict:
    """The units map (crashlab.units, shown units) of pareto.csv, near_optimal.csv and failures.csv: each variable's
    file unit by its label, the objectives' (objective_unit), the rest poses and the state at first contact."""
    from .problem import variable_unit
    return {f.label: variable_unit(f) for f in problem.free} | {
        "f_<vehicle>": objective_unit(problem), "dheading_<vehicle>": "deg", "misfit_<item>": "sigma",
        "rest_<vehicle>_x": "m", "rest_<vehicle>_y": "m", "rest_<vehicle>_heading": "deg",
        "contact_<vehicle>_x": "m", "contact_<vehicle>_y": "m", "contact_<vehicle>_heading": "deg",
        "contact_<vehicle>_speed": "km/h"}


def failure_counts(reasons) -> dict:
    """Failure reasons grouped with their numbers replaced by N, most frequent first."""
    counts: dict[str, int] = {}
    for r in reasons:
        key = re.sub(r"(?<![\w.])[-+]?\d+(\.\d+)?(e[-+]?\d+)?(?![\w.])", "N", str(r))
        counts[key] = counts.get(key, 0) + 1
    return dict(sorted(counts.items(), key=lambda kv: -kv[1]))


def pareto_table(problem, arch: dict):
    """Non-dominated feasible solutions among every evaluated candidate, one row each, best (smallest sum
    of objectives) first: free variables, objectives f_<vehicle>, dheading_<vehicle> (simulated minus
    measured rest heading [deg], wrapped to -180..180; empty where no heading was measured: it is there
    whatever heading_weight, so a good position with a wrong heading shows), rest poses and the state at
    first contact (file units). Rows whose every free variable lies within DUPLICATE_TOL of its bound
    width of a better row's are the same solution and kept once."""
    from pymoo.util.nds.non_dominated_sorting import NonDominatedSorting
    feasible = np.flatnonzero(np.all(arch["G"] <= 0, axis=1) & arch["ok"])
    if len(feasible) == 0:  # the columns still (an empty pareto.csv without its header was no CSV to read)
        return pd.DataFrame(columns=_pareto_columns(problem))
    _, first = np.unique(arch["X"][feasible], axis=0, return_index=True)  # exact repeats (cheap, first)
    idx = feasible[np.sort(first)]
    front = NonDominatedSorting().do(arch["F"][idx], only_non_dominated_front=True)
    idx = idx[front]
    idx = idx[np.argsort(arch["F"][idx].sum(axis=1), kind="stable")]
    Z = (arch["X"][idx] - problem.xl) / (problem.xu - problem.xl)
    keep: list[int] = []
    for k in range(len(idx)):
        if not keep or np.min(np.max(np.abs(Z[keep] - Z[k]), axis=1)) > DUPLICATE_TOL:
            keep.append(k)
    idx = idx[keep]
    rows = []
    for k in idx:
        row = {f.label: arch["X"][k, c] for c, f in enumerate(problem.free)}
        row.update({f"f_{n}": arch["F"][k, c] for c, n in enumerate(problem.objective_names)})
        if problem.evidence_set is not None:  # every evidence item's normalised misfit, the log-likelihood
            es = problem.evidence_set
            R = arch["R"][k][None]
            row.update(dict(zip(misfit_columns(problem), es.item_misfits(R)[0])))
            row["log_likelihood"] = float(log_likelihood_of(R)[0])
        for i, n in enumerate(problem.names):
            eh = problem.evidence.get(n, (None, None, None))[2]
            row[f"dheading_{n}"] = math.nan if eh is None else float(wrap_deg(rad_to_deg(arch["rest"][k, i, 2]) - eh))
        for i, n in enumerate(problem.names):
            r, c = arch["rest"][k, i], arch["contact"][k, i]
            row.update({f"rest_{n}_x": r[0], f"rest_{n}_y": r[1], f"rest_{n}_heading": rad_to_deg(r[2])})
            row.update({f"contact_{n}_x": c[0], f"contact_{n}_y": c[1], f"contact_{n}_heading": rad_to_deg(c[2]),
                        f"contact_{n}_speed": ms_to_kmh(c[3])})
        rows.append(row)
    return pd.DataFrame(rows)


def _pareto_columns(problem) -> list[str]:
    """pareto_table's columns, in its order: the header of a table without rows (its rows name their own)."""
    cols = [f.label for f in problem.free] + [f"f_{n}" for n in problem.objective_names]
    if problem.evidence_set is not None:
        cols += misfit_columns(problem) + ["log_likelihood"]
    cols += [f"dheading_{n}" for n in problem.names]
    for n in problem.names:
        cols += [f"rest_{n}_x", f"rest_{n}_y", f"rest_{n}_heading",
                 f"contact_{n}_x", f"contact_{n}_y", f"contact_{n}_heading", f"contact_{n}_speed"]
    return cols


def misfit_columns(problem) -> list[str]:
    """The Pareto table's columns misfit_<item> (crashlab.reconstruction.evidence: sqrt(sum (r / sigma)^2)
    of that item's residual components) of a problem with the misfit objective."""
    return [f"misfit_{it.label}" for it in problem.evidence_set.items] if problem.evidence_set is not None else []


def write_failures(problem, arch: dict, path: Path, n_search: int, system: str = "si"):
    """failures.csv: one row per failed evaluation: its index, phase (search/polish), free variables
    (file units, or US units with system "us") and the reason. Written (with its header) also when nothing
    failed."""
    bad = np.flatnonzero(~arch["ok"]) if len(arch["X"]) else np.empty(0, int)
    table = pd.DataFrame({"evaluation": bad, "phase": np.where(bad < n_search, "search", "polish")})
    for c, f in enumerate(problem.free):
        table[f.label] = arch["X"][bad, c] if len(bad) else []
    table["reason"] = arch["reason"][bad] if len(bad) else []
    frame_in(table, system, pareto_units(problem)).to_csv(path, index=False)


def near_optimal_table(problem, arch: dict, tol: float) -> pd.DataFrame:
    """The evaluated starts (ok and feasible) whose every objective is at most `tol` [m], free variables and
    objectives, sorted by the largest objective."""
    cols = [f.label for f in problem.free]
    names = list(problem.objective_names)
    if not len(arch["X"]):
        return pd.DataFrame(columns=cols + [f"f_{n}" for n in names])
    good = arch["ok"] & np.all(arch["G"] <= 0, axis=1) & np.all(arch["F"] <= tol, axis=1)
    table = pd.DataFrame(arch["X"][good], columns=cols)
    for j, n in enumerate(names):
        table[f"f_{n}"] = arch["F"][good, j]
    return table.iloc[np.argsort(arch["F"][good].max(axis=1), kind="stable")].reset_index(drop=True)


def drawing_failed(name: str, err: Exception) -> str:
    """A note for a figure that could not be drawn: what and the kind of error, not the library's message."""
    return (f"{name} could not be drawn ({type(err).__name__} in the plotting library); the tables and CSV "
            "files hold the same numbers.")


def write_outputs(study, result: ReconstructionResult, arch: dict, out_dir: Path):
    """pareto.csv, failures.csv, objectives.png, top views of chosen solutions, summary.md; returns the
    arguments of html_report.write_reconstruction_report (the page is written by the caller once every file
    it shows exists). The tables come first; a figure that cannot be drawn is named in summary.md instead
    of ending the run."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from crashlab.execution import model_for
    from crashlab.tools.plotting import time_histories, top_view
    problem = result.problem
    info = result.algorithm_info
    system = study.shown_units  # the units every table, CSV file and figure here shows (crashlab.units)
    units = pareto_units(problem)
    frame_in(result.pareto, system, units).to_csv(out_dir / "pareto.csv", index=False)
    write_failures(problem, arch, out_dir / "failures.csv", info["search_evaluations"], system)
    names = list(problem.objective_names)
    notes = []
    if len(names) >= 2:
        try:
            why = objectives_figure(problem, arch, result.pareto, out_dir / "objectives.png", plt, system)
            if why:
                notes.append(f"objectives.png not drawn: {why}")
        except Exception as err:  # noqa: BLE001 - the search's result is in the tables already
            notes.append(drawing_failed("objectives.png", err))
        finally:
            plt.close("all")
    tol = study.spec.objective.near_optimal_tol(study.mode)
    near = near_optimal_table(problem, arch, tol)
    frame_in(near, system, units).to_csv(out_dir / "near_optimal.csv", index=False)
    if len(near) and len(problem.free) >= 2:
        try:
            figures_near = near_optimal_figure(problem, near, out_dir / "near_optimal.png", plt, system)
        except Exception as err:  # noqa: BLE001
            figures_near = None
            notes.append(drawing_failed("near_optimal.png", err))
        finally:
            plt.close("all")
    else:
        figures_near = None
    model = model_for(problem.model, problem.model_options)
    chosen = []
    if len(result.pareto):
        cols = [f.label for f in problem.free]
        for k in sorted({0, *[int(result.pareto[f"f_{n}"].idxmin()) for n in names]}):
            chosen.append((k, result.pareto.loc[k, cols].to_numpy(dtype=float)))
    figures = []
    run_warnings: list[str] = []
    best = None  # (scene, outcome) of Pareto row 0: its impact table, time histories and animation in report.html
    time_figure = time_distance_figure = None
    for k, x in chosen[:3]:
        scene = problem.scene_for(x)
        try:
            outcome = model.simulate(scene)
        except Exception as err:  # noqa: BLE001 - a model that raises on the chosen start: named, not fatal
            notes.append(f"Pareto row {k} could not be simulated again ({type(err).__name__}).")
            continue
        if k == 0:
            best = (scene, outcome)
            run_warnings = [str(w) for w in getattr(outcome, "warnings", ()) or ()]  # e.g. a law outside its data
            try:
                time_histories(scene, outcome, out_dir / "solution_0_time.png",
                               title="Pareto row 0: speed, distance travelled and heading against time",
                               system=system)
                time_figure = "solution_0_time.png"
            except Exception as err:  # noqa: BLE001
                notes.append(drawing_failed("solution_0_time.png", err))
            finally:
                plt.close("all")
            from .avoidance import write_time_distance  # the avoidance diagram (docs/physics.md §29)
            time_distance_figure, more = write_time_distance(outcome, out_dir, "Pareto row 0: distance to the "
                                                             "point of impact and speed against time", system)
            notes += more
        try:
            top_view(scene, outcome, out_dir / f"solution_{k}.png",
                     title=f"Pareto solution {k}", measured=problem.evidence, system=system)
            figures.append(f"solution_{k}.png")
        except Exception as err:  # noqa: BLE001
            notes.append(drawing_failed(f"solution_{k}.png", err))
        finally:
            plt.close("all")
    hw = problem.heading_weight
    lines = [f"# Reconstruction: {study.spec.name or study.path.stem}", "",
             f"- study: `{study.path}`; model `{problem.model}`; optimizer `{info['optimizer']}`",
             f"- evaluations {result.evaluations} (search {info['search_evaluations']}, least-squares polish "
             f"{info['polish_evaluations']} of a budget of {info['polish_budget']}), failed {result.failed}, "
             f"feasible fraction {result.feasible_fraction:.1%}, wall time {result.wall_time_s:.1f} s"]
    lines.append("- " + infeasible_sentence(evaluation_counts(problem, arch)))
    if result.failed:
        counts = failure_counts(arch["reason"][~arch["ok"]])
        lines.append("- failed evaluations by reason (every one in failures.csv): " + "; ".join(
            f"{c} x {r}" for r, c in list(counts.items())[:5]) + ("; ..." if len(counts) > 5 else ""))
    for key in ("sigma_share", "repaired"):
        if key in info:
            lines.append(f"- {key}: {info[key]}")
    length = unit_in("m", system)
    if problem.evidence_set is None:
        lines += ["", f"Evidence (measured rest poses, {length}): " + "; ".join(
            f"{n} ({value_in(x, 'm', system):.2f}, {value_in(y, 'm', system):.2f}"
            + (f", {h:.1f} deg)" if h is not None else ", heading not measured)")
            for n, (x, y, h) in problem.evidence.items()), "",
            f"Objectives (thesis): f_<vehicle> = |r - r*| + heading_weight |dpsi| [{length}].", ""]
    else:
        lines += ["", "Evidence, each with its standard deviation:", ""]
        lines += [f"- {line}" for line in problem.evidence_set.describe(system)]
        lines += ["", "Objectives (normalised misfit): f_<vehicle> = sqrt(sum (residual / sigma)^2) over the items "
                  "that concern the vehicle (the point of impact: every vehicle); log_likelihood = -0.5 sum "
                  "(residual / sigma)^2 over all items, each once (crashlab.reconstruction.evidence).", ""]
    if study.spec.evidence.twin:
        lines += ["Twin experiment: the evidence is the model's own run of the base scene, whose start is the "
                  "truth: " + ", ".join(f"{f.label} = {value_in(v, units[f.label], system):.3f}"
                                        + (f" {unit_in(units[f.label], system)}" if system == "us" else "")
                                        for f, v in zip(problem.free, problem.base_values()))
                  + ("" if study.spec.evidence.noise_seed is None else
                     f"; Gaussian noise with the given sigmas added (noise_seed {study.spec.evidence.noise_seed})"),
                  ""]
    measured_h = [n for n, ev in problem.evidence.items() if ev[2] is not None]
    lines += [f"## Pareto set ({len(result.pareto)} solutions, sorted by the sum of objectives)", ""]
    if measured_h:
        lines += ["dheading_<vehicle>: simulated minus measured rest heading [deg], wrapped to -180..180; " +
                  ("in the objectives divided by sigma_heading." if problem.evidence_set is not None else
                   f"weighted {value_in(hw, 'm/deg', system):g} {unit_in('m/deg', system)} in the objectives."
                   if hw else
                   "**not part of the objectives** (heading_weight = 0): a small f_ does not mean the "
                   "headings match."), ""]
    warnings = [f"**Warning (Pareto row 0's run): {w}**" for w in run_warnings]
    if best is not None and problem.evidence_set is not None:
        warnings += [f"**Warning: {w}**" for w in unscored_damage(problem.evidence_set, best[1])]
    for w in warnings:
        lines += [w, ""]
    if len(result.pareto):
        first = result.pareto.iloc[0]
        off = [f"{n} {first[f'dheading_{n}']:+.0f} deg" for n in measured_h
               if abs(first[f"dheading_{n}"]) > HEADING_WARN_DEG]
        if off:
            warnings.append(f"**Warning: the first solution's rest headings are off the measured ones: "
                            f"{', '.join(off)}.**")
            lines += [warnings[-1], ""]
        show = frame_in(result.pareto[[f.label for f in problem.free] + [f"f_{n}" for n in names] +
                                      [f"dheading_{n}" for n in measured_h]].head(SUMMARY_ROWS), system, units)
        lines.append(show.to_markdown(index=False, floatfmt=".3f"))
        if len(result.pareto) > SUMMARY_ROWS:  # (it cut the table silently until 2026-11-28)
            lines += ["", f"(rows 0-{SUMMARY_ROWS - 1} of {len(result.pareto)}; every row in pareto.csv and "
                      "report.html)"]
        if problem.evidence_set is not None:
            mcols = misfit_columns(problem)
            lines += ["", f"### Misfit of every evidence item, every Pareto row ({len(result.pareto)})", "",
                      "misfit_<item> = sqrt(sum (residual / sigma)^2) of the item's components: about 1 is a "
                      "one-sigma match per component; the same columns are in pareto.csv.", "",
                      result.pareto[mcols + ["log_likelihood"]].set_axis(
                          [f"row {k}" for k in range(len(result.pareto))]).rename_axis("Pareto")
                      .to_markdown(floatfmt=".3f")]
    else:
        lines.append("No feasible solution.")
    unit = f" {length}" if problem.evidence_set is None else " (normalised misfit, sigmas)"
    shown_tol = value_in(tol, objective_unit(problem), system)
    lines += ["", f"## Starts that explain the evidence within {shown_tol:g}{unit} ({len(near)} evaluated)", ""]
    if len(near):
        cols = [f.label for f in problem.free]
        shown_near = frame_in(near[cols], system, units)
        lines += [f"Every objective at most {shown_tol:g}{unit} (`[objective] near_optimal`); all in near_optimal.csv"
                  + (", the first two free variables in near_optimal.png" if figures_near else "") +
                  ". The evidence cannot tell these starts apart; their range is only what the search tried, at "
                  "least what the evidence leaves open, not an uncertainty interval (that is the posterior: "
                  "crashlab infer).", "",
                  pd.DataFrame({"variable": list(shown_near.columns), "min": shown_near.min().to_numpy(),
                                "max": shown_near.max().to_numpy()}).to_markdown(index=False, floatfmt=".3f")]
    else:
        lines.append("None: no evaluated start explains every vehicle's rest pose that well.")
    if figures:
        lines += ["", "Top views (start dotted, first contact dashed, rest solid, measured rest pose thick and "
                  "pale, heading arrows in each vehicle's colour): " + ", ".join(figures)]
    if notes:
        lines += [""] + [f"- {n}" for n in notes]
    lines += ["", "All of this, with every figure embedded and an animation of the first solution: report.html."]
    (out_dir / "summary.md").write_text("\n".join(lines) + "\n")
    captions = []
    for f in figures:
        k = int(f[len("solution_"):-len(".png")])
        why = (["the smallest sum of objectives"] if k == 0 else []) + [
            f"the smallest f_{n}" for n in names if int(result.pareto[f"f_{n}"].idxmin()) == k]
        captions.append((f, f"Pareto row {k}: {', '.join(why)}."))
    return dict(figures=captions, near_figure=figures_near, near=near, tol=tol, best=best, warnings=warnings,
                notes=notes, time_figure=time_figure, time_distance_figure=time_distance_figure,
                failure_reasons=failure_counts(arch["reason"][~arch["ok"]]) if result.failed else None)


def unscored_damage(evidence_set, outcome) -> list[str]:
    """Why a run cannot score its damage evidence: one sentence per [evidence.damage.<vehicle>] whose side the run
    did not strike (EvidenceSet.unstruck_damage, docs/physics.md §28), naming the sides it did strike."""
    pop = Population.of_outcomes([outcome], evidence_set.names)
    return [f"{it.label}: Pareto row 0 strikes {it.vehicles[0]} on its {', '.join(struck) or 'nothing'}, not on "
            f"its {it.side}, where the damage was measured: no run like it can be scored (check "
            f"evidence.damage.{it.vehicles[0]}.side and pdof)" for it, struck in evidence_set.unstruck_damage(pop)]
