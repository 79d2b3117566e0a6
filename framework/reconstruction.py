"""Reconstruction: search the pre-impact conditions whose simulated rest poses match the evidence.

A study file names a base scene, a model, an optimizer, the free variables with bounds and the
measured rest poses. The problem is a pymoo Problem evaluated a population at a time through the
model's `simulate_batch` (in this process, in worker processes or on Dask: crashlab.execution).
Objectives, one per vehicle with evidence (thesis eqs 4.13-4.14, 5.4-5.8):
f_k = |r_k - r_k*| + heading_weight * |wrap(psi_k - psi_k*)|. Constraints: g1 = overlap depth at the
start <= 0, g2 = 0 when the vehicles collide, 1 when they miss (added to the objectives as a penalty
for an optimizer without constraint handling). After the search a least-squares polish ([polish],
optimizers/polish.py) refines the best candidates; it runs by default with POLISH_SHARE of the search
budget (at least POLISH_MIN evaluations); `[polish] evaluations = 0` turns it off.

Failed evaluations. A candidate fails (objectives FAILED_OBJECTIVE, both constraints violated, so every
optimizer is pushed away from it as from an infeasible one) when the model raises, times out, its worker
dies, the Outcome is not ok (the physics guard's verdict included), or, after contact, a vehicle with
evidence is still moving at the end of the run (a miss whose cars drive on is not a failure: it is
infeasible by g2 and its end poses are not scored either). A moving vehicle's end pose is not a rest
pose: scoring its distance to the measured rest position would reward a start that merely has not
finished yet, and a penalty would have to trade km/h against metres with a weight nobody can justify;
failing it is truthful, and the reason ("V1 still moving at 34 km/h at the end ...") tells the user that
the scene's duration is too short when it happens often. Every failure is in DIR/failures.csv with its
free variables and reason.

Resume. The checkpoint (DIR/checkpoint.pkl, after every generation) holds a fingerprint of what the
result depends on: the study file's content (without the execution backend and workers, which do not
change results), the base scene and every vehicle's data as loaded (so edits of comments change
nothing), the evidence as used (a twin's evidence is the model's run), the model and its options, and the
crashlab version. `--resume` refuses a checkpoint whose fingerprint differs, or that cannot be read.
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import os
import pickle
import re
import time
from pathlib import Path
from typing import Annotated, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, Strict, StrictBool, ValidationError, model_validator
from pymoo.core.problem import Problem

from .errors import InputError
from .execution import DEFAULT_TIMEOUT_S
from .registry import UnknownPluginError, available_models, available_optimizers
from .scene import Scene, load_scene
from .units import deg_to_rad, kmh_to_ms, ms_to_kmh, rad_to_deg, wrap_deg
from .vehicle import pydantic_error, read_toml

VEHICLE_FIELDS = ("x", "y", "heading", "speed")
IMPACT_FIELDS = ("restitution", "friction")
# least distance between polish starts, normalised decision space: with 0.1 every start of twin 4 at
# seed 9 lay in one wrong basin (0.14 m); with 0.2 the fifty twin runs (5 studies x 10 seeds) end <= 7.6 cm
POLISH_SPACING = 0.2
# default polish budget: this share of pop_size x generations, at least POLISH_MIN evaluations (a
# least-squares iteration costs n_var + 1 evaluations: 100 are ~10 iterations with all eight variables
# of case 5 free). The twins need it: the search alone leaves 0.16-0.23 m on twin 4 (README)
POLISH_SHARE = 0.10
POLISH_MIN = 100
FAILED_OBJECTIVE = 1e3  # m: objective value of a failed or infeasible evaluation
DUPLICATE_TOL = 1e-6  # Pareto rows whose every free variable lies this close (share of its bound width) are one
CHECKPOINT_FORMAT = "crashlab reconstruction checkpoint 2"

# Bounds of a study file (file units): finite numbers (true/false are not numbers) in these ranges, the
# ranges of a scene file (crashlab.scene) where they describe the same thing
POSITION_MAX = 1e5  # m: |x|, |y| of free bounds and evidence (a local site frame)
ANGLE_MAX = 3600.0  # deg: |heading|
SPEED_MAX = 400.0  # km/h
FRICTION_MAX = 2.0
FIELD_RANGES = {"x": (-POSITION_MAX, POSITION_MAX), "y": (-POSITION_MAX, POSITION_MAX),
                "heading": (-ANGLE_MAX, ANGLE_MAX), "speed": (0.0, SPEED_MAX),
                "restitution": (0.0, 1.0), "friction": (0.0, FRICTION_MAX)}
POP_SIZE_RANGE = (4, 100_000)  # 4: two mating pairs; 1e5 x the largest sensible number of free variables
GENERATIONS_MAX = 100_000
SEED_MAX = 2**32 - 1  # numpy's seed range
WORKERS_MAX = 1024

Real = Annotated[float, Strict()]  # int or float, never a bool or a string; NaN and inf refused
Int = Annotated[int, Strict()]  # an integer: 1e9 (a float) and true are refused


# ---------------------------------------------------------------- study file
class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)


class OptimizerSection(_Strict):
    name: str = "nsga2"
    pop_size: Int = Field(default=75, ge=POP_SIZE_RANGE[0], le=POP_SIZE_RANGE[1],
                          description=f"[{POP_SIZE_RANGE[0]}, {POP_SIZE_RANGE[1]}]")
    generations: Int = Field(default=20, ge=1, le=GENERATIONS_MAX, description=f"[1, {GENERATIONS_MAX}]")
    seed: Int = Field(default=1, ge=0, le=SEED_MAX, description=f"[0, {SEED_MAX}]")
    options: dict = Field(default_factory=dict)


class FreeVariable(_Strict):
    vehicle: str | None = None  # None for the impact's restitution / friction
    field: Literal["x", "y", "heading", "speed", "restitution", "friction"]
    lower: Real
    upper: Real

    @model_validator(mode="after")
    def _check(self):
        lo, hi = FIELD_RANGES[self.field]
        unit = {"x": " m", "y": " m", "heading": " deg", "speed": " km/h"}.get(self.field, "")
        for key in ("lower", "upper"):
            val = getattr(self, key)
            if not lo <= val <= hi:
                raise ValueError(f"{key} = {val:g} is outside [{lo:g}, {hi:g}]{unit} for {self.field}")
        if not self.lower < self.upper:
            raise ValueError(f"lower ({self.lower}) must be below upper ({self.upper})")
        if self.field in VEHICLE_FIELDS and self.vehicle is None:
            raise ValueError(f"field {self.field!r} needs a vehicle")
        if self.field in IMPACT_FIELDS and self.vehicle is not None:
            raise ValueError(f"field {self.field!r} belongs to the impact: give no vehicle")
        return self

    @property
    def label(self) -> str:
        return f"{self.vehicle}.{self.field}" if self.vehicle else f"impact.{self.field}"


class RestPose(_Strict):
    x: Real = Field(ge=-POSITION_MAX, le=POSITION_MAX, description=f"m; |value| <= {POSITION_MAX:g}")
    y: Real = Field(ge=-POSITION_MAX, le=POSITION_MAX, description=f"m; |value| <= {POSITION_MAX:g}")
    # deg; without it the heading term is left out for this vehicle (dheading is empty)
    heading: Real | None = Field(default=None, ge=-ANGLE_MAX, le=ANGLE_MAX)


class Evidence(_Strict):
    rest: dict[str, RestPose] = Field(default_factory=dict)
    twin: StrictBool = False  # evidence = the model's own simulation of the base scene (twin experiment)


class ObjectiveSection(_Strict):
    # m per deg of rest-heading error; 100 m/deg would already let 0.01 deg outweigh a metre
    heading_weight: Real = Field(default=0.0, ge=0, le=100.0, description="m/deg; [0, 100]")
    hv_reference: Real = Field(default=10.0, gt=0, le=1e6)  # m, hypervolume reference point per objective


class ExecutionSection(_Strict):
    backend: Literal["serial", "processes", "dask"] = "serial"
    workers: Int = Field(default=2, ge=1, le=WORKERS_MAX, description=f"[1, {WORKERS_MAX}]")
    scheduler: str | None = None
    # s per evaluation (crashlab.execution.DEFAULT_TIMEOUT_S); 0: no limit (the serial backend then runs
    # in this process, and a hanging model hangs the run)
    timeout_s: Real = Field(default=DEFAULT_TIMEOUT_S, ge=0, le=86400.0, description="s; [0, 86400], 0 = no limit")


class RepairSection(_Strict):
    enabled: StrictBool = True
    max_shift: Real = Field(default=1.0, ge=0, le=100.0, description="m; [0, 100]")


class PolishSection(_Strict):
    """Least-squares polish after the search (optimizers/polish.py). evaluations: the budget; absent:
    POLISH_SHARE of pop_size x generations, at least POLISH_MIN; 0: off."""
    evaluations: Int | None = Field(default=None, ge=0, le=10_000_000)
    step: Real = Field(default=0.01, gt=0, lt=0.5)  # forward-difference step, fraction of each bound range

    def budget(self, pop_size: int, generations: int) -> int:
        if self.evaluations is not None:
            return int(self.evaluations)
        return max(POLISH_MIN, math.ceil(POLISH_SHARE * pop_size * generations))


class StudyFile(_Strict):
    name: str = ""
    scene: str
    model: str = "impulse"
    model_options: dict = Field(default_factory=dict)
    optimizer: OptimizerSection = OptimizerSection()
    free: list[FreeVariable] = Field(min_length=1, max_length=1000)
    evidence: Evidence
    objective: ObjectiveSection = ObjectiveSection()
    execution: ExecutionSection = ExecutionSection()
    repair: RepairSection = RepairSection()
    polish: PolishSection = PolishSection()


# ---------------------------------------------------------------- the problem
class ReconstructionProblem(Problem):
    """pymoo Problem: free variables (file units) -> scenes -> rest poses -> objectives/constraints."""

    def __init__(self, scene: Scene, free: list[FreeVariable], evidence: dict, heading_weight: float,
                 model: str, model_options: dict, constraints_as_penalty: bool = False):
        self.scene, self.free, self.evidence = scene, free, evidence  # evidence: name -> (x, y, heading deg)
        self.heading_weight, self.model, self.model_options = heading_weight, model, model_options
        self.names = scene.vehicle_names
        self.targets = [self.names.index(n) for n in evidence]
        self.executor = None
        self.archive = {"X": [], "F": [], "G": [], "rest": [], "contact": [], "ok": [], "reason": []}
        self.n_failed = 0
        nv = len(self.names)
        self.outline_dims = np.array([[v.spec.cg_to_front, v.spec.cg_to_rear, v.spec.width / 2]
                                      for v in scene.vehicles])
        self.movable = np.zeros(nv, bool)
        self.columns = {}  # (vehicle index, field) -> column of X
        for c, f in enumerate(free):
            if f.vehicle is not None:
                self.columns[(self.names.index(f.vehicle), f.field)] = c
        for i in range(nv):
            self.movable[i] = (i, "x") in self.columns and (i, "y") in self.columns
        # for an optimizer without constraint handling the violation is added to every objective
        self.constraints_as_penalty = constraints_as_penalty
        super().__init__(n_var=len(free), n_obj=len(evidence), n_ieq_constr=0 if constraints_as_penalty else 2,
                         xl=np.array([f.lower for f in free]), xu=np.array([f.upper for f in free]))

    def __getstate__(self):
        state = dict(self.__dict__)
        state["executor"] = None  # a live pool or Dask client is not part of a checkpoint
        return state

    # -- variables <-> scenes (file units in X: m, deg, km/h)
    def scene_for(self, x) -> Scene:
        changes: dict[int, dict] = {}
        impact = {}
        for f, val in zip(self.free, x):
            if f.vehicle is None:
                impact[f.field] = float(val)
                continue
            i = self.names.index(f.vehicle)
            v = {"heading": deg_to_rad(val), "speed": kmh_to_ms(val)}.get(f.field, float(val))
            changes.setdefault(i, {})[f.field] = v
        scene = self.scene
        for i, ch in changes.items():
            scene = scene.with_vehicle(self.names[i], **ch)
        if impact:
            import dataclasses
            scene = scene.replace(impact=dataclasses.replace(scene.impact, **impact))
        return scene

    def base_values(self) -> np.ndarray:
        """Each free variable's value in the base scene (file units): the truth of a twin experiment."""
        out = []
        for f in self.free:
            if f.vehicle is None:
                out.append(getattr(self.scene.impact, f.field))
                continue
            v = self.scene.vehicles[self.names.index(f.vehicle)]
            out.append({"x": v.x, "y": v.y, "heading": rad_to_deg(v.heading), "speed": ms_to_kmh(v.speed)}[f.field])
        return np.array(out, dtype=float)

    def start_poses(self, X) -> np.ndarray:
        """(n, nv, 4): x, y, heading [rad], speed [m/s] of every vehicle at the start."""
        X = np.atleast_2d(X)
        poses = np.empty((len(X), len(self.names), 4))
        for i, v in enumerate(self.scene.vehicles):
            base = (v.x, v.y, v.heading, v.speed)
            for q, field in enumerate(VEHICLE_FIELDS):
                c = self.columns.get((i, field))
                if c is None:
                    poses[:, i, q] = base[q]
                else:
                    poses[:, i, q] = X[:, c] if field in ("x", "y") else (
                        np.radians(X[:, c]) if field == "heading" else X[:, c] / 3.6)
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
        from crashlab.optimizers.repair import _depth
        if self.scene.impact.point is not None:
            return np.full(len(np.atleast_2d(X)), -1.0)
        poses = self.start_poses(X)
        nv = len(self.names)
        out = np.full(len(poses), -1.0)
        for k in range(len(poses)):
            for i in range(nv):
                for j in range(i + 1, nv):
                    out[k] = max(out[k], _depth(poses[k], self.outline_dims, i, j)[0])
        return out

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
        """Evaluate X (recorded in the archive like any evaluation) -> residuals; a failed or
        infeasible candidate gets FAILED_OBJECTIVE in every component."""
        G, rest = self.evaluate(np.atleast_2d(X), return_values_of=["constraints", "rest"])
        R = self.residuals(rest)
        R[np.any(G > 0, axis=1) | ~np.isfinite(R).all(axis=1)] = FAILED_OBJECTIVE
        return R

    def _evaluate(self, X, out, *args, **kwargs):
        from .execution import Executor
        scenes = [self.scene_for(x) for x in X]
        executor = self.executor or Executor()
        ev = executor.evaluate(self.model, self.model_options, scenes)
        ok, reason = ev.ok.copy(), ev.reason.copy()
        hit = ev.n_impacts > 0
        moving = np.zeros(len(X), bool)
        for name in self.evidence:  # a vehicle with evidence must be at rest: its end pose is scored as one
            i = self.names.index(name)
            moving |= ev.ok & ~ev.at_rest[:, i]
            for k in np.flatnonzero(ev.ok & hit & ~ev.at_rest[:, i]):
                reason[k] = (reason[k] + "; " if reason[k] else "") + (
                    f"{name} still moving at {ms_to_kmh(ev.end_speed[k, i]):.0f} km/h at the end "
                    "(scene duration too short?)")
        ok &= ~(moving & hit)  # a miss that drives on is no failure: it is infeasible (g2) and not scored
        F = self.objectives(ev.rest)
        F[~ok | moving] = FAILED_OBJECTIVE
        G = np.column_stack([self.start_overlap(X), np.where(ev.n_impacts > 0, 0.0, 1.0)])
        G[~ok] = 1.0
        self.n_failed += int((~ok).sum())
        for key, val in (("X", X), ("F", F), ("G", G), ("rest", ev.rest), ("contact", ev.contact), ("ok", ok),
                         ("reason", reason)):
            self.archive[key].append(np.asarray(val))
        out["constraints"], out["rest"] = G, ev.rest
        if self.constraints_as_penalty:
            out["F"] = F + FAILED_OBJECTIVE * np.maximum(G, 0.0).sum(axis=1, keepdims=True)
        else:
            out["F"], out["G"] = F, G

    def archive_arrays(self) -> dict:
        return {k: np.concatenate(v) if v else np.empty(0) for k, v in self.archive.items()}


