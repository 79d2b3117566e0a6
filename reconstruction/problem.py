"""The reconstruction problem (a pymoo Problem): free variables -> scenes -> rest poses -> objectives.

Objectives, one per vehicle with evidence. The thesis's (thesis eqs 4.13-4.14, 5.4-5.8; [objective] mode =
"thesis"): f_k = |r_k - r_k*| + heading_weight * |wrap(psi_k - psi_k*)| [m]. The normalised misfit (mode =
"misfit", crashlab.reconstruction.evidence): f_k = sqrt(sum (residual / sigma)^2) over the evidence items
that concern vehicle k (rest pose, point of impact, marks, EDR); the polish then minimises the sum of
squares of all normalised residuals, each item once: the negative Gaussian log-likelihood.

A population of candidates is evaluated at a time as variants of the study's scene (the model's
`simulate_population`, crashlab.population: no Scene or Outcome per candidate; the evidence is scored on the
arrays), on the executor bound with `running_on` (crashlab.execution) or in this process. Evidence with
marks needs each candidate's CG path: then a scene per candidate is simulated and scored where it ran.
Constraints: g1 = overlap depth of the outlines at the start <= 0 (crashlab.geometry), g2 = 0 when the
vehicles collide, 1 when they miss (added to the objectives as a penalty for an optimizer without
constraint handling).

Failed evaluations. A candidate fails (objectives FAILED_OBJECTIVE, both constraints violated, so every
optimizer is pushed away from it as from an infeasible one) when the model raises, times out, its worker
dies, the Outcome is not ok (the physics guard's verdict included), or, after contact, a vehicle with
evidence is still moving at the end of the run (a miss whose cars drive on is not a failure: it is
infeasible by g2 and its end poses are not scored either). A moving vehicle's end pose is not a rest
pose: scoring its distance to the measured rest position would reward a start that merely has not
finished yet, and a penalty would have to trade km/h against metres with a weight nobody can justify;
failing it is truthful, and the reason ("V1 still moving at 34 km/h at the end ...") tells the user that
the scene's duration is too short when it happens often.

Uncertain parameters (`[[uncertain]]` in the study or its scene file, crashlab.uncertainty) are searched as
extra free variables within their support (UncertainVariable): uniform and triangular on [lower, upper], a
normal on mean +- 3 sd within its truncation (99.7 % of it). A Pareto search has no place for a prior's shape:
it asks which parameter values explain the evidence, and the Pareto rows show the values found. An entry on
a field that is a free variable already changes nothing (the free variable's bounds stand). The posterior
(crashlab.reconstruction.infer) uses the distributions themselves as priors.
"""
from __future__ import annotations

import contextlib
import dataclasses

import numpy as np
from numba import njit
from pymoo.core.problem import Problem

from crashlab import fields
from crashlab.execution import Executor
from crashlab.geometry import penetration, rect_corners
from crashlab.scene import Scene
from crashlab.units import ms_to_kmh, wrap_deg

from .schema import VEHICLE_FIELDS

FAILED_OBJECTIVE = 1e3  # m: objective value of a failed or infeasible evaluation
NORMAL_SPAN_SD = 3.0  # a normal uncertain parameter is searched on mean +- 3 sd (within its truncation)


def variable_label(path: str) -> str:
    """An uncertain parameter's column label: V1.mass for vehicles.V1.mass; road.friction, impact.restitution,
    road.zones.0.friction as they are (the posterior's labels, crashlab.reconstruction.infer)."""
    return path[len("vehicles."):] if path.startswith("vehicles.") else path


def objective_unit(problem) -> str:
    """The objectives' unit: m (thesis objective) or sigma (the normalised misfit: residuals in their sigmas)."""
    return "m" if problem.evidence_set is None else "sigma"


def evaluation_counts(problem, arch: dict | None = None) -> dict:
    """Every evaluation in the problem's archive by what became of it: total, feasible (run ok, no overlap at
    the start, a collision), overlap (run ok, vehicles overlapping at the start), no_contact (run ok, no
    impact), failed (the run failed: its reason in the archive). An overlapping start without contact counts
    as overlap."""
    arch = problem.archive_arrays() if arch is None else arch
    n = len(arch["X"])
    if not n:
        return {"total": 0, "feasible": 0, "overlap": 0, "no_contact": 0, "failed": 0}
    ok, G = arch["ok"].astype(bool), np.atleast_2d(arch["G"])
    overlap = ok & (G[:, 0] > 0)
    no_contact = ok & ~overlap & (G[:, 1] > 0)
    return {"total": int(n), "feasible": int((ok & np.all(G <= 0, axis=1)).sum()), "overlap": int(overlap.sum()),
            "no_contact": int(no_contact.sum()), "failed": int((~ok).sum())}


