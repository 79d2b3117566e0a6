"""Evidence with its uncertainty, its normalised residuals and the Gaussian log-likelihood of a candidate
(its items are read from a study file by crashlab.reconstruction.evidence, where these names are imported too).

The contract (docs/physics.md, "Evidence and likelihood"; the posterior builds on it):

    es = study.evidence_set                      # an EvidenceSet: items, each with its sigmas
    R = es.residuals(outcomes)                   # (n, m): every residual component divided by its sigma
    L = es.log_likelihood(outcomes)              # (n,): -0.5 * sum(R**2, axis=1); -inf where R has a NaN
    executor.evaluate(model, options, scenes, scorer=es).scores  # R, each Outcome scored in the worker that
                                                 # simulated it (model.simulate where marks need a CG path)

Residual components (simulated minus measured, each divided by its sigma; file units km/h, deg, m):
  rest.<V>       (x - x*) / sigma_xy, (y - y*) / sigma_xy; with a heading: wrap(psi - psi*) / sigma_heading
                 [deg, wrapped to (-180, 180]]: the rest pose (Outcome.rest_si);
  impact         (px - x*) / sigma, (py - y*) / sigma: the point of the first impact row (Outcome.impact_rows,
                 point_x, point_y; the row with the smallest t); joint: counts in every vehicle's objective,
                 once in the likelihood;
  marks.<k>      d_p / sigma for every point p of the mark: d_p >= 0 the distance of p from the vehicle's
                 CG path (the polyline of Outcome.trajectories, recorded by `model.simulate`; the impulse
                 model's `simulate_batch` records none);
  edr.<V>        (v_c - v*) / sigma_speed with v_c the speed at first contact (Outcome.contact_si[:, 3]);
                 (|dv| - dv*) / sigma_delta_v with dv the sum of the vehicle's impact-row velocity changes
                 (dvx, dvy) [km/h]; a vehicle in no impact row has dv = 0;
  damage.<V>     (EES_sim - EES_damage) / sigma [km/h]: EES_damage and its sigma from the measured crush profile
                 (crashlab.damage.damage_ees, CRASH3, docs/physics.md §28); EES_sim = sqrt(2 sum_k E_k / m)
                 over the vehicle's impact rows that struck the damaged side (their crush_energy E_k, the
                 vehicle's share of each impact's dissipated energy, §21: energies add), m the vehicle's mass
                 in the study's scene. Expressing the
                 simulated energy at that mass makes the residual exactly the one at the candidate's own mass
                 when the mass is uncertain (both EES and sigma scale as 1/sqrt(m)). No impact of the vehicle
                 on that side: it cannot be scored (the damage says it was struck there). A profile without
                 residual crush (its mean depth within sigma_crush of 0) bounds EES_damage from above
                 (crashlab.damage.ees_is_upper_bound): the residual is max(0, EES_sim - EES_damage) / sigma.
A candidate that cannot be scored (Outcome not ok, None or an exception, no impact where the point of impact,
an EDR speed or a vehicle's damage is evidence, no CG path where marks are) has NaN residuals and log-likelihood -inf.

The log-likelihood is that of independent Gaussian measurement errors, up to the additive constant
-sum(log sigma) - m/2 log(2 pi), the same for every candidate (Davis, Law, Probability and Risk 2003):
a posterior needs only differences. A mark's residual is a distance (>= 0), so its term is a half-normal
of the distance, a standard choice for a point near a curve.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from crashlab.population import SIDE_INDEX, Population
from crashlab.structure import STRUCK_FACES
from crashlab.units import ms_to_kmh, unit_in, value_in, wrap_deg

# units of the residual components (file units), for the tables that list the evidence
UNITS = {"x": "m", "y": "m", "heading": "deg", "speed_at_impact": "km/h", "delta_v": "km/h", "ees": "km/h"}


@dataclass(frozen=True)
class EvidenceItem:
    """One piece of evidence. kind: "rest", "impact", "marks", "edr", "damage"; label: "rest.V1", "impact",
    "marks.0", "edr.V1", "damage.V1"; vehicles: whose objective it enters (the impact: every vehicle);
    components: the names of its residual components (e.g. ("x", "y", "heading")); values / sigmas: measured
    values and their standard deviations, per component, file units (m, deg, km/h); points: (p, 2) a mark's
    points [m]; mass: damage, the vehicle's mass [kg] at which the simulated crush energy is an EES; side:
    damage, the side it was measured on (front, rear, left, right), whose simulated crush energy is compared;
    detail: damage, what the value was computed from (for summary.md)."""
    kind: str
    label: str
    vehicles: tuple[str, ...]
    components: tuple[str, ...]
    values: tuple[float, ...]
    sigmas: tuple[float, ...]
    points: np.ndarray | None = field(default=None, compare=False)
    mass: float = math.nan
    side: str = ""

    def __post_init__(self):
        if self.kind == "damage" and self.side not in STRUCK_FACES:
            raise ValueError(f"{self.label}: damage evidence needs the side it was measured on (front, rear, "
                             f"left or right), got {self.side!r}")
    detail: str = field(default="", compare=False)
    warnings: tuple[str, ...] = field(default=(), compare=False)  # damage: the CRASH3 report's (crashlab.damage)
    upper_bound: bool = False  # damage without residual crush: its value bounds the simulated one from above


def polyline_distance(points: np.ndarray, path: np.ndarray) -> np.ndarray:
    """(p,) distance of each point (p, 2) from the polyline path (k, 2) [m]; NaN for an empty path."""
    points = np.asarray(points, float)
    path = np.asarray(path, float)
    if len(path) == 0 or not np.all(np.isfinite(path)):
        return np.full(len(points), np.nan)
    if len(path) == 1:
        return np.hypot(*(points - path[0]).T)
    a, b = path[:-1], path[1:]  # (k-1, 2) segments
    ab = b - a
    len2 = np.einsum("ij,ij->i", ab, ab)
    ap = points[:, None, :] - a[None, :, :]  # (p, k-1, 2)
    t = np.clip(np.einsum("pki,ki->pk", ap, ab) / np.where(len2 > 0, len2, 1.0), 0.0, 1.0)
    near = a[None] + t[..., None] * ab[None]
    return np.min(np.hypot(*(points[:, None, :] - near).transpose(2, 0, 1)), axis=1)


def _one(outcome) -> Population:
    return Population.of_outcomes([outcome], outcome.names)


def first_impact_point(outcome) -> tuple[float, float]:
    """(x, y) [m] of the first impact row (smallest t), NaN without one."""
    pop = _one(outcome)
    t = np.where(np.isfinite(pop.first_impact_t[0]), pop.first_impact_t[0], np.inf)
    return tuple(float(c) for c in pop.first_impact_point[0, t.argmin()])


def delta_v(outcome, name: str) -> float:
    """|sum of the vehicle's impact-row velocity changes| [m/s]; 0 when it is in no row."""
    return float(_one(outcome).delta_v[0, outcome.names.index(name)])


