"""Populations: many variants of one scene that differ in a few numbers, and their results as arrays.

A search, a posterior and a Monte Carlo evaluate thousands of variants of ONE scene. `CollisionModel.
simulate_population(scene, fields, values)` simulates them and returns a `Population`: one row per variant,
numpy arrays only, no Outcome per variant (docs/architecture.md). `fields` are dotted paths as crashlab.fields
names them, `values` an (N, k) array in file units (km/h, deg, m, s, kg).

Columns (SI; nv vehicles in scene order):
  ok (N,) bool, reason (N,) str ("" when ok): the run finished and passed the physics guard
  rest (N, nv, 3) x, y, heading [m, rad] at the end; final (N, nv, 3) vx, vy, yaw rate at the end
  rest_speed (N, nv) [m/s], at_rest (N, nv) bool (crashlab.outcome.REST_SPEED, REST_YAW_RATE)
  contact (N, nv, 4) x, y, heading, speed at first contact; n_impacts (N,) impacts (contact episodes)
  mass (N, nv) [kg]; delta_v (N, nv) |sum of the vehicle's impact-row velocity changes| [m/s];
  first_delta_v (N, nv) the velocity change of its first impact [m/s] (what an event data recorder reports)
  crush_energy (N, nv, 6) the vehicle's share of the dissipated energy summed over its impacts [J], per face it
  was struck on (front, rear, left, right, and a tilted vehicle's roof, underbody: crashlab.structure.IMPACT_FACES;
  0 where none struck it; ees: the EES of
  the sum, docs/physics.md §21); first_impact_t (N, nv) [s], first_impact_point (N, nv, 2) [m]
  of the vehicle's first impact (NaN without one); energy_start, energy_end (N,) planar kinetic energy [J];
  energy_impacts (N,) dissipated by all impacts, lowest_impact_energy (N,) of the impact that dissipated least
  (the guard: below zero an impact created energy)
  scores (N, k) a scorer's numbers (crashlab.execution; k = 0 without one)
  warnings (N,) str the model's warnings of a run that did not fail, one a line ("" none): a law used outside its
  assumptions (restitution = "speed" held at its end value, docs/physics.md §13b; a slip that reverses, §3), no
  contact (the Outcome's warnings; a failed run's are its reason)
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from .structure import IMPACT_FACES

SIDE_INDEX = {face: k for k, face in enumerate(IMPACT_FACES)}
ARRAYS = ("ok", "reason", "rest", "final", "rest_speed", "at_rest", "contact", "n_impacts", "mass", "delta_v",
          "first_delta_v", "crush_energy", "first_impact_t", "first_impact_point", "energy_start", "energy_end",
          "energy_impacts", "lowest_impact_energy", "scores", "warnings")


@dataclasses.dataclass(frozen=True)
class Variants:
    """N variants of one scene: `fields` (dotted paths or crashlab.fields.Field) set to the rows of `values`
    ((N, k), file units). What a population is made of, and the unit of work an executor sends to its workers
    (one scene and a block of rows: `variants[a:b]`); `invalid` as CollisionModel.simulate_population's."""
    scene: object
    fields: tuple
    values: np.ndarray
    invalid: str = "fail"

    def __len__(self) -> int:
        return len(self.values)

    def __getitem__(self, rows: slice) -> Variants:
        return dataclasses.replace(self, values=self.values[rows])

    def scenes(self) -> list:
        """A Scene per row (crashlab.fields.setter, unchecked)."""
        from .fields import setter
        build = setter(self.scene, self.fields, check=False)
        return [build(row) for row in self.values]

    def simulate(self, model) -> Population:
        return model.simulate_population(self.scene, self.fields, self.values, invalid=self.invalid)


