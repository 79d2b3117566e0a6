"""A second opinion from another model (`[refine]`): the fast model searches, a richer one checks.

After a search (the Pareto rows, best first) or a posterior (its draws), `refine` takes the best candidates,
simulates each again with the refine model (e.g. multibody) and polishes them, best first, with that model:
the least-squares polish of crashlab.reconstruction.polish (the same residuals, repair and forward-difference
step as the search's own polish) until `[refine] evaluations` evaluations of the refine model are spent, the
re-simulations included. The candidates are taken best first and spaced apart (polish.spaced_starts: one per
basin). Every candidate and refined point is also simulated with the search's model, so both models are seen
at both points. The refine model's objective is the polish's: the sum of squares of the residuals (the
thesis's dx, dy [m]; with the misfit objective the normalised residuals, i.e. -2 ln L); the polish keeps a
candidate's start when it finds nothing better, so the refined value is never above the start's.

Outputs (out_dir): refine.csv, a row per candidate:
  candidate, row, status, refine_evaluations      index (0 = best), its row in the table given (the table's
                                                   index: a Pareto row's or a draw's number), what happened, the
                                                   polish's evaluations
  <label>, refined_<label>, moved_<label>          the candidate (file units), the refine model's answer, the move
  moved_norm                                       |move| over the search bounds (normalised decision space)
  search_f_<n>, refine_f_<n>_start, refine_f_<n>, search_f_<n>_refined
                                                   objectives: search model at the candidate, refine model at the
                                                   candidate and at the refined point, search model there
  search_sumsq, refine_sumsq_start, refine_sumsq, search_sumsq_refined   the same as sums of squared residuals
  model_gap_<V>                                    m, rest positions of the two models at the candidate apart
  search_rest_<V>_x|y|heading, refine_rest_<V>_..., refined_rest_<V>_...  rest poses (m, deg)
and refine.md, the two models side by side. A failed or infeasible evaluation has empty objectives. Both files
are in the study's shown units (Study.shown_units, `--units`: crashlab.units, refine_units names each column's
unit; the sums of squares stay in the residuals' own units); the RefineResult's table stays in file units.
"""
from __future__ import annotations

import contextlib
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from crashlab.errors import InputError
from crashlab.units import frame_in, json_in, rad_to_deg, unit_in, unit_of, value_in

from .polish import polish, repaired_residuals, spaced_starts
from .study_executor import open_executor

SUMSQ = ("search_sumsq", "refine_sumsq_start", "refine_sumsq", "search_sumsq_refined")


@dataclass
class RefineResult:
    table: pd.DataFrame  # refine.csv
    search_model: str
    model: str
    budget: int
    evaluations: int  # refine-model evaluations: re-simulations and polish
    search_evaluations: int  # search-model evaluations (every candidate and refined point)
    wall_time_s: float
    source: str
    units: dict = field(default_factory=dict)  # refine_units: the units map of the table (file units)

    def to_json_dict(self, system: str = "si") -> dict:
        """The result as JSON in `system`'s units (crashlab.units.json_in, by the table's units map: each
        candidate's variables, objectives, rest poses and gaps in ft, mph with "us"), its "units" map saying
        them; the sums of squares stay in the residuals' file units."""
        return json_in({"model": self.model, "search_model": self.search_model, "budget": self.budget,
                        "evaluations": self.evaluations, "search_evaluations": self.search_evaluations,
                        "wall_time_s": round(self.wall_time_s, 3), "source": self.source,
                        "candidates": self.table.replace({np.nan: None}).to_dict(orient="records"),
                        "units": self.units | dict.fromkeys(SUMSQ, "squared residuals in file units (not converted)")
                        | {"wall_time_s": "s"}}, system)

    def summary_line(self, variables, wrote: bool, system: str = "si") -> str:
        """One line for the command line: how far the best candidate moved (in `system`'s units, each move
        with its unit) and its fit under this model."""
        if not len(self.table):
            return f"refine with {self.model}: no candidate (no feasible solution)"
        best = self.table.iloc[0]
        from .problem import variable_unit

        def moved(f):
            unit = variable_unit(f)
            shown = unit_in(unit, system)
            return f"{f.label} {value_in(best[f'moved_{f.label}'], unit, system):+.3f}" + (
                f" {shown}" if shown and shown != "-" else "")
        return (f"refine with {self.model}: {self.evaluations} evaluations of {self.budget}, "
                f"{self.wall_time_s:.1f} s; best candidate moved " + ", ".join(moved(f) for f in variables)
                + f"; sum of squared residuals under {self.model} {best['refine_sumsq_start']:.4g} -> "
                f"{best['refine_sumsq']:.4g}" + (" (refine.csv, refine.md)" if wrote else ""))


