"""Local polish of a search result: bounded nonlinear least squares from the best candidates.

After the search, `polish_archive` ([polish] of the study file) refines the best feasible candidates of a
ReconstructionProblem's archive with `polish`; it runs by default with POLISH_SHARE of the search budget
(at least POLISH_MIN evaluations, crashlab.reconstruction.schema); `[polish] evaluations = 0` turns it off.

A population search finds the basin of a good reconstruction quickly and closes in on its bottom
slowly (the thesis's NSGA has no elitism and shares fitness to keep the population spread). The
polish takes the best few candidates and runs ``scipy.optimize.least_squares`` (trust-region
reflective, inside the bounds) on the residual vector from each, until an evaluation budget is
spent. The Jacobian is a forward difference with a step of ``rel_step`` of every bound range; its
``n_var`` perturbed points are evaluated as one batch, so a batch-capable model and a parallel
executor serve the polish as they serve the search. A hybrid of a genetic search with a
gradient-based local search is the usual memetic scheme (e.g. Deb & Goel 2001, "A hybrid
multi-objective evolutionary approach to engineering shape design").

The step is coarse on purpose: a simulated rest pose is piecewise smooth in the start, with kinks
(a change of impact count or corner) and a small roughness from time stepping. With the impulse
model's former 1 mm onset tolerance (2-3 cm of rest-pose jitter) a step of 1e-4 stalled at 0.13 m on
twin 4 where 1e-2 reached 2e-7 m; with today's 0.01 mm the step matters little (twin 4, seeds 1-10,
worst after the polish: 0.031 m at 1e-3, 0.024 m at 1e-2, 0.034 m at 3e-2).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

DEFAULT_REL_STEP = 0.01
# least distance between polish starts, normalised decision space: with 0.1 every start of twin 4 at
# seed 9 lay in one wrong basin (0.14 m); with 0.2 the fifty twin runs (5 studies x 10 seeds) end <= 7.6 cm
POLISH_SPACING = 0.2


class _BudgetSpent(Exception):
    pass


@dataclass
class PolishResult:
    evaluations: int  # residual evaluations used (every candidate counted once per evaluation)
    x: np.ndarray  # (n_starts, n_var) best point reached from each start
    cost: np.ndarray  # (n_starts,) 0.5 * |r|^2 at those points


def polish(residuals, starts, xl, xu, max_evaluations: int, rel_step: float = DEFAULT_REL_STEP,
           start_residuals=None) -> PolishResult:
    """Least-squares polish of ``starts`` within the bounds ``xl``, ``xu``.

    residuals(X) maps a batch (n, n_var) to residual vectors (n, m); it is never asked for more
    than ``max_evaluations`` points in all. The starts are polished in the order given until the
    budget is spent. ``start_residuals`` (n_starts, m), when known, saves evaluating the starts again.
    """
    from scipy.optimize import least_squares  # imported when needed: it takes a while
    xl, xu = np.asarray(xl, float), np.asarray(xu, float)
    span = xu - xl
    starts = np.atleast_2d(np.asarray(starts, float))
    used = 0
    seen: dict[bytes, np.ndarray] = {}

    def batch(Z):  # normalised points -> residuals, within the budget
        nonlocal used
        if used + len(Z) > max_evaluations:
            raise _BudgetSpent
        used += len(Z)
        return np.asarray(residuals(xl + Z * span), float)

    best_x, best_cost = starts.copy(), np.full(len(starts), np.inf)

    def remember(k, z, r):
        cost = 0.5 * float(r @ r)
        if cost < best_cost[k]:
            best_x[k], best_cost[k] = xl + z * span, cost

    for k, x0 in enumerate(starts):
        seen.clear()

        def fun(z, k=k):
            key = z.tobytes()
            if key not in seen:
                seen[key] = batch(z[None])[0]
                remember(k, z, seen[key])
            return seen[key]

        def jac(z, k=k):
            r0 = fun(z)
            h = np.where(z + rel_step <= 1.0, rel_step, -rel_step)  # stay inside the bounds
            Z = z[None, :] + np.diag(h)
            R = batch(Z)
            for zi, ri in zip(Z, R):
                remember(k, zi, ri)
            return ((R - r0[None, :]) / h[:, None]).T

        z0 = np.clip((x0 - xl) / span, 0.0, 1.0)
        if start_residuals is not None:
            seen[z0.tobytes()] = np.asarray(start_residuals[k], float)
            remember(k, z0, seen[z0.tobytes()])
        try:
            least_squares(fun, z0, jac=jac, bounds=(0.0, 1.0), method="trf")
        except _BudgetSpent:
            break
        if used + 1 + len(z0) > max_evaluations:
            break
    return PolishResult(used, best_x, best_cost)


def spaced_starts(X, xl, xu, spacing: float = POLISH_SPACING):
    """The rows of X (best first) that lie at least `spacing` (normalised decision space) from every
    earlier pick, and their indices: one start per basin rather than several in the best one."""
    Z = (X - xl) / (xu - xl)
    picked: list[int] = []
    for k in range(len(Z)):
        if not picked or np.min(np.linalg.norm(Z[picked] - Z[k], axis=1)) >= spacing:
            picked.append(k)
    return X[picked], np.array(picked, dtype=int)


def polish_archive(problem, spec, repair=None, budget: int | None = None):
    """Least-squares polish (`polish`) from the best feasible candidates so far, ranked
    by their worse objective and spaced apart, until the budget is spent; every polish evaluation
    enters the archive. With a repair, each point is repaired before it is evaluated: the back-off
    makes the residual continuous across the start-overlap boundary, where repaired candidates sit."""
    arch = problem.archive_arrays()
    # a start must be scored: a row of NaN residuals (evidence no candidate run can score, e.g. damage on a side
    # the impact did not strike, crashlab.reconstruction.evidence_set) makes least_squares raise at its first point
    scored = np.all(np.isfinite(arch["R"]), axis=1) if arch["R"].ndim == 2 else np.ones(len(arch["ok"]), bool)
    feasible = np.flatnonzero(np.all(arch["G"] <= 0, axis=1) & arch["ok"] & scored)
    if len(feasible) == 0:
        return
    order = feasible[np.argsort(arch["F"][feasible].max(axis=1), kind="stable")]
    starts, picked = spaced_starts(arch["X"][order], problem.xl, problem.xu)

    budget = spec.evaluations if budget is None else budget
    polish(repaired_residuals(problem, repair), starts, problem.xl, problem.xu, budget, spec.step,
           start_residuals=arch["R"][order[picked]])


def repaired_residuals(problem, repair=None):
    """The residual function a polish runs on: X -> the problem's residuals (ReconstructionProblem.
    evaluate_residuals, every point recorded in its archive), each point repaired first when a repair is given."""
    def residuals(X):
        return problem.evaluate_residuals(X if repair is None else repair.apply(problem, X))
    return residuals