# ---------------------------------------------------------------- the study
class ReconstructionResult:
    def __init__(self, pareto, evaluations, failed, feasible_fraction, wall_time_s, problem, algorithm_info):
        self.pareto, self.evaluations, self.failed = pareto, evaluations, failed
        self.feasible_fraction, self.wall_time_s = feasible_fraction, wall_time_s
        self.problem, self.algorithm_info = problem, algorithm_info

    def to_json_dict(self) -> dict:
        p = self.problem

        def num(v):
            v = float(v)
            return None if math.isnan(v) else v
        items = []
        for _, row in self.pareto.iterrows():
            items.append({"start": {f.label: float(row[f.label]) for f in p.free},
                          "objectives": {f"f_{n}": float(row[f"f_{n}"]) for n in p.evidence},
                          "rest": {n: {**{k: float(row[f"rest_{n}_{k}"]) for k in ("x", "y", "heading")},
                                       "dheading": num(row[f"dheading_{n}"])} for n in p.names}})
        arch = p.archive_arrays()
        reasons = failure_counts(arch["reason"][~arch["ok"]]) if len(arch["X"]) else {}
        return {"pareto": items, "evaluations": self.evaluations, "failed": self.failed,
                "failure_reasons": reasons, "feasible_fraction": self.feasible_fraction,
                "wall_time_s": round(self.wall_time_s, 3), **self.algorithm_info}