def _settings(study, model, model_options, evaluations, n_candidates):
    cfg = study.spec.refine
    if model is None and cfg is None:
        raise InputError(study.path, "refine", "no [refine] section: give model = \"multibody\" (and evaluations)")
    if model is None or (cfg is not None and model == cfg.model):
        model, opts = cfg.model, dict(cfg.model_options)
    else:
        opts = {}
    opts = opts if model_options is None else dict(model_options)
    evaluations = evaluations if evaluations is not None else cfg.evaluations if cfg else 200
    n_candidates = n_candidates if n_candidates is not None else cfg.candidates if cfg else 5
    for key, val in (("evaluations", evaluations), ("candidates", n_candidates)):
        if not isinstance(val, (int, np.integer)) or isinstance(val, bool) or val < 1:
            raise InputError(study.path, f"refine.{key}", f"must be an integer >= 1, got {val!r}")
    return model, opts, int(evaluations), int(n_candidates)


def _candidates(study, problem, candidates, n: int) -> tuple[np.ndarray, np.ndarray]:
    """The candidates' variables (file units, a column per label; a label the table lacks takes the base
    scene's value), best first, spaced apart, at most n; and their rows in the table (its index labels: a
    Pareto row's number, a posterior draw's number also after the draws were sorted)."""
    labels = problem.labels
    if not isinstance(candidates, pd.DataFrame):
        candidates = pd.DataFrame(np.atleast_2d(np.asarray(candidates, float)), columns=labels)
    if len(candidates) and not any(c in candidates.columns for c in labels):
        raise InputError(study.path, "refine", f"the candidates name none of the variables ({', '.join(labels)})")
    base = problem.base_values()
    X = np.column_stack([candidates[c].to_numpy(float) if c in candidates.columns else np.full(len(candidates), b)
                         for c, b in zip(labels, base)]) if len(candidates) else np.empty((0, len(labels)))
    keep = np.flatnonzero(np.isfinite(X).all(axis=1))
    X, rows = X[keep], candidates.index.to_numpy()[keep]
    if not len(X):
        return X, rows
    lo, hi = np.minimum(problem.xl, X.min(axis=0)), np.maximum(problem.xu, X.max(axis=0))
    X, picked = spaced_starts(X, lo, hi)
    return X[:n], rows[picked[:n]]


def _evaluate(problem, X) -> dict:
    """Evaluate X (recorded in the problem's archive): its rows (F, G, R, rest, ok, reason), scored."""
    problem.evaluate(X, return_values_of=["constraints"])
    return _scored({k: problem.archive[k][-1] for k in ("F", "G", "R", "rest", "ok", "reason")})


def _scored(ev: dict) -> dict:
    """ev with valid (ok, feasible, finite residuals) and sumsq (the sum of squared residuals; NaN if not
    valid)."""
    valid = ev["ok"] & np.all(ev["G"] <= 0, axis=1) & np.isfinite(ev["R"]).all(axis=1)
    R = np.where(valid[:, None], ev["R"], 0.0)
    return {**ev, "valid": valid, "sumsq": np.where(valid, np.sum(R ** 2, axis=1), np.nan)}


def _why(ev, k) -> str:
    if not ev["ok"][k]:
        return "refine model failed: " + str(ev["reason"][k])
    if ev["G"][k, 1] > 0:
        return "no contact under the refine model"
    return "start overlap" if ev["G"][k, 0] > 0 else "not scored"