@dataclasses.dataclass
class Population:
    """Results of N variants of a scene with nv vehicles (module docstring); `names` the vehicles'."""
    names: tuple
    ok: np.ndarray
    reason: np.ndarray
    rest: np.ndarray
    final: np.ndarray
    rest_speed: np.ndarray
    at_rest: np.ndarray
    contact: np.ndarray
    n_impacts: np.ndarray
    mass: np.ndarray
    delta_v: np.ndarray
    first_delta_v: np.ndarray
    crush_energy: np.ndarray
    first_impact_t: np.ndarray
    first_impact_point: np.ndarray
    energy_start: np.ndarray
    energy_end: np.ndarray
    energy_impacts: np.ndarray
    lowest_impact_energy: np.ndarray
    scores: np.ndarray
    warnings: np.ndarray
    # what it was made of and by which model (CollisionModel.simulate_population), for `outcome`
    variants: Variants | None = dataclasses.field(default=None, repr=False, compare=False)
    model: object = dataclasses.field(default=None, repr=False, compare=False)

    @classmethod
    def empty(cls, n: int, names, reason: str = "not evaluated", k: int = 0) -> Population:
        """n failed rows (NaN numbers, the reason given)."""
        nv = len(names)
        nan = np.full
        return cls(tuple(names), np.zeros(n, bool), np.array([reason] * n, dtype=object),
                   nan((n, nv, 3), np.nan), nan((n, nv, 3), np.nan), nan((n, nv), np.nan), np.zeros((n, nv), bool),
                   nan((n, nv, 4), np.nan), np.zeros(n, int), nan((n, nv), np.nan), nan((n, nv), np.nan),
                   nan((n, nv), np.nan), nan((n, nv, len(IMPACT_FACES)), np.nan), nan((n, nv), np.nan),
                   nan((n, nv, 2), np.nan),
                   nan(n, np.nan), nan(n, np.nan), nan(n, np.nan), nan(n, np.nan), nan((n, k), np.nan),
                   np.array([""] * n, dtype=object))

    def __len__(self) -> int:
        return len(self.ok)

    @property
    def ees(self) -> np.ndarray:
        """(N, nv) energy-equivalent speed of each vehicle's crush energy (all sides) at its own mass [m/s]
        (sqrt(2 E / m), docs/physics.md §21; 0 without an impact)."""
        return np.sqrt(2.0 * self.crush_energy.sum(2) / self.mass)

    # -------------------------------------------------------------- assembling
    def put(self, start: int, part: Population) -> None:
        """Rows start.. of this population from `part` (a block evaluated elsewhere)."""
        for name in ARRAYS:
            getattr(self, name)[start:start + len(part)] = getattr(part, name)

    def fail(self, idx, reason: str) -> None:
        self.ok[idx] = False
        self.reason[idx] = reason

    @classmethod
    def concat(cls, parts: list[Population]) -> Population:
        """The rows of several populations of one scene, in order."""
        return dataclasses.replace(parts[0], **{name: np.concatenate([getattr(p, name) for p in parts])
                                                for name in ARRAYS}, variants=None, model=None)

    # -------------------------------------------------------------- from Outcomes
    @classmethod
    def of_outcomes(cls, outcomes, names, masses=None, scorer=None) -> Population:
        """The population of Outcomes (or exceptions in their place; the base class's route over
        simulate_batch, and any model's): an exception, None or a failed Outcome fails its row with the
        reason; a non-finite rest pose fails. masses (N, nv) [kg] the variants' masses (None: NaN, left to the
        caller: CollisionModel.simulate_population's wrapper fills them from the rows). With a scorer
        (crashlab.execution), its numbers of the outcomes."""
        n, nv = len(outcomes), len(names)
        k = 0 if scorer is None else int(scorer.n_residuals)
        pop = cls.empty(n, names, "", k)
        if masses is not None:
            pop.mass[:] = masses
        for r, o in enumerate(outcomes):
            if isinstance(o, BaseException):
                pop.reason[r] = exception_reason(o)
                continue
            if o is None:
                pop.reason[r] = "the model returned no outcome"
                continue
            diag = getattr(o, "diagnostics", None)  # (an outcome of a duck-typed model may lack them)
            if diag is not None:
                pop.energy_start[r], pop.energy_end[r] = _number(diag.energy_start), _number(diag.energy_end)
            if not getattr(o, "outcome_ok", False):
                pop.reason[r] = outcome_reason(o)
                continue
            rest = np.asarray(o.rest_si, float)
            if rest.shape != (nv, 3) or not np.all(np.isfinite(rest)):
                pop.reason[r] = "non-finite rest pose"
                continue
            rows = o.impact_rows
            unnamed = sorted({str(row.get("vehicle")) for row in rows if row.get("side") not in SIDE_INDEX})
            if unnamed:  # (its energy could not be booked to the side damage evidence compares)
                pop.reason[r] = (f"the model's impact rows of {', '.join(unnamed)} name no struck face (front, rear, "
                                 "left, right, roof or underbody; crashlab.models.common.impact_rows.pair_rows "
                                 "builds them)")
                continue
            pop.ok[r] = True
            pop.warnings[r] = "\n".join(str(w) for w in getattr(o, "warnings", ()) or ())
            pop.rest[r] = rest
            pop.final[r] = o.final_si
            pop.contact[r] = o.contact_si
            pop.rest_speed[r] = o.end_speed_si
            # an Outcome without velocities: nothing says it moves
            pop.at_rest[r] = o.at_rest_mask if np.all(np.isfinite(o.final_si)) else True
            pop.n_impacts[r] = diag["episodes"] if diag is not None and "episodes" in diag else len(rows)
            e = o.impact_energy
            pop.energy_impacts[r] = math.fsum(e.tolist())
            pop.lowest_impact_energy[r] = float(e.min()) if len(e) else np.nan
            _impact_columns(pop, r, names, rows)
        if scorer is not None:
            pop.score(k, lambda: scorer.residuals(outcomes))
        return pop

    def score(self, k: int, residuals) -> None:
        """scores (N, k) from `residuals()`, a scorer's numbers of these rows (crashlab.execution); a scorer
        that raises leaves them NaN and fails every row with its reason."""
        self.scores = np.full((len(self), k), np.nan)
        try:
            self.scores[:] = residuals()
        except Exception as err:  # noqa: BLE001 - the block is unscored: failed, with the reason
            self.fail(slice(None), one_line(f"scoring the outcome raised {type(err).__name__}: {err}"))

    # -------------------------------------------------------------- reading
    def to_frame(self):
        """A pandas DataFrame, one row per variant: the values of the fields (file units, when the source is
        known: `variants`), ok and reason, and per vehicle V.x, V.y [m], V.heading [deg], V.rest_speed, V.delta_v,
        V.first_delta_v, V.ees [km/h], V.at_rest, V.first_impact_t [s]; the energies [J]."""
        import pandas as pd
        cols = {}
        if self.variants is not None:
            for c, f in enumerate(self.variants.fields):
                cols[getattr(f, "path", f)] = self.variants.values[:, c]
        cols["ok"], cols["reason"], cols["n_impacts"] = self.ok, self.reason, self.n_impacts
        ees = self.ees
        for i, name in enumerate(self.names):
            cols[f"{name}.x"], cols[f"{name}.y"] = self.rest[:, i, 0], self.rest[:, i, 1]
            cols[f"{name}.heading"] = np.degrees(self.rest[:, i, 2])
            for key, a in (("rest_speed", self.rest_speed), ("delta_v", self.delta_v),
                           ("first_delta_v", self.first_delta_v), ("ees", ees)):
                cols[f"{name}.{key}"] = a[:, i] * 3.6
            cols[f"{name}.at_rest"] = self.at_rest[:, i]
            cols[f"{name}.first_impact_t"] = self.first_impact_t[:, i]
        for key in ("energy_start", "energy_end", "energy_impacts"):
            cols[key] = getattr(self, key)
        return pd.DataFrame(cols)

    def outcome(self, i: int):
        """The full Outcome of variant i (trajectories, impact rows, warnings), simulated again with the model
        that made the population (for reports)."""
        if self.variants is None or self.model is None:
            raise ValueError("this population does not know its scene and model (a part of one)")
        return self.model.simulate(self.variants[i:i + 1].scenes()[0])