def failure_counts(reasons) -> dict:
    """Failure reasons grouped with their numbers replaced by N, most frequent first."""
    counts: dict[str, int] = {}
    for r in reasons:
        key = re.sub(r"(?<![\w.])[-+]?\d+(\.\d+)?(e[-+]?\d+)?(?![\w.])", "N", str(r))
        counts[key] = counts.get(key, 0) + 1
    return dict(sorted(counts.items(), key=lambda kv: -kv[1]))


def _canonical(obj) -> str:
    def default(o):
        if isinstance(o, np.ndarray):
            return o.tolist()
        if isinstance(o, (np.floating, np.integer, np.bool_)):
            return o.item()
        return repr(o)
    return json.dumps(obj, sort_keys=True, default=default)


def _digest(obj) -> str:
    return hashlib.sha256(_canonical(obj).encode()).hexdigest()[:16]


def crashlab_version() -> str:
    from importlib.metadata import PackageNotFoundError, version
    try:
        return version("crashlab")
    except PackageNotFoundError:
        return "unknown"


class Study:
    def __init__(self, path: Path, spec: StudyFile, scene: Scene, evidence: dict):
        self.path, self.spec, self.scene, self.evidence = path, spec, scene, evidence

    def fingerprint(self) -> dict:
        """What a result depends on, part by part (see the module docstring): part -> digest."""
        study = self.spec.model_dump(exclude={"execution": {"backend", "workers", "scheduler"}})
        scene = dataclasses.asdict(self.scene)
        for key in ("source", "references"):
            scene.pop(key, None)
        for v in scene["vehicles"]:
            v.pop("spec", None)
        parts = {"study file": _digest(study), "scene file": _digest(scene)}
        for v in self.scene.vehicles:
            parts[f"vehicle data of {v.name}"] = _digest(dataclasses.asdict(v.spec))
        parts["evidence"] = _digest({n: [None if e is None else float(e) for e in ev]
                                     for n, ev in self.evidence.items()})
        parts["model and its options"] = _digest([self.spec.model, self.spec.model_options])
        parts["crashlab version"] = crashlab_version()
        return parts

    def make_problem(self, constraints_as_penalty: bool = False) -> ReconstructionProblem:
        return ReconstructionProblem(self.scene, self.spec.free, self.evidence, self.spec.objective.heading_weight,
                                     self.spec.model, self.spec.model_options, constraints_as_penalty)

    def make_repair(self):
        """The study's CollisionRepair, or None (switched off, or a scene at its collision position)."""
        if not self.spec.repair.enabled or self.scene.impact.point is not None:
            return None
        from crashlab.optimizers.repair import CollisionRepair
        return CollisionRepair(max_shift=self.spec.repair.max_shift)

    def make_algorithm(self, optimizer: str | None = None):
        from .registry import OPTIMIZERS, load
        o = self.spec.optimizer
        name = optimizer or o.name
        opts = dict(o.options)
        repair = self.make_repair()
        if repair is not None:
            opts["repair"] = repair
        try:
            factory = load(OPTIMIZERS, name)
            if getattr(factory, "takes_n_obj", False):  # conventions: optimizers/pymoo_algorithms.py
                opts.setdefault("n_obj", len(self.evidence))
            return name, factory(pop_size=o.pop_size, **opts)
        except UnknownPluginError as err:
            raise InputError(self.path, "optimizer.name", str(err)) from None
        except (TypeError, ValueError) as err:
            raise InputError(self.path, "optimizer.options", str(err)) from None

    def polish_budget(self) -> int:
        o = self.spec.optimizer
        return self.spec.polish.budget(o.pop_size, o.generations)

    def _resume(self, ckpt: Path, optimizer: str | None):
        """The algorithm and optimizer name of a checkpoint of this very study, else InputError."""
        if not ckpt.is_file():
            raise InputError(ckpt, "--resume", "no checkpoint to resume from (give the --out DIR of the run)")
        try:
            with open(ckpt, "rb") as fh:
                data = pickle.load(fh)
        except Exception as err:  # noqa: BLE001 - any unreadable file is the same one line
            raise InputError(ckpt, "--resume", f"cannot read the checkpoint ({type(err).__name__}): the file is "
                             "corrupt or not a checkpoint; start again without --resume") from None
        if not isinstance(data, dict) or data.get("format") != CHECKPOINT_FORMAT:
            raise InputError(ckpt, "--resume", "not a checkpoint of this crashlab version (no study fingerprint); "
                             "start again without --resume")
        mine, theirs = self.fingerprint(), data.get("fingerprint", {})
        changed = [k for k in sorted(set(mine) | set(theirs)) if mine.get(k) != theirs.get(k)]
        if changed:
            raise InputError(ckpt, "--resume", f"the checkpoint was made from a different study ({', '.join(changed)} "
                             "changed); start again without --resume, or give another --out")
        if optimizer and optimizer != data["optimizer"]:
            raise InputError(ckpt, "--optimizer", f"the checkpoint was made with optimizer {data['optimizer']!r}, "
                             f"not {optimizer!r}")
        return data["algorithm"], data["optimizer"]

    def _checkpoint(self, ckpt: Path, algorithm, name: str):
        try:
            _atomic_pickle(ckpt, {"format": CHECKPOINT_FORMAT, "fingerprint": self.fingerprint(),
                                  "optimizer": name, "algorithm": algorithm})
        except (pickle.PicklingError, TypeError, AttributeError) as err:
            raise InputError(ckpt, "--out", f"the state of optimizer {name!r} cannot be saved for --resume "
                             f"({err}); run it without --out") from None
        except OSError as err:
            raise InputError(ckpt, "--out", err.strerror or str(err)) from None

    def run(self, optimizer: str | None = None, workers: int | None = None, scheduler: str | None = None,
            out_dir: str | Path | None = None, resume: bool = False, progress: bool = False,
            stop_after: int | None = None):
        """Search, polish, and (with out_dir) write the outputs. stop_after: stop after that many
        generations as a kill would (checkpoint written, no polish, no outputs; returns None): tests."""
        from .execution import WorkerStartError
        try:
            return self._run(optimizer, workers, scheduler, out_dir, resume, progress, stop_after)
        except WorkerStartError as err:
            raise InputError(self.path, "execution", str(err)) from None

    def _run(self, optimizer, workers, scheduler, out_dir, resume, progress, stop_after):
        from .execution import Executor
        t0 = time.perf_counter()
        ex = self.spec.execution
        if workers is not None and not 1 <= workers <= WORKERS_MAX:
            raise InputError(self.path, "--workers", f"must be in [1, {WORKERS_MAX}], got {workers}")
        backend = ex.backend
        if scheduler or ex.scheduler:
            backend = "dask"
        elif workers and backend == "serial":
            backend = "dask"
        out_dir = Path(out_dir) if out_dir else None
        ckpt = out_dir / "checkpoint.pkl" if out_dir else None
        if resume:
            if ckpt is None:
                raise InputError(self.path, "--resume", "no checkpoint to resume from (give --out DIR)")
            algorithm, name = self._resume(ckpt, optimizer)
            problem = algorithm.problem
        else:
            name, algorithm = self.make_algorithm(optimizer)
            problem = self.make_problem(constraints_as_penalty=not getattr(algorithm, "handles_constraints", True))
            algorithm.setup(problem, termination=("n_gen", self.spec.optimizer.generations),
                            seed=self.spec.optimizer.seed, verbose=False)
        if out_dir:
            try:
                out_dir.mkdir(parents=True, exist_ok=True)
            except OSError as err:
                raise InputError(out_dir, "--out", err.strerror or str(err)) from None
            if not resume:  # before any evaluation: an optimizer whose state cannot be saved is refused now
                self._checkpoint(ckpt, algorithm, name)
        bar = _progress(self.spec.optimizer.generations, progress)
        done = max(int(algorithm.n_iter or 1) - 1, 0) if algorithm.is_initialized else 0
        if bar is not None and done:
            bar.update(done)  # generations done before a resume
        with Executor(backend, workers or ex.workers, scheduler or ex.scheduler, ex.timeout_s) as executor:
            problem.executor = executor
            while algorithm.has_next():
                algorithm.next()
                if getattr(algorithm, "generator", None) is not None:
                    continue  # a loop-wise algorithm (MOEA/D) within a generation: no checkpoint there
                gen = int(algorithm.n_iter) - 1
                if ckpt is not None:
                    self._checkpoint(ckpt, algorithm, name)
                if bar is not None:
                    bar.set_postfix_str(_status(problem, self.spec.objective.hv_reference))
                    bar.update(gen - done)
                done = gen
                if stop_after is not None and gen >= stop_after and algorithm.has_next():
                    problem.executor = None
                    if bar is not None:
                        bar.close()
                    return None
            n_search = sum(len(x) for x in problem.archive["X"])
            budget = self.polish_budget()
            if budget:
                polish_archive(problem, self.spec.polish, self.make_repair(), budget)
                if bar is not None:
                    bar.set_postfix_str("polished: " + _status(problem, self.spec.objective.hv_reference))
            problem.executor = None
        if bar is not None:
            bar.close()
        info = {"optimizer": name, "generations": int(algorithm.n_gen or 1) - 1,
                "pop_size": int(getattr(algorithm, "pop_size", None) or self.spec.optimizer.pop_size),
                "search_evaluations": n_search, "polish_evaluations": sum(len(x) for x in problem.archive["X"])
                - n_search, "polish_budget": budget}
        if getattr(algorithm, "sigma_share", None) is not None:
            info["sigma_share"] = float(algorithm.sigma_share)
        repair = getattr(algorithm, "repair", None)
        if repair is not None and hasattr(repair, "repaired"):
            info["repaired"] = int(repair.repaired)
        arch = problem.archive_arrays()
        feasible = np.all(arch["G"] <= 0, axis=1) & arch["ok"]
        pareto = pareto_table(problem, arch)
        result = ReconstructionResult(pareto, int(len(arch["X"])), int((~arch["ok"]).sum()),
                                      float(feasible.mean()) if len(feasible) else 0.0,
                                      time.perf_counter() - t0, problem, info)
        if out_dir:
            write_outputs(self, result, arch, out_dir)
        return result


