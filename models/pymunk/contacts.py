"""The contacts of a pymunk run (docs/physics.md §18): Chipmunk's collision callbacks open a contact episode
per pair at `begin`, set the pair's restitution and friction on the arbiter every pre-solve, and each step's
contact velocity jumps and the kinetic energy the contact impulses removed are booked to the episodes in contact.
An episode lasts until the pair is SEPARATION apart (a re-touch before continues it) and its contact later than
PUSH_TIME after its start is its push, as in every model (crashlab.outcome; docs/physics.md §15, §18)."""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from crashlab.geometry import overlap_centroid, penetration
from crashlab.models.common.planar_vehicle import struck_side
from crashlab.outcome import PUSH, PUSH_DV_MIN, PUSH_TIME, SEPARATION
from crashlab.restitution import restitution_at

# the separating-axis test compiled for this Python loop (crashlab.geometry's is register_jitable: in Python it runs
# interpreted, 0.17 ms a call, 9 % of a side collision's run while its pair parts)
_penetration = njit(cache=True)(penetration)


class Episode:
    """One contact episode of a pair (vehicle i, vehicle or barrier k): its impact ("continuous") or its push."""

    __slots__ = ("cp", "dv", "e", "energy", "i", "j", "k", "kind", "n", "plane", "px", "py", "sides", "t",
                 "t_end", "weight")

    def __init__(self, t, i, k, px, py, plane, e, sides, kind="continuous"):
        self.t, self.i, self.k, self.px, self.py, self.plane = t, i, k, px, py, plane
        self.kind = kind
        self.n = (0.0, 0.0)  # the contact normal from i to k and a contact point, of the last step with an impulse
        self.cp = (px, py)
        self.sides = sides  # the sides of i and k its first contact strikes (planar_vehicle.struck_side; 0: barrier)
        self.e = e  # the episode's restitution (the scene's, or its law at the first contact's closing speed)
        self.t_end = t  # end of the last step with a contact impulse
        self.dv = np.zeros((2, 3))  # contact velocity jump of i and (if a vehicle) k: vx, vy, r
        self.energy = 0.0  # kinetic energy removed by the contact impulses [J]
        self.weight = 0.0  # impulse of this step [N s], to share a vehicle's yaw jump between contacts
        self.j = np.zeros(2)  # impulse of this step on vehicle i [N s, global] (on k: -j)


def contact_islands(episodes, nv):
    """The contact islands of a step: (sorted vehicles, their episodes) per group of vehicles joined by
    vehicle-vehicle contacts (a barrier is static: it joins nothing)."""
    root = list(range(nv))

    def find(a):
        while root[a] != a:
            root[a] = root[root[a]]
            a = root[a]
        return a

    for ep in episodes:
        if ep.k < nv:
            root[find(ep.k)] = find(ep.i)
    groups: dict = {}
    for ep in episodes:
        groups.setdefault(find(ep.i), []).append(ep)
    return [(sorted({q for ep in eps for q in (ep.i, ep.k) if q < nv}), eps) for eps in groups.values()]


def step_energy(S1, jump, mass, iz, vehicles):
    """Kinetic energy the contact impulses added this step (negative: dissipated)."""
    de = 0.0
    for q in vehicles:
        v, dv = S1[q, 3:6], jump[q]
        w = v - dv
        de += (0.5 * mass[q] * (v[0] ** 2 + v[1] ** 2 - w[0] ** 2 - w[1] ** 2)
               + 0.5 * iz[q] * (v[2] ** 2 - w[2] ** 2))
    return de


def _outline(shape) -> np.ndarray:
    """A pymunk polygon's corners in the world frame, counter-clockwise (crashlab.geometry's convention)."""
    return np.array([tuple(shape.body.local_to_world(v)) for v in shape.get_vertices()])


def _overlap_middle(arb, px, py) -> tuple[float, float]:
    """The middle of the two shapes' overlap at their first contact (crashlab.geometry.overlap_centroid), the point
    whose side each vehicle is struck on (docs/physics.md §21); the contact point (px, py) where it has no area.
    Not the contact point itself: at an angle that is the striking car's corner, on the diagonal that separates its
    front from its side."""
    x, y, _ = overlap_centroid(*(_outline(s) for s in arb.shapes))
    return (x, y) if math.isfinite(x) else (px, py)


def _contact(arb, sgn) -> tuple[float, float, float, float]:
    """An arbiter's contact point (the mean of its points' midpoints) and normal, oriented by sgn (from i to k)."""
    cps = arb.contact_point_set
    pts = cps.points
    px = sum(0.5 * (p.point_a.x + p.point_b.x) for p in pts) / max(len(pts), 1)
    py = sum(0.5 * (p.point_a.y + p.point_b.y) for p in pts) / max(len(pts), 1)
    return px, py, sgn * cps.normal.x, sgn * cps.normal.y


