"""The example collision model: vehicles as translating rigid boxes.

Physics (each law chosen so the model is small and still honest; README.md of this folder explains them):

- A vehicle is its outline, a rectangle, that keeps its heading: it translates but never turns (as if its
  yaw inertia were infinite). A scene in which a vehicle starts turning (a yaw rate or a steer angle) is
  therefore not something this model can simulate: it answers with a failed Outcome saying so.
- Road: constant decelerations, the Coulomb friction of the tyres (docs/physics.md §2 in the crashlab
  repository states the same limits for the detailed tyre). Wheels locked (or braked, ABS-like): the full
  friction mu g against the velocity. Rolling: f_r g against the velocity along the vehicle, the rest of
  the friction circle, sqrt(mu^2 - f_r^2) g, against the sideways velocity. `locked_after_impact` rolls
  until the vehicle's first impact, then locks. Each step integrates these exactly (a velocity component
  reaches zero and stays there), so the road only ever takes energy.
- Impact: when two outlines overlap (found at the end of a step of length `dt`, separating-axis test) and
  approach along the contact normal (the axis of least overlap), a Newtonian impulse along that normal
  makes the normal relative velocity -e times what it was (e the scene's restitution). Equal and opposite
  impulses conserve momentum exactly; the energy dissipated, (1 - e^2) / 2 m* v_n^2 with
  m* = m1 m2 / (m1 + m2), is never negative. The contact plane is frictionless (the scene's impact
  friction is not used). A barrier is a box of infinite mass. The overlap found late by the step is
  removed by moving the two boxes apart along the normal, in proportion to their inverse masses (their
  common centre of mass stays where it is; no velocity changes, so no energy changes).

The one accuracy knob is the step `dt`: contacts are found up to one step late.
"""
from __future__ import annotations

import math
import time

import numpy as np

import crashlab
from crashlab.geometry import overlap_centroid
from crashlab.models.common.crush_structure import side_code
from crashlab.models.common.impact_rows import pair_rows, struck_compliance
from crashlab.options import ModelOptions, option
from crashlab.units import G

LOCKED_STATES = ("locked", "braked")  # wheel states that take the full friction against the velocity
FULL_SLIP = 0.01  # m/s: below this tangential relative velocity after the impulse an impact is "full"


class _Box:
    """One outline: centre, unit axes (along, across), half length and half width, inverse mass."""

    def __init__(self, centre, heading, half_length, half_width, inv_mass):
        self.centre = np.array(centre, dtype=float)
        self.axes = np.array([[math.cos(heading), math.sin(heading)], [-math.sin(heading), math.cos(heading)]])
        self.half = np.array([half_length, half_width])
        self.inv_mass = inv_mass

    def corners(self) -> np.ndarray:
        signs = np.array([[1, 1], [1, -1], [-1, -1], [-1, 1]])
        return self.centre + (signs * self.half) @ self.axes

    def struck_side(self, point) -> int:
        """The face a contact point strikes: 0 front, 1 rear, 2 left, 3 right (crashlab's rule, side_code)."""
        local = self.axes @ (np.asarray(point) - self.centre)
        return side_code(float(local[0]), float(local[1]), float(self.half[0]), float(self.half[1]))

    def support(self, direction) -> np.ndarray:
        """The point of the outline furthest along `direction` (the middle of a face when a face is)."""
        c = self.corners()
        p = c @ direction
        return c[p >= p.max() - 1e-9].mean(axis=0)


def _struck_sides(a: _Box, b: _Box, b_is_vehicle: bool) -> tuple[int, int]:
    """The sides of a and b an impact strikes, from the middle of their overlap (crashlab's rule; the support
    points' midpoint lies on the striking corner at an angle, on the diagonal between front and side)."""
    x, y, _ = overlap_centroid(a.corners()[::-1].copy(), b.corners()[::-1].copy())  # (counter-clockwise)
    return a.struck_side((x, y)), b.struck_side((x, y)) if b_is_vehicle else 0


def _separation(a: _Box, b: _Box):
    """(separation [m], unit normal from a to b): the largest gap over the four axes of the two boxes;
    negative when they overlap (then -separation is the depth along the axis of least overlap)."""
    axes = np.vstack([a.axes, b.axes])
    reach = np.abs(axes @ a.axes.T) @ a.half + np.abs(axes @ b.axes.T) @ b.half
    proj = axes @ (b.centre - a.centre)
    gaps = np.abs(proj) - reach
    k = int(np.argmax(gaps))
    return float(gaps[k]), axes[k] * (1.0 if proj[k] >= 0 else -1.0)