def refine(study, candidates, out_dir=None, *, model=None, model_options=None, evaluations=None,
           n_candidates=None, executor=None, source="Pareto rows", progress=False) -> RefineResult:
    """Simulate the best `candidates` (a DataFrame with the study's variable labels as columns, best first:
    the Pareto table, or posterior draws) again with the refine model and polish them with it (module
    docstring); with out_dir, write refine.csv and refine.md. The settings default to the study's [refine].
    Both models run on `executor` (a live crashlab.execution.Executor, e.g. the search's), else on one of the
    study's [execution] opened here."""
    t0 = time.perf_counter()
    model, opts, budget, n_cand = _settings(study, model, model_options, evaluations, n_candidates)
    search, ref = study.make_problem(), study.problem_for(model, opts)
    X, source_rows = _candidates(study, search, candidates, min(n_cand, budget))
    if len(X):  # a posterior draw may lie outside the search bounds (a normal's tail): widen them to it
        ref.xl, ref.xu = np.minimum(ref.xl, X.min(axis=0)), np.maximum(ref.xu, X.max(axis=0))
    n, nv = len(X), ref.n_var
    bar = None
    if progress:
        from tqdm import tqdm
        bar = tqdm(total=budget, unit="eval", desc=f"refine ({model})", dynamic_ncols=True)
    ex = study.spec.execution
    # both models on the executor given (the search's), else on one of the study's [execution]; each model's
    # first call in a worker has the compile grace (crashlab.execution)
    rows = []
    own = contextlib.nullcontext(executor) if executor is not None else \
        open_executor(study.path, ex.backend, ex.workers, ex.scheduler, ex.timeout_s, "execution.scheduler")
    with own as live, \
            search.running_on(live), ref.running_on(live):
        s0 = _evaluate(search, X) if n else None
        r0 = _evaluate(ref, X) if n else None
        used = n
        if bar is not None:
            bar.update(n)
        residual = repaired_residuals(ref, study.make_repair())

        def counted(Z):
            if bar is not None:
                bar.update(len(Z))
            return residual(Z)

        best_X = X.copy()
        r1 = {key: np.array(val, copy=True) for key, val in r0.items()} if n else None  # refine model there
        status, spent = [], np.zeros(n, int)
        for k in range(n):
            if not r0["valid"][k]:
                status.append(_why(r0, k))
                continue
            if used + 1 + nv > budget:
                status.append("not polished (budget spent)")
                continue
            a = sum(len(x) for x in ref.archive["X"])
            res = polish(counted, X[k:k + 1], ref.xl, ref.xu, budget - used, study.spec.polish.step,
                         start_residuals=r0["R"][k:k + 1])
            used += res.evaluations
            spent[k] = res.evaluations
            arch = ref.archive_arrays()
            part = {key: arch[key][a:] for key in ("F", "G", "R", "rest", "ok", "reason")}
            cost = _scored(part)["sumsq"]
            j = int(np.nanargmin(cost)) if np.isfinite(cost).any() else -1
            if j >= 0 and cost[j] < r0["sumsq"][k]:  # the best point the polish evaluated (repaired as run)
                best_X[k] = arch["X"][a + j]
                for key in part:
                    r1[key][k] = part[key][j]
            status.append("polished")
        r1 = _scored(r1) if n else None
        s1 = _evaluate(search, best_X) if n else None
    if bar is not None:
        bar.close()
    span = search.xu - search.xl
    for k in range(n):
        row = {"candidate": k, "row": source_rows[k], "status": status[k], "refine_evaluations": int(spent[k])}
        for c, lab in enumerate(search.labels):
            row[lab], row[f"refined_{lab}"] = X[k, c], best_X[k, c]
            row[f"moved_{lab}"] = best_X[k, c] - X[k, c]
        row["moved_norm"] = float(np.linalg.norm((best_X[k] - X[k]) / span))
        for j, name in enumerate(search.objective_names):
            for key, ev in (("search_f_{}", s0), ("refine_f_{}_start", r0), ("refine_f_{}", r1),
                            ("search_f_{}_refined", s1)):
                row[key.format(name)] = ev["F"][k, j] if ev["valid"][k] else np.nan
        for key, ev in (("search_sumsq", s0), ("refine_sumsq_start", r0), ("refine_sumsq", r1),
                        ("search_sumsq_refined", s1)):
            row[key] = ev["sumsq"][k]
        for i, v in enumerate(search.names):
            a, b = s0["rest"][k, i], r0["rest"][k, i]
            row[f"model_gap_{v}"] = float(np.hypot(*(a[:2] - b[:2]))) if s0["ok"][k] and r0["ok"][k] else np.nan
            for pre, ev in (("search_rest", s0), ("refine_rest", r0), ("refined_rest", r1)):
                p = ev["rest"][k, i]
                row.update({f"{pre}_{v}_x": p[0], f"{pre}_{v}_y": p[1], f"{pre}_{v}_heading": rad_to_deg(p[2])})
        rows.append(row)
    result = RefineResult(pd.DataFrame(rows), study.spec.model, model, budget, used, 2 * n,
                          time.perf_counter() - t0, source, refine_units(search))
    if out_dir is not None:
        write_refine(study, search, result, Path(out_dir))
    return result