def written(ep, mass) -> bool:
    """Whether an episode gives impact rows: every impact; a push whose impulse changed the pair's relative velocity
    by PUSH_DV_MIN or more (a light touch at rest writes none, as in the 3D models: contact_episodes.close_episode)."""
    if ep.kind != PUSH:
        return True
    rel = ep.dv[0, 0:2] - (ep.dv[1, 0:2] if ep.k < len(mass) else 0.0)
    return math.hypot(rel[0], rel[1]) >= PUSH_DV_MIN


class Contacts:
    """The contact bookkeeping of one run: the callbacks of its pymunk space (`attach`) and the episodes.

    bodies: the vehicles' pymunk bodies, in scene order; owner: pymunk shape -> vehicle index (a barrier:
    the number of vehicles + its index); impact: the scene's [impact]; dt: the engine's step; P: the vehicles'
    parameters (planar_vehicle.pack_vehicle rows). The run sets `t`, the time at the start of the step the engine
    takes next."""

    def __init__(self, bodies, owner, impact, dt: float, P):
        self.bodies, self.owner, self.impact, self.dt, self.P = bodies, owner, impact, dt, P
        self.nv = len(bodies)
        self.t = 0.0
        self.open = {}  # (i, k) -> the Episode of a pair in contact
        self.ended = {}  # (i, k) -> (its Episode, its two shapes): contact ended, the pair not yet SEPARATION apart
        self.episodes = []
        self.touching = np.zeros(self.nv, bool)
        self.hit = np.zeros(self.nv, bool)
        self.contact = np.full((self.nv, 4), np.nan)
        self.contact_t = math.nan
        self.max_depth = 0.0
        self.law_warnings = []  # restitution = "speed" outside its data (crashlab.restitution.range_warning)

    def attach(self, space) -> None:
        """Chipmunk calls this bookkeeping for every pair of shapes of the space."""
        space.on_collision(begin=self._begin, pre_solve=self._pre_solve, post_solve=self._post_solve,
                           separate=self._separate)

    def _pair(self, arb):
        a, b = arb.shapes
        i, k = self.owner[a], self.owner[b]
        return (i, k, 1.0) if i < k else (k, i, -1.0)

    def _struck_side(self, q, px, py) -> int:
        """The face of vehicle q the point (px, py) strikes (planar_vehicle.struck_side: 0 front, 1 rear, 2 left,
        3 right)."""
        body = self.bodies[q]
        return struck_side(self.P[q], body.position.x, body.position.y, body.angle, px, py)

    def _begin(self, arb, space, data):
        i, k, sgn = self._pair(arb)
        t = self.t + self.dt
        px, py, nx, ny = _contact(arb, sgn)
        if (i, k) in self.ended:  # a re-touch before the pair was SEPARATION apart: the episode goes on
            ep, _ = self.ended.pop((i, k))
            if ep.kind == PUSH or t - ep.t < PUSH_TIME - 0.5 * self.dt:  # (t counts steps: half a step for round-off)
                self.open[(i, k)] = ep
            else:  # later than PUSH_TIME after its impact: the impact's push (§15), the impact's sides struck
                self._open(arb, i, k, t, px, py, nx, ny, ep.e, PUSH, ep.sides)
            return
        if math.isnan(self.contact_t):
            self.contact_t = t
            for q, body in enumerate(self.bodies):  # positions at touch, velocities before the impulses
                v = body.velocity
                self.contact[q] = (body.position.x, body.position.y, body.angle, math.hypot(v.x, v.y))
        # restitution of the episode: the scene's, or its law at the normal closing speed of the first
        # contact (docs/physics.md §13b), kept for the whole episode (Chipmunk re-reads it every step)
        vi = self.bodies[i].velocity_at_world_point((px, py))
        vk = tuple(self.bodies[k].velocity_at_world_point((px, py))) if k < self.nv else (0.0, 0.0)
        e, why = restitution_at(max(-((vk[0] - vi.x) * nx + (vk[1] - vi.y) * ny), 0.0), self.impact)
        if why:
            self.law_warnings.append(why)
        sx, sy = _overlap_middle(arb, px, py)
        self._open(arb, i, k, t, px, py, nx, ny, e, "continuous",
                   (self._struck_side(i, sx, sy), self._struck_side(k, sx, sy) if k < self.nv else 0))
        for q in (i, k):
            if q < self.nv and not self.hit[q]:
                self.hit[q] = True  # locked_after_impact wheels lock from here (driver_inputs.effective_mode)

    def _open(self, arb, i, k, t, px, py, nx, ny, e, kind, sides) -> None:
        """A new episode of pair (i, k) in contact from t at point (px, py), normal (nx, ny) from i to k, striking
        `sides`: an impact, or the push of one (kind PUSH)."""
        ep = Episode(t, i, k, px, py, math.atan2(nx, -ny), e, sides, kind)
        ep.n = (nx, ny)
        self.open[(i, k)] = ep
        self.episodes.append(ep)

    def _pre_solve(self, arb, space, data):
        imp = self.impact
        i, k, _ = self._pair(arb)
        ep = self.open.get((i, k))
        # exactly the pair's values, not a product of per-shape ones
        arb.restitution = imp.restitution if ep is None else ep.e
        arb.friction = imp.friction
        for q in (i, k):
            if q < self.nv:
                self.touching[q] = True
        for p in arb.contact_point_set.points:
            self.max_depth = max(self.max_depth, -p.distance)

    def _post_solve(self, arb, space, data):
        i, k, sgn = self._pair(arb)
        ep = self.open.get((i, k))
        if ep is not None:
            j = arb.total_impulse  # the impulse on the body of arb.shapes[0]
            ep.weight += math.hypot(j.x, j.y)
            ep.j[0] += sgn * j.x
            ep.j[1] += sgn * j.y
            if j.x != 0.0 or j.y != 0.0:
                ep.t_end = self.t + self.dt
                px, py, nx, ny = _contact(arb, sgn)
                ep.cp, ep.n = (px, py), (nx, ny)

    def _separate(self, arb, space, data):
        i, k, _ = self._pair(arb)
        ep = self.open.pop((i, k), None)
        if ep is not None:
            self.ended[(i, k)] = (ep, arb.shapes)

    def step_end(self, t: float) -> None:
        """After a step to t (its impulses booked): an impact in contact later than PUSH_TIME after its start goes on
        as its push from the first step end where the pair does not separate at the contact point (an impact still
        rebounding keeps its rebound); an ended episode whose pair is SEPARATION apart is over (the outlines' largest
        separating-axis gap, crashlab.geometry.penetration; docs/physics.md §15)."""
        if not self.open and not self.ended:
            return
        for (i, k), ep in list(self.open.items()):
            if ep.kind != PUSH and t - ep.t >= PUSH_TIME - 0.5 * self.dt:
                vi = self.bodies[i].velocity_at_world_point(ep.cp)
                vk = tuple(self.bodies[k].velocity_at_world_point(ep.cp)) if k < self.nv else (0.0, 0.0)
                if (vk[0] - vi.x) * ep.n[0] + (vk[1] - vi.y) * ep.n[1] <= 0.0:  # approaching or resting
                    push = Episode(t, i, k, *ep.cp, math.atan2(ep.n[0], -ep.n[1]), ep.e, ep.sides, PUSH)
                    push.n = ep.n
                    self.open[(i, k)] = push
                    self.episodes.append(push)
        for pair, (_, shapes) in list(self.ended.items()):
            if _penetration(*(_outline(s) for s in shapes))[0] <= -SEPARATION:
                del self.ended[pair]

    def book(self, S1, jump, mass, iz):
        """Share each vehicle's contact jump of this step among its contact episodes: the velocity jump
        exactly, from each contact's impulse (so every episode exchanges momentum, m1 dv1 + m2 dv2 = 0, also
        when a car touches two others at once); the yaw-rate jump by impulse share. The energy is booked per
        contact island (the vehicles in touch with each other this step): the kinetic energy the island's
        contact impulses removed, shared among its episodes by impulse. A pair's own share is no dissipation
        measure when three touch (a car pressed between two others passes energy on from one to the
        other: per vehicle shares read as energy created while the island's total falls; issue 27)."""
        active = list(self.open.values())  # an episode that separated this step had no impulse in it
        if not active:
            return
        for q in range(self.nv):
            mine = [(ep, 0 if ep.i == q else 1) for ep in active if ep.i == q or ep.k == q]
            if not mine:
                continue
            total = sum(ep.weight for ep, _ in mine)
            for ep, side in mine:
                share = ep.weight / total if total > 0 else 1.0 / len(mine)
                if len(mine) == 1:
                    ep.dv[side] += jump[q]
                else:
                    ep.dv[side, 0:2] += (1.0 if side == 0 else -1.0) * ep.j / mass[q]
                    ep.dv[side, 2] += share * jump[q, 2]
        for members, eps in contact_islands(active, self.nv):
            de = step_energy(S1, jump, mass, iz, members)
            total = sum(ep.weight for ep in eps)
            for ep in eps:
                ep.energy -= (ep.weight / total if total > 0 else 1.0 / len(eps)) * de