def spaced_starts(X, xl, xu, spacing: float = POLISH_SPACING):
    """The rows of X (best first) that lie at least `spacing` (normalised decision space) from every
    earlier pick, and their indices: one start per basin rather than several in the best one."""
    Z = (X - xl) / (xu - xl)
    picked: list[int] = []
    for k in range(len(Z)):
        if not picked or np.min(np.linalg.norm(Z[picked] - Z[k], axis=1)) >= spacing:
            picked.append(k)
    return X[picked], np.array(picked, dtype=int)


def polish_archive(problem: ReconstructionProblem, spec: PolishSection, repair=None, budget: int | None = None):
    """Least-squares polish (optimizers/polish.py) from the best feasible candidates so far, ranked
    by their worse objective and spaced apart, until the budget is spent; every polish evaluation
    enters the archive. With a repair, each point is repaired before it is evaluated: the back-off
    makes the residual continuous across the start-overlap boundary, where repaired candidates sit."""
    from crashlab.optimizers.polish import polish
    arch = problem.archive_arrays()
    feasible = np.flatnonzero(np.all(arch["G"] <= 0, axis=1) & arch["ok"])
    if len(feasible) == 0:
        return
    order = feasible[np.argsort(arch["F"][feasible].max(axis=1), kind="stable")]
    starts, picked = spaced_starts(arch["X"][order], problem.xl, problem.xu)

    def residuals(X):
        return problem.evaluate_residuals(X if repair is None else repair.apply(problem, X))

    budget = spec.evaluations if budget is None else budget
    polish(residuals, starts, problem.xl, problem.xu, budget, spec.step,
           start_residuals=problem.residuals(arch["rest"][order[picked]]))