def _coulomb_step(v: float, decel: float, h: float) -> tuple[float, float]:
    """(distance, new velocity) of one velocity component under a constant deceleration against it over a
    step h, exactly: it reaches zero and stays there."""
    s = abs(v)
    if decel <= 0.0 or s == 0.0:
        return v * h, v
    if s <= decel * h:  # stops within the step
        return math.copysign(s * s / (2.0 * decel), v), 0.0
    return math.copysign((s - 0.5 * decel * h) * h, v), math.copysign(s - decel * h, v)


class ExampleModel(crashlab.CollisionModel):
    """Translating rigid boxes, constant-deceleration road, Newtonian restitution impulse (module docstring)."""

    name = "example"
    # False: the model does not realise driver actions or friction zones; crashlab refuses scenes that have
    # them (one line naming the key) instead of letting this model ignore them
    driver_inputs = False

    class Options(ModelOptions):
        dt: float = option(0.001, "time step; contacts are found at the end of a step", "s",
                           accuracy="smaller", gt=0, le=0.05)

    def simulate(self, scene):
        start = time.perf_counter()
        names = scene.vehicle_names
        for v in scene.vehicles:
            if v.yaw_rate != 0.0 or v.steer != 0.0:
                return crashlab.Outcome.failed(
                    names, f"model {self.name!r}: {v.name} starts with a yaw rate or a steer angle, and the "
                    "vehicles of this model cannot turn", model=self.name, wall_time_s=time.perf_counter() - start)
        vehicles = scene.vehicles
        nv = len(vehicles)
        mass = np.array([v.spec.mass for v in vehicles])
        mu, e = scene.road.friction, scene.impact.restitution
        # the box centre lies between the bumpers, off the CG by (cg_to_front - cg_to_rear) / 2 along the car
        offset = [(v.spec.cg_to_front - v.spec.cg_to_rear) / 2 for v in vehicles]
        boxes = [_Box((v.x + d * math.cos(v.heading), v.y + d * math.sin(v.heading)), v.heading,
                      v.spec.length / 2, v.spec.width / 2, 1.0 / v.spec.mass) for v, d in zip(vehicles, offset)]
        boxes += [_Box((b.x, b.y), b.heading, b.length / 2, b.width / 2, 0.0) for b in scene.barriers]
        vel = np.array([[v.speed * math.cos(v.heading), v.speed * math.sin(v.heading)] for v in vehicles])
        locked = [v.wheels in LOCKED_STATES for v in vehicles]
        lock_on_impact = [v.wheels == "locked_after_impact" for v in vehicles]
        f_r = [min(v.spec.rolling_resistance, mu) for v in vehicles]

        contact_si = np.full((nv, 4), np.nan)
        contact_time = math.nan
        episodes: dict = {}  # (i, j) -> the open contact episode of a pair (j >= nv: barrier j - nv)
        rows: list = []
        max_pen, steps, impulses = 0.0, 0, 0
        record = {name: {k: [] for k in ("t", "x", "y", "vx", "vy")} for name in names}

        def sample(t):
            for i, name in enumerate(names):
                cg = boxes[i].centre - offset[i] * boxes[i].axes[0]
                for k, val in zip(("t", "x", "y", "vx", "vy"), (t, cg[0], cg[1], vel[i, 0], vel[i, 1])):
                    record[name][k].append(float(val))

        t, dt = 0.0, self.options.dt
        sample(t)
        while t < scene.duration - 1e-12:
            h = min(dt, scene.duration - t)
            for i in range(nv):  # the road: exact constant-deceleration step
                if locked[i]:
                    speed = math.hypot(*vel[i])
                    dist, new = _coulomb_step(speed, mu * G, h)
                    if speed > 0.0:
                        boxes[i].centre += vel[i] / speed * dist
                        vel[i] *= new / speed
                else:
                    along, across = boxes[i].axes
                    du, u = _coulomb_step(float(vel[i] @ along), f_r[i] * G, h)
                    dw, w = _coulomb_step(float(vel[i] @ across), math.sqrt(mu * mu - f_r[i] ** 2) * G, h)
                    boxes[i].centre += du * along + dw * across
                    vel[i] = u * along + w * across
            steps += 1
            t = min(steps * dt, scene.duration)  # not a running sum: no round-off creeping into t
            for i in range(nv):  # contacts: every vehicle against every later vehicle and every barrier
                for j in range(i + 1, len(boxes)):
                    gap, n = _separation(boxes[i], boxes[j])
                    if gap >= 0.0:
                        episodes.pop((i, j), None)  # apart: the pair's contact episode, if any, is over
                        continue
                    max_pen = max(max_pen, -gap)
                    rel = (vel[j] if j < nv else np.zeros(2)) - vel[i]  # velocity of j relative to i
                    vn = float(rel @ n)
                    inv_sum = boxes[i].inv_mass + boxes[j].inv_mass
                    if vn < 0.0:  # approaching: the Newtonian impulse on j along n (on i the opposite)
                        impulses += 1
                        if math.isnan(contact_time):
                            contact_time = t
                        for q in (i, j):
                            if q < nv and math.isnan(contact_si[q, 0]):
                                cg = boxes[q].centre - offset[q] * boxes[q].axes[0]
                                contact_si[q] = (cg[0], cg[1], vehicles[q].heading, math.hypot(*vel[q]))
                        impulse = -(1.0 + e) * vn / inv_sum * n
                        dv_i = -impulse * boxes[i].inv_mass
                        dv_j = impulse * boxes[j].inv_mass
                        vel[i] += dv_i
                        if j < nv:
                            vel[j] += dv_j
                        energy = 0.5 * (1.0 - e * e) * vn * vn / inv_sum
                        ep = episodes.get((i, j))
                        if ep is None:  # a new contact episode: one impact-table row per vehicle
                            slip = rel - vn * n  # tangential relative velocity (a normal impulse keeps it)
                            point = 0.5 * (boxes[i].support(n) + boxes[j].support(-n))
                            ep = episodes[(i, j)] = {
                                "i": i, "j": j, "t": t, "t_end": t, "energy": 0.0, "dv": np.zeros((2, 2)),
                                "impulse": np.zeros(2), "point": point,
                                "sides": _struck_sides(boxes[i], boxes[j], j < nv),
                                "plane": math.atan2(n[1], n[0]) + math.pi / 2,
                                "kind": "full" if math.hypot(*slip) < FULL_SLIP else "sliding"}
                            rows.append(ep)
                        ep["t_end"], ep["energy"] = t, ep["energy"] + energy
                        ep["dv"] += (dv_i, dv_j)
                        ep["impulse"] += impulse
                        for q in (i, j):
                            if q < nv and lock_on_impact[q]:
                                locked[q] = True
                    # the overlap the step found late: move the boxes apart along n, centre of mass kept
                    boxes[i].centre -= n * (-gap) * boxes[i].inv_mass / inv_sum
                    boxes[j].centre += n * (-gap) * boxes[j].inv_mass / inv_sum
            sample(t)
            if scene.stop_at_rest and not vel.any():
                break

        trajectories = {}
        for i, name in enumerate(names):
            tr = {k: np.asarray(vals) for k, vals in record[name].items()}
            tr["heading"] = np.full(len(tr["t"]), vehicles[i].heading)
            tr["yaw_rate"] = np.zeros(len(tr["t"]))
            trajectories[name] = tr
        rest = np.array([[trajectories[n]["x"][-1], trajectories[n]["y"][-1], v.heading]
                         for n, v in zip(names, vehicles)])
        final = np.column_stack([vel, np.zeros(nv)])
        headings = [v.heading for v in vehicles]

        impact_rows = []  # one row per vehicle per contact episode (a barrier has no row)
        compliance = struck_compliance(v.spec for v in vehicles)  # shares each impact's energy by the struck sides
        for ep in rows:
            i, j = ep["i"], ep["j"]
            dv = [(*ep["dv"][0], 0.0), (*ep["dv"][1], 0.0)]  # (dvx, dvy, d_yaw_rate): these boxes never turn
            push = [-ep["impulse"], ep["impulse"]]
            impact_rows += pair_rows(names, mass, i, j, ep["t"], ep["energy"], dv, push,
                                     [headings[i], headings[j] if j < nv else 0.0], ep["point"], ep["plane"],
                                     ep["kind"], ep["sides"], compliance, t_end=ep["t_end"])

        diagnostics = {"steps": steps, "rejected_steps": 0, "episodes": len(rows), "t_end": t,
                       "max_penetration": max_pen, "impulses": impulses}
        return crashlab.Outcome(names, rest, final, contact_si, contact_time, trajectories, impact_rows,
                                diagnostics, model=self.name, wall_time_s=time.perf_counter() - start,
                                impact_energy=[ep["energy"] for ep in rows])