def scored_feasible(arch: dict) -> np.ndarray:
    """(n,) bool: the evaluation ran, is feasible and every evidence item was scored (its residuals finite; an
    unscored one, e.g. damage evidence on a side the run did not strike, has objectives FAILED_OBJECTIVE). Decided
    by these flags, not by the objectives' size: a real misfit may be as large."""
    n = len(arch["X"])
    if not n:
        return np.zeros(0, bool)
    R = np.asarray(arch["R"], dtype=float).reshape(n, -1)
    return arch["ok"].astype(bool) & np.all(np.atleast_2d(arch["G"]) <= 0, axis=1) & np.isfinite(R).all(axis=1)


def infeasible_sentence(counts: dict) -> str:
    """Why evaluations were not feasible, in words (evaluation_counts)."""
    parts = [f"{counts['overlap']} had the vehicles overlapping at the start" if counts["overlap"] else "",
             f"{counts['no_contact']} made no contact" if counts["no_contact"] else "",
             f"{counts['failed']} failed (failures.csv gives each reason)" if counts["failed"] else ""]
    parts = [p for p in parts if p]
    return (f"{counts['feasible']} of {counts['total']} evaluations feasible"
            + (": of the others " + ", ".join(parts) if parts else "") + ".")


def variable_unit(var) -> str:
    """A searched variable's file unit (km/h, m, deg, ...): a study's FreeVariable (vehicle, field) or an
    UncertainVariable (its fields path); "" where it has none."""
    from crashlab import fields
    try:
        path = getattr(var, "path", None) or fields.study_path(var.vehicle, var.field)
        return fields.parse(path).unit
    except Exception:  # noqa: BLE001 - the unit is a label only
        return ""


@dataclasses.dataclass(frozen=True)
class UncertainVariable:
    """An uncertain parameter (crashlab.uncertainty.Uncertain) as a free variable of the search: its label,
    crashlab.fields path and the search bounds (file units) of `search_bounds`."""
    label: str
    path: str
    lower: float
    upper: float
    uncertain: object = None  # the crashlab.uncertainty.Uncertain it stands for

    @classmethod
    def of(cls, u) -> UncertainVariable:
        return cls(variable_label(u.field), u.field, *search_bounds(u), u)


def search_bounds(u) -> tuple[float, float]:
    """Where the search looks for an uncertain parameter (file units): uniform and triangular on their support
    [lower, upper]; a normal on mean +- NORMAL_SPAN_SD sd within its truncation [lower, upper]."""
    if u.distribution == "normal":
        return (max(u.lower, u.mean - NORMAL_SPAN_SD * u.sd), min(u.upper, u.mean + NORMAL_SPAN_SD * u.sd))
    return float(u.lower), float(u.upper)


@njit(cache=True)
def outline_depth(poses, dims, i, j):
    """Overlap of the outlines of vehicles i and j (crashlab.geometry.penetration: depth [m], axis, ...).
    poses (nv, >=3): x, y, heading [rad]; dims (nv, 3): front, rear, half width."""
    ci = rect_corners(poses[i, 0], poses[i, 1], poses[i, 2], dims[i, 0], dims[i, 1], dims[i, 2])
    cj = rect_corners(poses[j, 0], poses[j, 1], poses[j, 2], dims[j, 0], dims[j, 1], dims[j, 2])
    return penetration(ci, cj)


@njit(cache=True)
def largest_overlap(poses, dims):
    """(n,) largest outline overlap depth over every pair of vehicles of each candidate (<= 0: none)."""
    n, nv = poses.shape[0], poses.shape[1]
    out = np.full(n, -1.0)
    for k in range(n):
        for i in range(nv):
            for j in range(i + 1, nv):
                out[k] = max(out[k], outline_depth(poses[k], dims, i, j)[0])
    return out


