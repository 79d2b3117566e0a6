"""Model `pymunk`: a general-purpose 2D rigid-body engine (Chipmunk2D through pymunk) with impulse
contacts, driven by the same planar tyre/ground forces as the impulse model.

pymunk is imported inside `simulate` only, so listing the models never imports it.
"""
from __future__ import annotations

import math
import time

import numpy as np

from crashlab.geometry import rect_corners
from crashlab.model import CollisionModel
from crashlab.models.common.driver_inputs import pack_action_tables, pack_zones
from crashlab.models.common.impact_rows import pair_rows
from crashlab.models.common.planar_vehicle import N_PARAMS, P_IZ, P_MASS, pack_vehicle
from crashlab.options import ModelOptions, option
from crashlab.outcome import Outcome
from crashlab.restitution import restitution_at
from crashlab.scene import barrier_outline


class PymunkModel(CollisionModel):
    """Vehicles and barriers as Chipmunk polygons, SI units, impulse contacts (sequential impulses).

    Options (documented defaults, the same for every scene):
      dt = 0.00025 s         fixed step of the engine. Two things set it. (1) Chipmunk's friction impulses
                             act on the two surface points of a penetrating contact, a penetration
                             (about v dt) apart, so angular momentum is not conserved exactly; on an
                             oblique car-to-car impact with the road off the error about the system's
                             centre of mass is 4.1 / 1.8 / 0.64 / 0.17 / 0.08 % at dt = 2 / 1 / 0.5 /
                             0.25 / 0.1 ms (studies/pymunk/angular_momentum_vs_step.py; with the
                             impact friction set to 0 it is 10-15 times smaller); 0.25 ms is the
                             largest step of that series under 0.5 %, with a factor 3 of margin.
                             (2) The tyre forces are evaluated once per step (semi-implicit Euler): at
                             0.25 ms the rest poses of the side collision are within 1 cm and 0.1 deg of
                             those at 0.1 ms.
      iterations = 100       solver iterations per step. A crash is a handful of contact points, so
                             the cost is not measurable; the sequential impulses on a two-point
                             manifold (face-to-face contact) converge to the simultaneous solution by
                             about 30 sweeps (Chipmunk's default 10 leaves 0.1 deg/s differences in the
                             yaw-rate change of the side collision); 100 leaves margin.
      collision_slop = 1e-4 m  penetration allowed without positional correction. Chipmunk's default
                             (0.1) is meant for pixels; in metres it would let the cars sink 10 cm into
                             each other. 0.1 mm is far below any crush depth yet above round-off.
                             An accuracy knob ("smaller"): a tolerance on the overlap, whose limit 0 is
                             the rigid non-penetration the model stands for.
      collision_bias = 0.0018  fraction of a penetration left after one second (Chipmunk's default,
                             (1 - 0.1)^60). The correction is a split impulse: it moves positions only
                             and never changes the velocities, so it adds no momentum or energy.
                             Not an accuracy knob: a stabilisation rate (as multibody's baumgarte), and
                             neither direction converges to the model (0 removes the whole penetration
                             in one step, 1 never removes it).
      record_dt = 0.01 s     trajectory sampling (0: none)
      v_rest = 0.03          m/s and rad/s below which a vehicle out of contact is at rest (as impulse)
      ground_forces = True   tyre/road forces on; False leaves only the contacts (momentum checks)

    The pair's restitution and friction are set exactly from the scene's [impact] on the arbiter in
    every pre-solve (Chipmunk would otherwise multiply the per-shape coefficients). A given impact point
    and contact plane are ignored: the engine finds its own contacts (a warning says so).

    Impacts: one contact episode (begin .. separate of a pair) is one impact. Its delta-V and yaw-rate
    change are the velocity jumps the contact caused, i.e. the change of velocity over the steps of the
    episode minus the part of the tyre forces (known exactly: Chipmunk adds F dt / m); the energy is the
    kinetic energy the contact impulses removed. The point is the middle of the contact points and the
    plane the tangent of the contact normal at the episode's first step; `contact_intervals` (and the rows'
    `duration`) span the episode's steps with contact impulses.

    What differs from the impulse model by construction: when two flat faces meet (a bumper on a
    door), Chipmunk's contact has two points, one at each end of the contact segment, and both get the
    restitution target. The normal relative velocity is then uniform along the segment after the impact,
    i.e. the relative rotation is stopped: the two cars leave a face-to-face impact with the same yaw
    rate, where a single-point impulse (PC-Crash, model `impulse`) lets them spin apart. This is the
    main source of the different rest poses in the side collision.
    """

    name = "pymunk"
    compiles = "pymunk"  # its numba ground contact (models/pymunk/ground.py)
    driver_inputs = True  # actions and friction zones (docs/physics.md §2a) through ground.ground_forces

    class Options(ModelOptions):
        dt: float = option(0.00025, "fixed step of the engine (Chipmunk's contact friction breaks angular "
                           "momentum by about the step's penetration; the tyre forces are evaluated once a step)",
                           "s", accuracy="smaller", gt=0, le=0.01)
        iterations: int = option(100, "sequential-impulse solver iterations per step", "", accuracy="larger",
                                 ge=1, le=10000)
        collision_slop: float = option(1e-4, "penetration allowed without positional correction", "m",
                                       accuracy="smaller", ge=0, le=0.1)
        collision_bias: float = option(0.0017970074436457143, "fraction of a penetration left uncorrected after "
                                       "one second (split impulse: positions only)", "", ge=0, le=1.0)
        record_dt: float = option(0.01, "trajectory sampling (0: none)", "s", ge=0)
        v_rest: float = option(0.03, "speed (m/s) and yaw rate (rad/s) below which a vehicle out of contact is at "
                               "rest", "m/s", gt=0, lt=10.0)
        ground_forces: bool = option(True, "test switch: False removes the tyre/road forces (momentum checks)")
        sleeping: bool = option(True, "study switch: False never puts a vehicle at rest to sleep (tyre forces "
                                "evaluated at every step; the run then lasts the scene's duration)")

    def __init__(self, **options):
        super().__init__(**options)
        o = self.options
        self.dt, self.iterations, self.record_dt, self.v_rest = o.dt, o.iterations, o.record_dt, o.v_rest
        self.collision_slop, self.collision_bias, self.ground_forces = o.collision_slop, o.collision_bias, \
            o.ground_forces
        self.sleeping = o.sleeping

    # ------------------------------------------------------------------ running
    def simulate(self, scene) -> Outcome:
        t0 = time.perf_counter()
        try:
            return _Run(self, scene).run(t0)
        except ImportError as err:
            return Outcome.failed(scene.vehicle_names, f"pymunk is not installed ({err})", self.name,
                                  time.perf_counter() - t0)


