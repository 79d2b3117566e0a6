"""One run of the pymunk model: the scene's vehicles and barriers built as a pymunk space, the time loop (tyre
forces, the engine's step, rest), and its Outcome; the contacts are booked by crashlab.models.pymunk.contacts."""
from __future__ import annotations

import math
import time

import numpy as np

from crashlab.geometry import rect_corners
from crashlab.models.common.contact_episodes import merged_intervals
from crashlab.models.common.driver_inputs import pack_action_tables, pack_zones
from crashlab.models.common.impact_rows import pair_rows, struck_compliance
from crashlab.models.common.planar_vehicle import N_PARAMS, P_IZ, P_MASS, pack_vehicle
from crashlab.outcome import Outcome
from crashlab.scene import barrier_outline

from .contacts import Contacts, step_energy, written


def build_space(pymunk, model, scene):
    """The scene as a pymunk space with the model's solver settings: (space, the vehicles' bodies in scene
    order, pymunk shape -> vehicle index; a barrier's: the number of vehicles + its index)."""
    space = pymunk.Space()
    space.gravity = (0.0, 0.0)  # plan view: the road's reaction is in the tyre forces
    space.damping = 1.0
    space.iterations = model.iterations
    space.collision_slop = model.collision_slop
    space.collision_bias = model.collision_bias
    bodies, owner = [], {}
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
        bodies.append(body)
        owner[shape] = i
    nv = len(scene.vehicles)
    for k, b in enumerate(scene.barriers):
        shape = pymunk.Poly(space.static_body, [tuple(c) for c in barrier_outline(b)])
        space.add(shape)
        owner[shape] = nv + k
    return space, bodies, owner


class Run:
    """The state of one simulation: the pymunk space, the packed vehicles and driver inputs, the contacts.
    model: the PymunkModel (its options)."""

    def __init__(self, model, scene):
        import pymunk

        from .ground import ground_forces
        self.pymunk, self.ground = pymunk, ground_forces
        self.m, self.scene = model, scene
        self.nv = len(scene.vehicles)
        self.P = np.array([pack_vehicle(v.spec, v.wheels, v.steer) for v in scene.vehicles]).reshape(-1, N_PARAMS)
        self.actions, self.n_actions = pack_action_tables(scene.vehicles)  # driver inputs (§2a)
        self.zones = pack_zones(scene.road)
        self.space, self.bodies, owner = build_space(pymunk, model, scene)
        self.contacts = Contacts(self.bodies, owner, scene.impact, model.dt, self.P)
        self.contacts.attach(self.space)
        self.t = 0.0

    def _read(self, S):
        for q, b in enumerate(self.bodies):
            p, v = b.position, b.velocity
            S[q, 0], S[q, 1], S[q, 2], S[q, 3], S[q, 4], S[q, 5] = p.x, p.y, b.angle, v.x, v.y, b.angular_velocity

    def run(self, t_start) -> Outcome:
        """The time loop, to rest or the scene's duration, and its Outcome (wall time since t_start)."""
        m, scene, nv, P, c = self.m, self.scene, self.nv, self.P, self.contacts
        dt, rec_dt = m.dt, m.record_dt
        mu = scene.road.friction
        warnings = []
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
                self.ground(P, S, self.t, self.actions, self.n_actions, c.hit, self.awake, mu, *self.zones,
                            acc, F)
            for q, b in enumerate(self.bodies):
                b.force = (F[q, 0], F[q, 1])  # global frame; Chipmunk clears it after the step
                b.torque = F[q, 2]
            c.touching[:] = False
            for ep in c.open.values():
                ep.weight = 0.0
                ep.j[:] = 0.0
            c.t = self.t  # the callbacks date what they book by this step's end
            self.space.step(dt)
            steps += 1
            self.t = steps * dt
            self._read(S1)
            if c.touching.any():
                # contact velocity jump of each vehicle this step: total change minus the tyre part
                # F dt / m (Chipmunk integrates v += F / m dt, no damping, no gravity)
                jump = S1[:, 3:6] - S[:, 3:6] - F * (dt / np.column_stack((mass, mass, iz)))
                c.book(S1, jump, mass, iz)
                e_contact += step_energy(S1, jump, mass, iz, range(nv))
            c.step_end(self.t)
            S, S1 = S1, S
            if not math.isfinite(S.sum()):
                ok = False
                warnings.append("the state became NaN")
                break
            # rest: a vehicle that has (almost) stopped is put to sleep unless it touches one that moves
            # (a pair at rest against each other, or a car at rest against a wall, is at rest)
            moving = (np.hypot(S[:, 3], S[:, 4]) >= m.v_rest) | (np.abs(S[:, 5]) >= m.v_rest)
            pushed = np.zeros(nv, bool)
            for i, k in c.open:
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
        warnings += c.law_warnings
        return self._outcome(S, traj[:nr], steps, ke0, e_contact, warnings, ok, time.perf_counter() - t_start)

    def _outcome(self, S, traj, steps, ke0, e_contact, warnings, ok, wall) -> Outcome:
        scene, nv, P, c = self.scene, self.nv, self.P, self.contacts
        names = scene.vehicle_names
        heads = [c.contact[q, 2] if not math.isnan(c.contact[q, 2]) else S[q, 2] for q in range(nv)]
        rows, compliance = [], struck_compliance(v.spec for v in scene.vehicles)
        kept = [ep for ep in c.episodes if written(ep, P[:, P_MASS])]  # the episodes with rows (a light push has none)
        for ep in kept:  # the force on a vehicle has the direction of its contact velocity jump
            rows += pair_rows(names, P[:, P_MASS], ep.i, ep.k, ep.t, ep.energy, ep.dv, ep.dv[:, 0:2],
                              (heads[ep.i], heads[ep.k] if ep.k < nv else 0.0), (ep.px, ep.py), ep.plane,
                              ep.kind, ep.sides, compliance, duration=ep.t_end - ep.t)
        if not c.episodes:
            warnings.append("no contact between the vehicles")
        # core (crashlab.diagnostics): fixed steps, none rejected; max_penetration from the arbiters' contact depths;
        # episodes: those with rows, pushes included, as the 3D models count their records
        diagnostics = {"steps": steps, "rejected_steps": 0, "t_end": self.t, "episodes": len(kept),
                       "max_penetration": c.max_depth, "kinetic_energy_start": ke0,
                       "energy_dissipated_impacts": -e_contact, "dt": self.m.dt,
                       "iterations": self.m.iterations}
        trajectories = {n: {"t": traj[:, i, 0], "x": traj[:, i, 1], "y": traj[:, i, 2], "heading": traj[:, i, 3],
                            "vx": traj[:, i, 4], "vy": traj[:, i, 5], "yaw_rate": traj[:, i, 6]}
                        for i, n in enumerate(names)}
        return Outcome(names, S[:, 0:3].copy(), S[:, 3:6].copy(), c.contact.copy(), c.contact_t,
                       trajectories, rows, diagnostics, warnings, ok, self.m.name, wall,
                       contact_intervals=merged_intervals([(ep.t, ep.t_end) for ep in c.episodes]),
                       impact_energy=[ep.energy for ep in kept])