class ReconstructionProblem(Problem):
    """pymoo Problem: free variables (file units) -> scenes -> rest poses -> objectives/constraints.
    `free`: the study's FreeVariables, then any UncertainVariables (each has label, path, lower, upper)."""

    def __init__(self, scene: Scene, free: list, evidence: dict, heading_weight: float,
                 model: str, model_options: dict, constraints_as_penalty: bool = False, evidence_set=None):
        self.scene, self.free, self.evidence = scene, list(free), evidence  # evidence: name -> (x, y, heading deg)
        self.scene_fields = [fields.resolve(scene, f.path) for f in self.free]  # ValueError: not in this scene
        self.heading_weight, self.model, self.model_options = heading_weight, model, model_options
        self.evidence_set = evidence_set  # None: the thesis objective; else the misfit (module docstring)
        self.names = scene.vehicle_names
        self.objective_names = list(evidence) if evidence_set is None else list(evidence_set.objective_names)
        self.executor = None
        # R: the residual vector of every evaluation (`residuals`; normalised with the misfit objective)
        self.archive = {"X": [], "F": [], "G": [], "R": [], "rest": [], "contact": [], "ok": [], "reason": []}
        self.n_failed = 0
        self.outline_dims = np.array([[v.spec.cg_to_front, v.spec.cg_to_rear, v.spec.width / 2]
                                      for v in scene.vehicles])
        self.columns = {}  # (vehicle index, field) -> column of X
        for c, f in enumerate(self.scene_fields):
            if f.kind == "vehicle" and f.quantity in VEHICLE_FIELDS:
                self.columns[(self.names.index(f.vehicle), f.quantity)] = c
        self.movable = np.array([(i, "x") in self.columns and (i, "y") in self.columns
                                 for i in range(len(self.names))], bool)
        # for an optimizer without constraint handling the violation is added to every objective
        self.constraints_as_penalty = constraints_as_penalty
        super().__init__(n_var=len(free), n_obj=len(self.objective_names),
                         n_ieq_constr=0 if constraints_as_penalty else 2,
                         xl=np.array([f.lower for f in free], dtype=float),
                         xu=np.array([f.upper for f in free], dtype=float),
                         # a live pool or Dask client, a closure: no state (the setter is made again)
                         exclude_from_serialization=["executor", "_setter"])
        self._setter = None

    # -- variables <-> scenes
    @property
    def labels(self) -> list[str]:
        """The column labels of X (pareto.csv): the free variables', then the uncertain parameters'."""
        return [f.label for f in self.free]

    def to_si(self, X) -> np.ndarray:
        """(n, n_var) free variables in SI (m, rad, m/s) from X in file units (m, deg, km/h). X may hold the
        first columns only (the study's free variables without the uncertain parameters)."""
        X = np.atleast_2d(np.asarray(X, dtype=float))
        S = X.copy()
        for c, f in enumerate(self.scene_fields[:X.shape[1]]):  # crashlab.fields: the one unit table
            S[:, c] = f.to_si_array(X[:, c])
        return S

    def scenes_for(self, X) -> list[Scene]:
        """The base scene with each row of X (file units) put in (crashlab.fields.setter, unchecked: the
        bounds lie within each field's range)."""
        if self._setter is None:
            self._setter = fields.setter(self.scene, self.scene_fields, check=False)
        return [self._setter(row) for row in np.atleast_2d(np.asarray(X, dtype=float))]

    def scene_for(self, x) -> Scene:
        return self.scenes_for(x)[0]

    def base_values(self) -> np.ndarray:
        """Each free variable's value in the base scene (file units): the truth of a twin experiment."""
        return np.array([fields.get(self.scene, f) for f in self.scene_fields], dtype=float)

    def start_poses(self, X) -> np.ndarray:
        """(n, nv, 4): x, y, heading [rad], speed [m/s] of every vehicle at the start."""
        S = self.to_si(X)
        poses = np.empty((len(S), len(self.names), 4))
        poses[:] = [(v.x, v.y, v.heading, v.speed) for v in self.scene.vehicles]
        for (i, field), c in self.columns.items():
            if c < S.shape[1]:
                poses[:, i, VEHICLE_FIELDS.index(field)] = S[:, c]
        return poses

    def with_positions(self, X, poses) -> np.ndarray:
        """X with the free x, y columns taken from poses, clipped to the bounds."""
        X = np.array(X, dtype=float, copy=True)
        for (i, field), c in self.columns.items():
            if field in ("x", "y"):
                X[:, c] = poses[:, i, 0 if field == "x" else 1]
        return np.clip(X, self.xl, self.xu)

    def start_overlap(self, X) -> np.ndarray:
        """Largest outline overlap at the start per candidate (<= 0: none). A scene at its collision
        position (a given point of impact) overlaps by design: no constraint then."""
        if self.scene.impact.point is not None:
            return np.full(len(np.atleast_2d(X)), -1.0)
        return largest_overlap(self.start_poses(X), self.outline_dims)

    # -- evaluation
    def objectives(self, rest: np.ndarray) -> np.ndarray:
        """rest (n, nv, 3) SI -> F (n, n_obj) [m]."""
        F = np.empty((len(rest), len(self.evidence)))
        for col, (name, (ex, ey, eh)) in enumerate(self.evidence.items()):
            i = self.names.index(name)
            F[:, col] = np.hypot(rest[:, i, 0] - ex, rest[:, i, 1] - ey)
            if self.heading_weight and eh is not None:
                F[:, col] += self.heading_weight * np.abs(wrap_deg(np.degrees(rest[:, i, 2]) - eh))
        return F

    def residuals(self, rest: np.ndarray) -> np.ndarray:
        """rest (n, nv, 3) SI -> (n, m) residual vector whose parts make the objectives: dx, dy per
        vehicle [m], and heading_weight * wrapped heading error [m] where the heading counts."""
        parts = []
        for name, (ex, ey, eh) in self.evidence.items():
            i = self.names.index(name)
            parts += [rest[:, i, 0] - ex, rest[:, i, 1] - ey]
            if self.heading_weight and eh is not None:
                parts.append(self.heading_weight * wrap_deg(np.degrees(rest[:, i, 2]) - eh))
        return np.column_stack(parts)

    def evaluate_residuals(self, X) -> np.ndarray:
        """Evaluate X (recorded in the archive like any evaluation) -> residuals (`residuals`, or the
        normalised ones of the misfit objective); a failed or infeasible candidate gets FAILED_OBJECTIVE in
        every component."""
        G, R = self.evaluate(np.atleast_2d(X), return_values_of=["constraints", "residuals"])
        R = np.array(R, dtype=float, copy=True)
        R[np.any(G > 0, axis=1) | ~np.isfinite(R).all(axis=1)] = FAILED_OBJECTIVE
        return R

    @contextlib.contextmanager
    def running_on(self, executor):
        """Evaluations inside the block run on `executor` (a live crashlab.execution.Executor), outside it in
        this process. A scoped binding, not a constructor argument: pymoo's algorithm owns the problem, and a
        checkpoint restores it without the live pool (exclude_from_serialization)."""
        self.executor = executor
        try:
            yield self
        finally:
            self.executor = None

    def simulate(self, X, paths=None):
        """(Population, residuals R) of the rows X (file units) of `paths` (crashlab.fields; default the
        problem's free variables), unchecked (the rows lie within the fields' ranges), on the executor:
        the variants as one scene and blocks of rows (the model's simulate_population), the evidence scored
        on the arrays; evidence with marks needs CG paths, so then a scene per row, scored where simulated
        (crashlab.execution, scorer). R: the thesis objective's residuals from the rest poses, or the
        evidence's normalised ones."""
        es = self.evidence_set
        fs = self.scene_fields if paths is None else [fields.resolve(self.scene, p) for p in paths]
        X = np.atleast_2d(np.asarray(X, dtype=float))
        ex = self.executor or Executor()
        if es is not None and es.needs_trajectory:
            build = fields.setter(self.scene, fs, check=False)
            pop = ex.evaluate(self.model, self.model_options, [build(row) for row in X], scorer=es)
        else:
            pop = ex.evaluate_population(self.model, self.model_options, self.scene, fs, X, scorer=es,
                                         invalid="unchecked")
        return pop, (self.residuals(pop.rest) if es is None else pop.scores)

    def _evaluate(self, X, out, *args, **kwargs):
        ev, R = self.simulate(X)
        ok, reason = ev.ok.copy(), ev.reason.copy()
        hit = ev.n_impacts > 0
        moving = np.zeros(len(X), bool)
        for name in self.evidence:  # a vehicle with evidence must be at rest: its end pose is scored as one
            i = self.names.index(name)
            moving |= ev.ok & ~ev.at_rest[:, i]
            for k in np.flatnonzero(ev.ok & hit & ~ev.at_rest[:, i]):
                reason[k] = (reason[k] + "; " if reason[k] else "") + (
                    f"{name} still moving at {ms_to_kmh(ev.rest_speed[k, i]):.0f} km/h at the end "
                    "(scene duration too short?)")
        ok &= ~(moving & hit)  # a miss that drives on is no failure: it is infeasible (g2) and not scored
        if self.evidence_set is None:
            F = self.objectives(ev.rest)
        else:
            F = self.evidence_set.objectives(R)
            F[~np.isfinite(F).all(axis=1)] = FAILED_OBJECTIVE  # e.g. a miss where the point of impact is evidence
        F[~ok | moving] = FAILED_OBJECTIVE
        G = np.column_stack([self.start_overlap(X), np.where(ev.n_impacts > 0, 0.0, 1.0)])
        G[~ok] = 1.0
        self.n_failed += int((~ok).sum())
        for key, val in (("X", X), ("F", F), ("G", G), ("R", R), ("rest", ev.rest), ("contact", ev.contact),
                         ("ok", ok), ("reason", reason)):
            self.archive[key].append(np.asarray(val))
        out["constraints"], out["rest"], out["residuals"] = G, ev.rest, R
        if self.constraints_as_penalty:
            out["F"] = F + FAILED_OBJECTIVE * np.maximum(G, 0.0).sum(axis=1, keepdims=True)
        else:
            out["F"], out["G"] = F, G

    def archive_arrays(self) -> dict:
        return {k: np.concatenate(v) if v else np.empty(0) for k, v in self.archive.items()}