class _Episode:
    """One contact episode of a pair (vehicle i, vehicle or barrier k)."""

    __slots__ = ("dv", "e", "energy", "i", "j", "k", "plane", "px", "py", "t", "t_end", "weight")

    def __init__(self, t, i, k, px, py, plane, e):
        self.t, self.i, self.k, self.px, self.py, self.plane = t, i, k, px, py, plane
        self.e = e  # the episode's restitution (the scene's, or its law at the first contact's closing speed)
        self.t_end = t  # end of the last step with a contact impulse
        self.dv = np.zeros((2, 3))  # contact velocity jump of i and (if a vehicle) k: vx, vy, r
        self.energy = 0.0  # kinetic energy removed by the contact impulses [J]
        self.weight = 0.0  # impulse of this step [N s], to share a vehicle's yaw jump between contacts
        self.j = np.zeros(2)  # impulse of this step on vehicle i [N s, global] (on k: -j)


def _islands(episodes, nv):
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


class _Run:
    """The state of one simulation: the pymunk space and the bookkeeping of contacts."""

    def __init__(self, model: PymunkModel, scene):
        import pymunk

        from .ground import ground_forces
        self.pymunk, self.ground = pymunk, ground_forces
        self.m, self.scene = model, scene
        self.nv = len(scene.vehicles)
        self.P = np.array([pack_vehicle(v.spec, v.wheels, v.steer) for v in scene.vehicles]).reshape(-1, N_PARAMS)
        self.actions, self.n_actions = pack_action_tables(scene.vehicles)  # driver inputs (§2a)
        self.zones = pack_zones(scene.road)
        space = pymunk.Space()
        space.gravity = (0.0, 0.0)  # plan view: the road's reaction is in the tyre forces
        space.damping = 1.0
        space.iterations = model.iterations
        space.collision_slop = model.collision_slop
        space.collision_bias = model.collision_bias
        self.space = space
        self.bodies, self.owner = [], {}
        for i, v in enumerate(scene.vehicles):
            s = v.spec
            body = pymunk.Body(s.mass, s.yaw_inertia)  # body origin = centre of gravity
            body.position = (v.x, v.y)
            body.angle = v.heading
            body.velocity = (v.speed * math.cos(v.heading), v.speed * math.sin(v.heading))
            body.angular_velocity = v.yaw_rate
            shape = pymunk.Poly(body, [tuple(c) for c in rect_corners(0.0, 0.0, 0.0, s.cg_to_front,
                                                                       s.cg_to_rear, s.width / 2)])
            space.add(body, shape)
            self.bodies.append(body)
            self.owner[shape] = i
        for k, b in enumerate(scene.barriers):
            shape = pymunk.Poly(space.static_body, [tuple(c) for c in barrier_outline(b)])
            space.add(shape)
            self.owner[shape] = self.nv + k
        space.on_collision(begin=self._begin, pre_solve=self._pre_solve, post_solve=self._post_solve,
                           separate=self._separate)
        self.open = {}  # (i, k) -> open _Episode
        self.episodes = []
        self.touching = np.zeros(self.nv, bool)
        self.hit = np.zeros(self.nv, bool)
        self.contact = np.full((self.nv, 4), np.nan)
        self.contact_t = math.nan
        self.t = 0.0
        self.max_depth = 0.0
        self.law_warnings = []  # restitution = "speed" outside its data (crashlab.restitution.range_warning)

    # ------------------------------------------------------------------ collision callbacks
    def _pair(self, arb):
        a, b = arb.shapes
        i, k = self.owner[a], self.owner[b]
        return (i, k, 1.0) if i < k else (k, i, -1.0)

    def _begin(self, arb, space, data):
        i, k, sgn = self._pair(arb)
        if math.isnan(self.contact_t):
            self.contact_t = self.t + self.m.dt
            for q, body in enumerate(self.bodies):  # positions at touch, velocities before the impulses
                v = body.velocity
                self.contact[q] = (body.position.x, body.position.y, body.angle, math.hypot(v.x, v.y))
        cps = arb.contact_point_set
        pts = cps.points
        px = sum(0.5 * (p.point_a.x + p.point_b.x) for p in pts) / max(len(pts), 1)
        py = sum(0.5 * (p.point_a.y + p.point_b.y) for p in pts) / max(len(pts), 1)
        nx, ny = sgn * cps.normal.x, sgn * cps.normal.y  # from i to k
        # restitution of the episode: the scene's, or its law at the normal closing speed of the first
        # contact (docs/physics.md §13b), kept for the whole episode (Chipmunk re-reads it every step)
        vi = self.bodies[i].velocity_at_world_point((px, py))
        vk = tuple(self.bodies[k].velocity_at_world_point((px, py))) if k < self.nv else (0.0, 0.0)
        e, why = restitution_at(max(-((vk[0] - vi.x) * nx + (vk[1] - vi.y) * ny), 0.0), self.scene.impact)
        if why:
            self.law_warnings.append(why)
        ep = _Episode(self.t + self.m.dt, i, k, px, py, math.atan2(nx, -ny), e)
        self.open[(i, k)] = ep
        self.episodes.append(ep)
        for q in (i, k):
            if q < self.nv and not self.hit[q]:
                self.hit[q] = True  # locked_after_impact wheels lock from here (driver_inputs.effective_mode)

    def _pre_solve(self, arb, space, data):
        imp = self.scene.impact
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
                ep.t_end = self.t + self.m.dt

    def _separate(self, arb, space, data):
        i, k, _ = self._pair(arb)
        self.open.pop((i, k), None)

    # ------------------------------------------------------------------ the time loop
    def _read(self, S):
        for q, b in enumerate(self.bodies):
            p, v = b.position, b.velocity
            S[q, 0], S[q, 1], S[q, 2], S[q, 3], S[q, 4], S[q, 5] = p.x, p.y, b.angle, v.x, v.y, b.angular_velocity

    def run(self, t_start) -> Outcome:
        m, scene, nv, P = self.m, self.scene, self.nv, self.P
        dt, rec_dt = m.dt, m.record_dt
        mu = scene.road.friction
        warnings = []
        if scene.impact.point is not None:
            warnings.append("pymunk ignores the given impact point and plane_angle: the engine finds its "
                            "own contacts")
        if scene.impact.engagement:
            warnings.append('pymunk ignores [impact] point = "engagement" (an impulse-model setting): the engine '
                            "finds its own contacts")
        S, S1 = np.empty((nv, 6)), np.empty((nv, 6))
        F = np.zeros((nv, 3))
        acc = np.zeros((nv, 2))
        self._read(S)
        self.awake = np.array([not (math.hypot(S[q, 3], S[q, 4]) < m.v_rest and abs(S[q, 5]) < m.v_rest)
                               for q in range(nv)])
        still = ~self.awake
        if not m.sleeping:
            self.awake[:] = True
        for q in range(nv):
            if still[q]:
                self.bodies[q].velocity, self.bodies[q].angular_velocity = (0.0, 0.0), 0.0
        self._read(S)
        mass, iz = P[:, P_MASS], P[:, P_IZ]
        ke0 = float(np.sum(0.5 * mass * (S[:, 3] ** 2 + S[:, 4] ** 2) + 0.5 * iz * S[:, 5] ** 2))
        n_rec = int(scene.duration / rec_dt) + 3 if rec_dt > 0 else 0
        traj = np.zeros((n_rec, nv, 7))
        nr, next_rec = 0, 0.0
        steps, ok, e_contact = 0, True, 0.0
        n_steps = math.ceil(scene.duration / dt - 1e-9)
        while steps < n_steps:
            if rec_dt > 0 and self.t >= next_rec - 1e-12 and nr < n_rec - 1:
                traj[nr, :, 0], traj[nr, :, 1:7] = self.t, S
                nr += 1
                next_rec += rec_dt
            if m.ground_forces:
                self.ground(P, S, self.t, self.actions, self.n_actions, self.hit, self.awake, mu, *self.zones,
                            acc, F)
            for q, b in enumerate(self.bodies):
                b.force = (F[q, 0], F[q, 1])  # global frame; Chipmunk clears it after the step
                b.torque = F[q, 2]
            self.touching[:] = False
            for ep in self.open.values():
                ep.weight = 0.0
                ep.j[:] = 0.0
            self.space.step(dt)
            steps += 1
            self.t = steps * dt
            self._read(S1)
            if self.touching.any():
                # contact velocity jump of each vehicle this step: total change minus the tyre part
                # F dt / m (Chipmunk integrates v += F / m dt, no damping, no gravity)
                jump = S1[:, 3:6] - S[:, 3:6] - F * (dt / np.column_stack((mass, mass, iz)))
                self._book(S1, jump, mass, iz)
                e_contact += self._step_energy(S1, jump, mass, iz, range(nv))
            S, S1 = S1, S
            if not math.isfinite(S.sum()):
                ok = False
                warnings.append("the state became NaN")
                break
            # rest: a vehicle that has (almost) stopped is put to sleep unless it touches one that moves
            # (a pair at rest against each other, or a car at rest against a wall, is at rest)
            moving = (np.hypot(S[:, 3], S[:, 4]) >= m.v_rest) | (np.abs(S[:, 5]) >= m.v_rest)
            pushed = np.zeros(nv, bool)
            for i, k in self.open:
                if k < nv:
                    pushed[i] |= moving[k]
                    pushed[k] |= moving[i]
            for q in range(nv):
                if self.awake[q]:
                    if not moving[q] and not pushed[q] and m.sleeping:
                        self.awake[q] = False
                        self.bodies[q].velocity, self.bodies[q].angular_velocity = (0.0, 0.0), 0.0
                        S[q, 3:6] = 0.0
                elif moving[q]:  # struck while at rest
                    self.awake[q] = True
            if not self.awake.any():
                if not scene.stop_at_rest:
                    self.t = scene.duration  # everything at rest: the state is final
                break
        if rec_dt > 0 and nr < n_rec:
            traj[nr, :, 0], traj[nr, :, 1:7] = self.t, S
            nr += 1
        warnings += self.law_warnings
        return self._outcome(S, traj[:nr], steps, ke0, e_contact, warnings, ok, time.perf_counter() - t_start)

    @staticmethod
    def _step_energy(S1, jump, mass, iz, vehicles):
        """Kinetic energy the contact impulses added this step (negative: dissipated)."""
        de = 0.0
        for q in vehicles:
            v, dv = S1[q, 3:6], jump[q]
            w = v - dv
            de += (0.5 * mass[q] * (v[0] ** 2 + v[1] ** 2 - w[0] ** 2 - w[1] ** 2)
                   + 0.5 * iz[q] * (v[2] ** 2 - w[2] ** 2))
        return de

    def _book(self, S1, jump, mass, iz):
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
        for members, eps in _islands(active, self.nv):
            de = self._step_energy(S1, jump, mass, iz, members)
            total = sum(ep.weight for ep in eps)
            for ep in eps:
                ep.energy -= (ep.weight / total if total > 0 else 1.0 / len(eps)) * de

    # ------------------------------------------------------------------ results
    def _outcome(self, S, traj, steps, ke0, e_contact, warnings, ok, wall) -> Outcome:
        scene, nv, P = self.scene, self.nv, self.P
        names = scene.vehicle_names
        heads = [self.contact[q, 2] if not math.isnan(self.contact[q, 2]) else S[q, 2] for q in range(nv)]
        rows = []
        for ep in self.episodes:  # the force on a vehicle has the direction of its contact velocity jump
            rows += pair_rows(names, P[:, P_MASS], ep.i, ep.k, ep.t, ep.energy, ep.dv, ep.dv[:, 0:2],
                              (heads[ep.i], heads[ep.k] if ep.k < nv else 0.0), (ep.px, ep.py), ep.plane,
                              "continuous", duration=ep.t_end - ep.t)
        if not self.episodes:
            warnings.append("no contact between the vehicles")
        # core (crashlab.diagnostics): fixed steps, none rejected; max_penetration from the arbiters' contact depths
        diagnostics = {"steps": steps, "rejected_steps": 0, "episodes": len(self.episodes), "t_end": self.t,
                       "max_penetration": self.max_depth, "kinetic_energy_start": ke0,
                       "energy_dissipated_impacts": -e_contact, "dt": self.m.dt,
                       "iterations": self.m.iterations}
        trajectories = {n: {"t": traj[:, i, 0], "x": traj[:, i, 1], "y": traj[:, i, 2], "heading": traj[:, i, 3],
                            "vx": traj[:, i, 4], "vy": traj[:, i, 5], "yaw_rate": traj[:, i, 6]}
                        for i, n in enumerate(names)}
        return Outcome(names, S[:, 0:3].copy(), S[:, 3:6].copy(), self.contact.copy(), self.contact_t,
                       trajectories, rows, diagnostics, warnings, ok, self.m.name, wall,
                       contact_intervals=[(ep.t, ep.t_end) for ep in self.episodes],
                       impact_energy=[ep.energy for ep in self.episodes])