def pareto_table(problem: ReconstructionProblem, arch: dict):
    """Non-dominated feasible solutions among every evaluated candidate, one row each, best (smallest sum
    of objectives) first: free variables, objectives f_<vehicle>, dheading_<vehicle> (simulated minus
    measured rest heading [deg], wrapped to -180..180; empty where no heading was measured: it is there
    whatever heading_weight, so a good position with a wrong heading shows), rest poses and the state at
    first contact (file units). Rows whose every free variable lies within DUPLICATE_TOL of its bound
    width of a better row's are the same solution and kept once."""
    import pandas as pd
    from pymoo.util.nds.non_dominated_sorting import NonDominatedSorting
    feasible = np.flatnonzero(np.all(arch["G"] <= 0, axis=1) & arch["ok"])
    if len(feasible) == 0:
        return pd.DataFrame()
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
        row.update({f"f_{n}": arch["F"][k, c] for c, n in enumerate(problem.evidence)})
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


def _status(problem, hv_ref):
    from pymoo.indicators.hv import HV
    G = problem.archive["G"][-1]
    feas = np.all(G <= 0, axis=1)
    allF = np.concatenate(problem.archive["F"])
    allfeas = np.all(np.concatenate(problem.archive["G"]) <= 0, axis=1)
    evals = len(allF)
    if allfeas.any():
        best = allF[allfeas].min(axis=0)
        hv = HV(ref_point=np.full(allF.shape[1], hv_ref))(allF[allfeas])
        best_s = " ".join(f"{b:.2f}" for b in best)
    else:
        hv, best_s = 0.0, "-"
    return f"evals {evals} feasible {feas.mean():.0%} best [{best_s}] m HV {hv:.2f}"