def _fmt(v, spec=".3f") -> str:
    return "-" if v is None or (isinstance(v, float) and not np.isfinite(v)) else format(v, spec)


def refine_units(problem) -> dict:
    """The units map (crashlab.units) of refine.csv: each variable's file unit (its value, refined value and
    move), the objectives' (m for the thesis objective, sigma for the misfit), the rest poses and the models'
    gap; the sums of squares have none (their residuals mix units)."""
    from .problem import variable_unit
    units = {}
    for f in problem.free:
        units |= dict.fromkeys((f.label, f"refined_{f.label}", f"moved_{f.label}"), variable_unit(f))
    f_unit = "m" if problem.evidence_set is None else "sigma"
    return units | dict.fromkeys(("search_f_<n>", "refine_f_<n>_start", "refine_f_<n>", "search_f_<n>_refined"),
                                 f_unit) | {
        "model_gap_<vehicle>": "m", "<pre>_rest_<vehicle>_x": "m", "<pre>_rest_<vehicle>_y": "m",
        "<pre>_rest_<vehicle>_heading": "deg"}


def write_refine(study, problem, result: RefineResult, out_dir: Path) -> None:
    """refine.csv (module docstring) and refine.md: the two models side by side, in the study's shown units
    (Study.shown_units)."""
    system = getattr(study, "shown_units", "si")
    units = refine_units(problem)
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
        frame_in(result.table, system, units).to_csv(out_dir / "refine.csv", index=False)
    except OSError as err:
        raise InputError(out_dir, "--out", err.strerror or str(err)) from None
    # the table's numbers as shown (its column names kept: the text below finds them by name)
    t = result.table.copy()
    for c in t.columns:
        if unit_of(c, units):
            t[c] = value_in(t[c], unit_of(c, units), system)
    a, b = result.search_model, result.model
    m = unit_in("m", system)
    unit = m if problem.evidence_set is None else "sigmas (normalised misfit)"
    names = list(problem.objective_names)
    lines = [f"# Second opinion: {a} searched, {b} checks", "",
             f"- study `{study.path}`; candidates: {len(t)} of the {result.source}, best first, one per basin "
             "(spaced apart as the polish's starts)",
             f"- {b}: {result.evaluations} evaluations of a budget of {result.budget} ({len(t)} to simulate the "
             f"candidates again, {result.evaluations - len(t)} in the least-squares polish); {a}: "
             f"{result.search_evaluations} evaluations; wall time {result.wall_time_s:.1f} s", "",
             f"Objectives f_<vehicle> in {unit}; sumsq: the sum of squared residuals, what the polish minimises "
             "(the refined point is the best one the polish evaluated, else the candidate itself). moved_norm: the "
             "move over the search bounds (normalised decision space). All columns: refine.csv"
             + (" (lengths in ft, speeds in mph; the sums of squares in the residuals' file units, m and deg)"
                if system == "us" else "") + ".", ""]
    if not len(t):
        lines.append("No candidates: nothing to refine.")
    else:
        best = t.iloc[0]
        moves = ", ".join(f"{lab} {best[lab]:.2f} -> {best[f'refined_{lab}']:.2f}"
                          + (f" {unit_in(unit_of(lab, units), system)}" if unit_of(lab, units) not in ("", "-")
                             else "")
                          for lab in problem.labels)
        lines += [f"**The best candidate under {b}:** at the {a} answer the objectives are "
                  + ", ".join(f"f_{n} {_fmt(best[f'search_f_{n}'])} ({a}) / {_fmt(best[f'refine_f_{n}_start'])} "
                              f"({b})" for n in names)
                  + f"; polished with {b} ({best['status']}): {moves}; objectives "
                  + ", ".join(f"f_{n} {_fmt(best[f'refine_f_{n}'])}" for n in names)
                  + f" ({b}), " + ", ".join(f"f_{n} {_fmt(best[f'search_f_{n}_refined'])}" for n in names)
                  + f" ({a} at the refined point).", "",
                  "## How the answer moves", ""]
        move = pd.DataFrame([{"candidate": int(r.candidate), "variable": lab,
                              "unit": unit_in(unit_of(lab, units), system) or "-", f"{a} answer": r[lab],
                              f"{b} answer": r[f"refined_{lab}"], "moved": r[f"moved_{lab}"]}
                             for _, r in t.iterrows() for lab in problem.labels])
        lines += [move.to_markdown(index=False, floatfmt=".3f"), "", "## Objectives under both models", "",
                  f"At the {a} answer (the candidate) and at the {b} answer (refined).", ""]
        cols = {"candidate": "candidate", "status": "status", "refine_evaluations": "evaluations",
                "moved_norm": "moved_norm"}
        for n in names:
            cols.update({f"search_f_{n}": f"f_{n} {a}", f"refine_f_{n}_start": f"f_{n} {b}",
                         f"refine_f_{n}": f"f_{n} {b} refined", f"search_f_{n}_refined": f"f_{n} {a} refined"})
        cols.update({"refine_sumsq_start": f"sumsq {b}", "refine_sumsq": f"sumsq {b} refined"})
        lines += [t[list(cols)].rename(columns=cols).to_markdown(index=False, floatfmt=".3f"), "",
                  "## Rest poses", "",
                  f"x, y [{m}], heading [deg] at the {a} answer under each model (gap: their rest positions "
                  f"apart [{m}]), and under {b} at its own answer.", ""]
        rest = []
        for _, r in t.iterrows():
            for v in problem.names:
                ev = problem.evidence.get(v)
                rest.append({"candidate": int(r.candidate), "vehicle": v,
                             "measured": "-" if ev is None else f"{value_in(ev[0], 'm', system):.2f}, "
                             f"{value_in(ev[1], 'm', system):.2f}" + ("" if ev[2] is None else f", {ev[2]:.1f}"),
                             a: ", ".join(_fmt(r[f"search_rest_{v}_{q}"], ".2f" if q != "heading" else ".1f")
                                          for q in ("x", "y", "heading")),
                             b: ", ".join(_fmt(r[f"refine_rest_{v}_{q}"], ".2f" if q != "heading" else ".1f")
                                          for q in ("x", "y", "heading")),
                             f"gap [{m}]": r[f"model_gap_{v}"],
                             f"{b} refined": ", ".join(_fmt(r[f"refined_rest_{v}_{q}"], ".2f" if q != "heading"
                                                            else ".1f") for q in ("x", "y", "heading"))})
        lines.append(pd.DataFrame(rest).to_markdown(index=False, floatfmt=".3f"))
    (out_dir / "refine.md").write_text("\n".join(lines) + "\n")