def crush_ees(outcome, name: str, mass: float, side: str) -> float:
    """m/s, the EES at `mass` [kg] of the vehicle's crush energy summed over its impact rows that struck `side`
    (front, rear, left or right; energies add, crashlab.damage.combined_ees); NaN when no impact struck it there."""
    return float(side_ees(_one(outcome).crush_energy[0, outcome.names.index(name), SIDE_INDEX[side]], mass))


def side_ees(energy, mass):
    """m/s, the EES sqrt(2 E / m) of the crush energy booked to one struck side; NaN where none was (E = 0)."""
    return np.sqrt(2.0 * np.where(energy > 0.0, energy, np.nan) / mass)


def cg_path(outcome, name: str) -> np.ndarray:
    """(k, 2) the vehicle's recorded CG path [m] (empty when the run recorded none)."""
    tr = (outcome.trajectories or {}).get(name)
    if not tr or len(tr.get("x", ())) == 0:
        return np.empty((0, 2))
    return np.column_stack([tr["x"], tr["y"]])


class EvidenceSet:
    """The study's evidence items over the scene's vehicles (names, in scene order)."""

    def __init__(self, names, items: list[EvidenceItem]):
        self.names = list(names)
        self.items = list(items)
        self.labels = [f"{it.label}.{c}" for it in self.items for c in it.components]
        # objective vehicles: every vehicle some item concerns, in scene order
        self.objective_names = [n for n in self.names if any(n in it.vehicles for it in self.items)]

    @property
    def needs_trajectory(self) -> bool:
        return any(it.kind == "marks" for it in self.items)

    @property
    def n_residuals(self) -> int:
        return len(self.labels)

    # ---------------------------------------------------------------- residuals
    def _simulated(self, it: EvidenceItem, pop) -> np.ndarray:
        """(n, components) the simulated counterparts of an item's components (file units) from a Population
        (crashlab.population), NaN where undefined; marks are read from Outcomes (`_mark_distances`)."""
        if it.kind == "impact":
            t = np.where(np.isfinite(pop.first_impact_t), pop.first_impact_t, np.inf)
            first = t.argmin(1)  # the vehicle in the earliest impact row: its point is the impact's
            return pop.first_impact_point[np.arange(len(pop)), first]
        i = self.names.index(it.vehicles[0])
        if it.kind == "rest":
            return np.column_stack([pop.rest[:, i, 0], pop.rest[:, i, 1], np.degrees(pop.rest[:, i, 2])])[
                :, :len(it.components)]
        if it.kind == "damage":  # the crush energy of the damaged side as an EES at the study's mass; NaN where
            # no impact struck that side (docs/physics.md §21, §28)
            return ms_to_kmh(side_ees(pop.crush_energy[:, i, SIDE_INDEX[it.side]], it.mass))[:, None]
        sim = {"speed_at_impact": lambda: ms_to_kmh(pop.contact[:, i, 3]),  # NaN without contact
               "delta_v": lambda: ms_to_kmh(pop.delta_v[:, i])}
        return np.column_stack([sim[c]() for c in it.components])

    @staticmethod
    def _mark_distances(it: EvidenceItem, outcomes, ok) -> np.ndarray:
        out = np.full((len(outcomes), len(it.points)), np.nan)
        for k in np.flatnonzero(ok):
            out[k] = polyline_distance(it.points, cg_path(outcomes[k], it.vehicles[0]))
        return out

    def residuals(self, outcomes) -> np.ndarray:
        """(n, m) normalised residuals (simulated - measured) / sigma of a batch of Outcomes, columns as
        `labels`; a row of NaN for a candidate that cannot be scored (module docstring)."""
        pop = Population.of_outcomes(outcomes, self.names)
        return self._residuals(pop, outcomes)

    def population_residuals(self, pop) -> np.ndarray:
        """`residuals` of a Population (crashlab.population: the arrays of many variants); marks need the CG
        paths of Outcomes, so a study with marks is scored by `residuals`."""
        return self._residuals(pop, None)

    def _residuals(self, pop, outcomes) -> np.ndarray:
        parts = []
        for it in self.items:
            if it.kind == "marks":  # the residual is the distance itself
                sim = self._mark_distances(it, outcomes, pop.ok) if outcomes is not None \
                    else np.full((len(pop), len(it.points)), np.nan)
                parts.append(sim / np.asarray(it.sigmas))
                continue
            diff = self._simulated(it, pop) - np.asarray(it.values)
            if it.kind == "rest" and len(it.components) == 3:
                diff[:, 2] = wrap_deg(diff[:, 2])
            if it.upper_bound:  # only the excess over a bound is a misfit (NaN stays NaN)
                diff = np.maximum(diff, 0.0)
            parts.append(diff / np.asarray(it.sigmas))
        R = np.concatenate(parts, axis=1) if parts else np.empty((len(pop), 0))
        R[~pop.ok | ~np.all(np.isfinite(R), axis=1)] = np.nan
        return R

    def log_likelihood(self, outcomes) -> np.ndarray:
        """(n,) Gaussian log-likelihood -0.5 * sum(R**2) of a batch of Outcomes (up to a constant, module
        docstring); -inf for a candidate that cannot be scored."""
        return log_likelihood_of(self.residuals(outcomes))

    def unstruck_damage(self, pop) -> list[tuple[EvidenceItem, list[str]]]:
        """Each damage item that no run of a Population (crashlab.population) can score, as no run that did not
        fail struck its vehicle on the damaged side (a crush energy there, docs/physics.md §28; `_simulated` is NaN
        then), with the sides those runs did strike."""
        out = []
        for it in self.items:
            if it.kind != "damage":
                continue
            energy = pop.crush_energy[pop.ok, self.names.index(it.vehicles[0])]
            if not (energy[:, SIDE_INDEX[it.side]] > 0).any():
                out.append((it, [s for s, k in SIDE_INDEX.items() if (energy[:, k] > 0).any()]))
        return out

    # ---------------------------------------------------------------- per item, per vehicle
    def item_slices(self) -> list[slice]:
        out, c = [], 0
        for it in self.items:
            out.append(slice(c, c + len(it.components)))
            c += len(it.components)
        return out

    def item_misfits(self, R: np.ndarray) -> np.ndarray:
        """(n, n_items) sqrt(sum (residual / sigma)^2) of each item's components."""
        R = np.atleast_2d(R)
        return np.column_stack([np.sqrt(np.sum(R[:, s] ** 2, axis=1)) for s in self.item_slices()])

    def objectives(self, R: np.ndarray) -> np.ndarray:
        """(n, len(objective_names)) per vehicle the normalised misfit sqrt(sum (residual / sigma)^2) over
        the items that concern it (the point of impact in every vehicle's)."""
        R = np.atleast_2d(R)
        cols = []
        for n in self.objective_names:
            use = np.concatenate([np.arange(s.start, s.stop) for it, s in zip(self.items, self.item_slices())
                                  if n in it.vehicles])
            cols.append(np.sqrt(np.sum(R[:, use] ** 2, axis=1)))
        return np.column_stack(cols)

    def describe(self, system: str = "si") -> list[str]:
        """One line per item, for summary.md, its values and sigmas in `system`'s units (crashlab.units: "us"
        gives ft and mph). A damage item's detail (the CRASH3 computation) is said in the SI units it was
        computed in, each number with its unit."""
        lines = []
        m = unit_in("m", system)
        for it in self.items:
            if it.kind == "marks":
                pts = ", ".join(f"({value_in(x, 'm', system):.2f}, {value_in(y, 'm', system):.2f})"
                                for x, y in it.points)
                lines.append(f"{it.label}: {it.vehicles[0]}'s CG path within {value_in(it.sigmas[0], 'm', system):g}"
                             f" {m} of {pts} {m}")
                continue
            detail = it.detail and (f"computed in SI: {it.detail}" if system == "us" else it.detail)
            rel = "<=" if it.upper_bound else "="  # (an upper bound is scored one-sided: its excess only)
            lines.append(f"{it.label}: " + ", ".join(f"{c} {rel} {value_in(v, UNITS[c], system):.2f} ± "
                                                      f"{value_in(s, UNITS[c], system):.3g} {unit_in(UNITS[c], system)}"
                                                      for c, v, s in zip(it.components, it.values, it.sigmas))
                         + (f" ({detail})" if detail else ""))
        return lines


def log_likelihood_of(R: np.ndarray) -> np.ndarray:
    """(n,) -0.5 * sum(R**2, axis=1) of normalised residuals R (n, m); -inf where a row has a NaN."""
    R = np.atleast_2d(R)
    L = -0.5 * np.sum(R ** 2, axis=1)
    L[~np.all(np.isfinite(R), axis=1)] = -np.inf
    return L