def _progress(total, enabled):
    if not enabled:
        return None
    from tqdm import tqdm
    return tqdm(total=total, unit="gen", dynamic_ncols=True)


def _atomic_pickle(path: Path, obj):
    tmp = path.with_suffix(path.suffix + ".tmp")
    with open(tmp, "wb") as fh:
        pickle.dump(obj, fh, protocol=pickle.HIGHEST_PROTOCOL)
    os.replace(tmp, path)  # atomic: a kill leaves the previous or the new checkpoint, never half of one


HEADING_WARN_DEG = 15.0  # deg: a rest heading this far off is plain on any site sketch or photo


def write_failures(problem: ReconstructionProblem, arch: dict, path: Path, n_search: int):
    """failures.csv: one row per failed evaluation: its index, phase (search/polish), free variables
    (file units) and the reason. Written (with its header) also when nothing failed."""
    import pandas as pd
    bad = np.flatnonzero(~arch["ok"]) if len(arch["X"]) else np.empty(0, int)
    table = pd.DataFrame({"evaluation": bad, "phase": np.where(bad < n_search, "search", "polish")})
    for c, f in enumerate(problem.free):
        table[f.label] = arch["X"][bad, c] if len(bad) else []
    table["reason"] = arch["reason"][bad] if len(bad) else []
    table.to_csv(path, index=False)