def _number(x) -> float:
    return math.nan if x is None else float(x)


def one_line(text: str, limit: int = 300) -> str:
    """A reason as one line of at most `limit` characters."""
    text = " ".join(str(text).split())
    return text if len(text) <= limit else text[:limit - 3] + "..."


def outcome_reason(o) -> str:
    """Why an Outcome with outcome_ok False failed: the physics guard's findings first, else its warnings."""
    warnings = [str(w) for w in getattr(o, "warnings", ()) or ()]
    guard = [w for w in warnings if w.startswith("physics guard")]
    return one_line("; ".join(guard or warnings) or "the model reported a failed run (no reason given)")


def exception_reason(err: BaseException) -> str:
    return one_line(f"model raised {type(err).__name__}: {err}")


def _impact_columns(pop: Population, r: int, names, rows) -> None:
    """Row r's per-vehicle impact columns from an Outcome's impact rows (SI): delta_v |sum dv|, the first
    impact's, crush energy summed per struck side, first impact time and point (NaN where a model's rows lack a
    column; every row names its side: of_outcomes fails a run whose rows do not)."""
    index = {n: i for i, n in enumerate(names)}
    dv = np.zeros((len(names), 2))
    pop.crush_energy[r] = 0.0
    pop.first_delta_v[r] = 0.0
    for row in sorted(rows, key=lambda x: x["t"]):
        i = index.get(row["vehicle"])
        if i is None:
            continue
        def get(key, row=row):
            return row.get(key, math.nan)
        dv[i] += (get("dvx"), get("dvy"))
        pop.crush_energy[r, i, SIDE_INDEX[row["side"]]] += max(row.get("crush_energy", 0.0), 0.0)
        if not math.isfinite(pop.first_impact_t[r, i]):
            pop.first_impact_t[r, i] = row["t"]
            pop.first_impact_point[r, i] = (get("point_x"), get("point_y"))
            pop.first_delta_v[r, i] = math.hypot(get("dvx"), get("dvy"))
    pop.delta_v[r] = np.hypot(dv[:, 0], dv[:, 1])