def write_outputs(study: Study, result: ReconstructionResult, arch: dict, out_dir: Path):
    """pareto.csv, failures.csv, objectives.png, top views of chosen solutions, summary.md. The tables
    come first; a figure that cannot be drawn is named in summary.md instead of ending the run."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .execution import _model
    from .plotting import top_view
    problem = result.problem
    info = result.algorithm_info
    result.pareto.to_csv(out_dir / "pareto.csv", index=False)
    write_failures(problem, arch, out_dir / "failures.csv", info["search_evaluations"])
    names = list(problem.evidence)
    notes = []
    if len(names) >= 2:
        try:
            fig, ax = plt.subplots(figsize=(6, 5))
            feas = np.all(arch["G"] <= 0, axis=1) & arch["ok"]
            F = arch["F"][feas]
            ax.scatter(F[:, 0], F[:, 1], s=6, color="0.6", label="dominated / evaluated")
            if len(result.pareto):
                ax.scatter(result.pareto[f"f_{names[0]}"], result.pareto[f"f_{names[1]}"], s=24, color="C3",
                           label="non-dominated")
            ax.set_xscale("log")
            ax.set_yscale("log")
            ax.set_xlabel(f"f_{names[0]} [m]")
            ax.set_ylabel(f"f_{names[1]} [m]")
            ax.legend()
            ax.grid(alpha=0.3, which="both")
            fig.tight_layout()
            fig.savefig(out_dir / "objectives.png", dpi=120)
        except Exception as err:  # noqa: BLE001 - the search's result is in the tables already
            notes.append(f"objectives.png could not be drawn: {type(err).__name__}: {err}")
        finally:
            plt.close("all")
    model = _model(problem.model, tuple(sorted(problem.model_options.items())))
    chosen = []
    if len(result.pareto):
        cols = [f.label for f in problem.free]
        for k in sorted({0, *[int(result.pareto[f"f_{n}"].idxmin()) for n in names]}):
            chosen.append((k, result.pareto.loc[k, cols].to_numpy(dtype=float)))
    figures = []
    for k, x in chosen[:3]:
        scene = problem.scene_for(x)
        try:
            top_view(scene, model.simulate(scene), out_dir / f"solution_{k}.png",
                     title=f"Pareto solution {k}", measured=problem.evidence)
            figures.append(f"solution_{k}.png")
        except Exception as err:  # noqa: BLE001
            notes.append(f"solution_{k}.png could not be drawn: {type(err).__name__}: {err}")
        finally:
            plt.close("all")
    hw = problem.heading_weight
    lines = [f"# Reconstruction: {study.spec.name or study.path.stem}", "",
             f"- study: `{study.path}`; model `{problem.model}`; optimizer `{info['optimizer']}`",
             f"- evaluations {result.evaluations} (search {info['search_evaluations']}, least-squares polish "
             f"{info['polish_evaluations']} of a budget of {info['polish_budget']}), failed {result.failed}, "
             f"feasible fraction {result.feasible_fraction:.1%}, wall time {result.wall_time_s:.1f} s"]
    if result.failed:
        counts = failure_counts(arch["reason"][~arch["ok"]])
        lines.append("- failed evaluations by reason (every one in failures.csv): " + "; ".join(
            f"{c} x {r}" for r, c in list(counts.items())[:5]) + ("; ..." if len(counts) > 5 else ""))
    for key in ("sigma_share", "repaired"):
        if key in info:
            lines.append(f"- {key}: {info[key]}")
    lines += ["", "Evidence (measured rest poses): " + "; ".join(
        f"{n} ({x:.2f}, {y:.2f}" + (f", {h:.1f} deg)" if h is not None else ", heading not measured)")
        for n, (x, y, h) in problem.evidence.items()), ""]
    if study.spec.evidence.twin:
        lines += ["Twin experiment: the evidence is the model's own run of the base scene, whose start is the "
                  "truth: " + ", ".join(f"{f.label} = {v:.3f}" for f, v in zip(problem.free, problem.base_values())),
                  ""]
    measured_h = [n for n, ev in problem.evidence.items() if ev[2] is not None]
    lines += [f"## Pareto set ({len(result.pareto)} solutions, sorted by the sum of objectives)", ""]
    if measured_h:
        lines += ["dheading_<vehicle>: simulated minus measured rest heading [deg], wrapped to -180..180; " +
                  (f"weighted {hw:g} m/deg in the objectives." if hw else
                   "**not part of the objectives** (heading_weight = 0): a small f_ does not mean the "
                   "headings match."), ""]
    if len(result.pareto):
        best = result.pareto.iloc[0]
        off = [f"{n} {best[f'dheading_{n}']:+.0f} deg" for n in measured_h
               if abs(best[f"dheading_{n}"]) > HEADING_WARN_DEG]
        if off:
            lines += [f"**Warning: the first solution's rest headings are off the measured ones: {', '.join(off)}.**",
                      ""]
        show = result.pareto[[f.label for f in problem.free] + [f"f_{n}" for n in names] +
                             [f"dheading_{n}" for n in measured_h]].head(15)
        lines.append(show.to_markdown(index=False, floatfmt=".3f"))
    else:
        lines.append("No feasible solution.")
    if figures:
        lines += ["", "Top views (start dotted, first contact dashed, rest solid, measured rest pose thick and "
                  "pale, heading arrows in each vehicle's colour): " + ", ".join(figures)]
    if notes:
        lines += [""] + [f"- {n}" for n in notes]
    (out_dir / "summary.md").write_text("\n".join(lines) + "\n")


# ---------------------------------------------------------------- loading and CLI
def load_study(path) -> Study:
    path = Path(path)
    data = read_toml(path, "study")
    try:
        spec = StudyFile.model_validate(data)
    except ValidationError as err:
        raise pydantic_error(path, err) from None
    if spec.model not in available_models():
        raise InputError(path, "model", str(UnknownPluginError("model", spec.model, available_models())))
    if spec.optimizer.name not in available_optimizers():
        raise InputError(path, "optimizer.name",
                         str(UnknownPluginError("optimizer", spec.optimizer.name, available_optimizers())))
    from .options import OptionError
    from .registry import get_model
    try:
        model = get_model(spec.model, **spec.model_options)
    except OptionError as err:
        raise InputError(path, f"model_options.{err.key}", err.problem) from None
    except (TypeError, ValueError) as err:
        raise InputError(path, "model_options", str(err)) from None
    scene_path = path.parent / spec.scene
    if not scene_path.is_file():
        raise InputError(path, "scene", f"scene file {spec.scene!r} not found")
    scene = load_scene(scene_path)
    names = scene.vehicle_names
    for k, f in enumerate(spec.free):
        if f.vehicle is not None and f.vehicle not in names:
            raise InputError(path, f"free.{k}.vehicle", f"no vehicle {f.vehicle!r} in the scene ({', '.join(names)})")
    if spec.evidence.twin:
        from .execution import outcome_reason
        out = model.simulate(scene)
        if not out.outcome_ok:
            raise InputError(path, "evidence.twin", f"the model's run of the base scene failed: {outcome_reason(out)}")
        moving = [f"{n} still moving at {ms_to_kmh(out.end_speed_si[i]):.0f} km/h"
                  for i, n in enumerate(names) if not out.at_rest_mask[i]]
        if moving:
            raise InputError(path, "evidence.twin", f"{', '.join(moving)} at the end of the base scene: an end pose "
                             "is no rest pose (lengthen the scene's duration)")
        evidence = {n: (out.rest_si[i, 0], out.rest_si[i, 1], math.degrees(out.rest_si[i, 2]))
                    for i, n in enumerate(names)}
    else:
        for n in spec.evidence.rest:
            if n not in names:
                raise InputError(path, f"evidence.rest.{n}", f"no vehicle {n!r} in the scene")
        evidence = {n: (p.x, p.y, p.heading) for n, p in spec.evidence.rest.items()}
    if not evidence:
        raise InputError(path, "evidence.rest", "no measured rest pose given")
    return Study(path, spec, scene, evidence)


def run_cli(args) -> int:
    study = load_study(args.study)
    if args.optimizer and args.optimizer not in available_optimizers():
        raise InputError(args.study, "--optimizer",
                         str(UnknownPluginError("optimizer", args.optimizer, available_optimizers())))
    res = study.run(optimizer=args.optimizer, workers=args.workers, scheduler=args.scheduler,
                    out_dir=args.out, resume=args.resume, progress=not (args.json or args.no_progress))
    if args.json:
        print(json.dumps(res.to_json_dict(), indent=2))
        return 0
    import pandas as pd
    with pd.option_context("display.float_format", "{:.3f}".format, "display.width", 200, "display.max_columns", 40):
        cols = [f.label for f in study.spec.free] + [f"f_{n}" for n in study.evidence]
        cols += [f"dheading_{n}" for n, ev in study.evidence.items() if ev[2] is not None]
        print(res.pareto[cols].to_string(index=False) if len(res.pareto) else "no feasible solution")
    print(f"evaluations {res.evaluations}, failed {res.failed}, feasible {res.feasible_fraction:.1%}, "
          f"{res.wall_time_s:.2f} s" + (f", outputs in {args.out}" if args.out else ""))
    return 0
