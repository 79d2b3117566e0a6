"""Model `exudyn`: the 9-body vehicle of the 3D models (crashlab.models.common.vehicle_3d) built in exudyn
(build.py), with the chassis contact shared with the multibody model (geometry, gap search, force law:
crashlab.models.common.chassis_contact, road_contact, contact_episodes) applied as loads.

exudyn is imported only here and in build.py, inside `simulate` (the registry imports this module only when
the model is asked for; `import crashlab.models.exudyn` itself does not import exudyn).
"""
from __future__ import annotations

import math
import time
from typing import Literal

import numpy as np
from pydantic import model_validator

from crashlab.model import CollisionModel
from crashlab.models.common import chassis_contact as C
from crashlab.models.common import contact_episodes as EP
from crashlab.models.common import driver_inputs as DI
from crashlab.models.common import road_contact as R
from crashlab.models.common.contact_force import FRICTION_V0, FRICTION_V1, FRICTION_VS, chi, friction_code
from crashlab.models.common.crush_structure import clamp_restitution, speed_law_setting, structure_row
from crashlab.models.common.tyre_moments import OMEGA_BRAKE, brake_moment, rolling_resistance_moment
from crashlab.models.common.vehicle_3d import CORNERS, NW, T_ETA, T_R1, T_R2, build_scene_vehicles, steer_angles
from crashlab.models.common.wheel_states import BRAKED, LOCKED
from crashlab.options import ModelOptions, option
from crashlab.outcome import Outcome
from crashlab.restitution import E_SPEED_LAW, SPEED
from crashlab.units import G

from .chassis_state import chassis_states

BIG_ERROR = 1e6        # N: a post-Newton error that always repeats the step (exudyn's tolerance is 1 N)
LOAD_ABS_TOL = 10.0    # N: absolute part of the load-iteration tolerance
MAX_LOAD_ITER = 4      # load passes per step before the step is halved (exudyn allows 5 iterations)
FY_LOCAL = 0           # the lateral component of the rolling disc's ForceLocal (x lateral, y forward, z normal)
ADAPT_RECOVERY = 5     # accepted steps before exudyn doubles a shortened step again


class ExudynModel(CollisionModel):
    """The multibody model's vehicle (9 rigid bodies, joints, suspension) built with exudyn's items, exudyn's
    rolling-disc penalty tyre, and the multibody model's chassis contact applied as loads.

    Options (the schema `Options` below; why these defaults, the same for every scene):
      step = 1e-3 s              largest step of exudyn's generalized-alpha (implicit, index 3; exudyn's adaptive step
                                 shortens it at contact onsets and when the contact load iteration does not
                                 settle, then doubles it back every 5 steps). The contact loads are iterated to
                                 their values at the step end, so the step sets the accuracy of the contact
                                 force history (170-310 force samples per PC-Crash contact), not its energy.
      min_step = 1e-6 s          shortest step exudyn may take (below it the run fails with a reason)
      onset_tolerance = 1e-3 m   a step in which a contact (car-car, car-barrier, chassis-road) opens deeper than
                                 this is repeated shorter (the multibody model's first-contact control, 1 mm)
      load_tolerance = 1e-3      the contact forces at the step end have settled when a pass changes them by
                                 less than this share of the largest (+ 10 N)
      spectral_radius = 0.8      generalized-alpha numerical damping at infinite frequency (exudyn's default is
                                 0.9): damps the activation transient of the wheel locks and the penalty
                                 tyre's stiff friction zone; the vehicle modes (< 20 Hz) keep > 99.9 % of
                                 their energy per period at 1 ms.
      friction_zone = 0.2 m/s    the rolling disc's dryFrictionProportionalZone (linear regularisation of
                                 Coulomb friction): below this slip speed the friction force is
                                 mu F_z v_slip / zone. 0.2 m/s gives a rolling Clio tyre (F_z 2.4 kN, mu 0.8)
                                 the equivalent cornering stiffness mu F_z V / zone = 133 kN/rad at 50 km/h,
                                 close to the UA tyre's 150 kN/rad, and keeps exudyn's modified Newton at
                                 ~7 iterations per step (0.05 m/s needed ~35 after an impact: 3-4x the cost).
      record_dt = 0.01 s         trajectory sampling
      v_rest = 0.01 m/s, w_rest = 0.01 rad/s, t_sleep = 0.2 s   every chassis slower than this (horizontal
                                 speed, yaw rate) for t_sleep, no contact open: the run stops (the multibody
                                 model's thresholds)
      contact_law = "structure"  the vehicles' CRASH3 crush structures in series, unloading to the scene's
                                 restitution (docs/physics.md §13a); "generic": K delta^n with the scene's
                                 force_law (§13) and the two options below (the multibody model's defaults)
      contact_stiffness = 1.35e6 N/m^1.5   generic law: K of one vehicle against a rigid barrier; car-to-car
                                 pairs use K/2^1.5 for equal K (series Hertz springs)
      contact_exponent = 1.5     generic law: n of F_N = K delta^n (1 + chi delta_dot / delta_dot0)
      v_min = 0.001 m/s          smallest approach velocity delta_dot0 stored at onset (multibody default)

    Tyre: exudyn's `CreateRollingDiscPenalty` (an infinitely thin disc of radius r1 + r2 on the plane z = 0)
    instead of our UA tyre. Normal force K_z delta + C_z delta_dot with K_z and C_z of vehicle_3d (the
    multibody tyre's radial stiffness and damping). In-plane: regularised Coulomb friction, mu F_z along the
    slip velocity of the contact point (dryFriction = [mu, mu] with the scene's road friction, linear below
    `friction_zone`). Differences to the UA tyre: no slip stiffness, no relaxation, no camber or
    self-aligning torque; a rolling wheel's lateral force is mu F_z v_lat / zone, i.e. an equivalent
    cornering stiffness mu F_z V / zone that grows with speed (96 kN/rad per Clio tyre at 10 m/s, 133 kN/rad at
    50 km/h, against UA's constant 150 kN/rad); the full mu F_z is reached at zone, not at the brush model's
    sliding limit. For a locked or sliding wheel both give mu F_z against the sliding velocity. Rolling
    resistance (the vehicle's rolling_resistance f_r, 0 in the PC-Crash scenes) is a moment
    f_r F_z R tanh(omega_rel / 0.5 rad/s) between wheel and knuckle (as our UA tyre), applied as a torque pair
    updated before every step; `braked` (ABS-like) adds the UA tyre's brake moment
    eta mu F_z R tanh(omega_rel / 1 rad/s), eta = 0.95 of the locking torque, the same way.

    Wheels: rolling (revolute joint), locked for the whole run (generic joint, all six axes); a vehicle whose
    wheels lock at some time (an action, locked_after_impact) has the revolute joint plus a spin-lock generic
    joint that is switched on and off between steps; braked (revolute joint + the brake moment above).
    Driver actions and friction zones (docs/physics.md §2a) come from common/driver_inputs, read before every
    step at its middle (`_Run._driver`): wheel state (locked_after_impact through effective_mode with the first
    contact) -> spin locks; brake fraction b -> a brake moment giving the road force b sqrt((mu F_z)^2 - F_y^2)
    (with the wheel's spin inertia I_yy a / R added); steer -> the prismatic joints' chassis markers turned to
    the Ackermann angles of vehicle_3d.steer_angles; zones -> each rolling disc's dry friction at its wheel's
    position predicted half a step on (and the chassis-road contact's at the CG).

    Contact: the numba `common.chassis_contact.contacts` shared with multibody (superellipsoids, horizontal gap search,
    normal_force_chi with the scene's force_law and restitution, the scene's friction law and impact friction) and
    the shared chassis-road contact (common.road_contact: each chassis's lowest point against the
    plane z = 0, Hunt-Crossley, a stiffness that carries the vehicle's weight at 5 mm, road friction and a patch
    moment) give the force and moment on each chassis; they are
    written into a global force and torque load on the chassis. exudyn's generalized-alpha satisfies the
    equations of motion at the step end, so the load must be the contact force of the step-end state: the
    pre-step function sets a predictor (the loads at the step start, extrapolated), the post-Newton function
    (exudyn's PostNewtonUserFunction, its discontinuous iteration, Flores & Ambrosio 2010) evaluates the
    contacts at the converged step end and repeats the step with those loads until they settle (an implicit
    contact force by fixed-point iteration; 1-2 extra passes in a contact step). Held at the step start, as
    before issue 10, the load lagged the penetration by one step and made energy in proportion to the step
    (elastic wall at 50 km/h: restitution 1.05; 200 km/h head-on +7.5 % kinetic energy). Equal and opposite
    loads: linear momentum is exchanged exactly.
    """

    name = "exudyn"
    compiles = "common"  # the shared chassis contact, compiled with numba (models/common)
    driver_inputs = True   # actions and friction zones (docs/physics.md §2a): see _Run._driver
    # the guard's interpenetration check compares rectangular outlines; the contact bodies here are
    # superellipsoids (2/eps = 4) whose rounded corners lie up to ~0.3 m inside the rectangle's: a car at rest
    # 3 cm from a barrier with its corner towards it "overlapped" by 0.26 m (stress scene random 2:17). The
    # model checks the end state with its own contact shapes instead (same tolerance, guard.PENETRATION_TOL).
    guard_skip = frozenset({"interpenetration"})

    class Options(ModelOptions):
        step: float = option(1e-3, "largest step of exudyn's generalized-alpha (shortened at contact onsets and "
                             "unsettled load iterations, then doubled back)", "s", accuracy="smaller", gt=0, le=0.01)
        spectral_radius: float = option(0.8, "generalized-alpha numerical damping at infinite frequency", "",
                                        ge=0, le=1)
        friction_zone: float = option(0.2, "rolling disc's linear friction zone: below this slip speed the tyre "
                                      "force is mu F_z v_slip / zone", "m/s", gt=0)
        record_dt: float = option(0.01, "trajectory sampling", "s", ge=0)
        v_rest: float = option(0.01, "chassis horizontal speed below which a vehicle counts as still", "m/s", gt=0)
        w_rest: float = option(0.01, "chassis yaw rate below which a vehicle counts as still", "rad/s", gt=0)
        t_sleep: float = option(0.2, "every chassis still this long, no contact open: the run stops", "s", ge=0)
        contact_law: Literal["structure", "generic"] = option(
            "structure", "chassis contact force: 'structure' = the vehicles' CRASH3 crush stiffness A + B C per "
            "unit of engaged width, the two structures in series, unloading to the scene's restitution "
            "(docs/physics.md §13a); 'generic' = K delta^n with the scene's force_law (§13)")
        contact_stiffness: float = option(1.35e6, "generic law: K of one vehicle against a rigid barrier; car-to-car "
                                          "pairs use K/2^1.5 for equal K (series Hertz springs)", "N/m^1.5", gt=0)
        contact_exponent: float = option(1.5, "generic law: n of F_N = K delta^n (1 + chi delta_dot / "
                                         "delta_dot0)", "", ge=1)
        v_min: float = option(1e-3, "smallest approach velocity delta_dot0 stored at onset", "m/s", gt=0)
        min_step: float = option(1e-6, "shortest step exudyn may take (below it the run fails with a reason)", "s",
                                 accuracy="smaller", gt=0)
        onset_tolerance: float = option(1e-3, "a step in which a contact (car-car, car-barrier, chassis-road) opens "
                                        "deeper than this is repeated shorter", "m", accuracy="smaller", gt=0)
        load_tolerance: float = option(1e-3, "the contact forces at the step end have settled when a pass changes "
                                       "them by less than this share of the largest (+ 10 N)", "",
                                       accuracy="smaller", gt=0, lt=1)

        @model_validator(mode="after")
        def _min_step_not_above_step(self):
            if self.min_step > self.step:
                raise ValueError("min_step: must be <= step")
            return self

    def simulate(self, scene) -> Outcome:
        t0 = time.perf_counter()
        names = scene.vehicle_names
        vehicles = build_scene_vehicles(scene)  # a vehicle the model cannot build is bad input (exit 2)
        try:
            return _Run(self.options.model_dump(), scene, vehicles).run(t0)
        except Exception as e:  # exudyn raises RuntimeError/ValueError when Newton fails or a state blows up
            return Outcome.failed(names, f"exudyn model: simulation failed: {type(e).__name__}: {e}", self.name,
                                  time.perf_counter() - t0)


class _Run:
    """One simulation: the exudyn system of a scene, the contact state and the records."""

    def __init__(self, opts, scene, vehicles):
        import exudyn as exu

        from .build import build_vehicle, set_locks, steer
        self.set_locks, self.steer = set_locks, steer
        self.exu = exu
        self.o = opts
        self.scene = scene
        self.names = scene.vehicle_names
        nv = self.nv = len(self.names)
        self.SC = exu.SystemContainer()
        mbs = self.mbs = self.SC.AddSystem()
        ground = mbs.CreateGround()
        self.vehs = vehicles
        # driver actions and friction zones (docs/physics.md §2a, common/driver_inputs.py)
        self.AT, self.nAT = DI.pack_action_tables(scene.vehicles)
        self.timed = np.array([len(vs.actions) > 0 for vs in scene.vehicles])
        self.zones = DI.pack_zones(scene.road) if scene.road.zones else None
        modes = [DI.action_modes(vs) for vs in scene.vehicles]
        self.items = [build_vehicle(mbs, ground, veh, vs, scene.road.friction, opts["friction_zone"], True, md)
                      for veh, vs, md in zip(self.vehs, scene.vehicles, modes)]
        self.mu_wheel = np.full((nv, NW), float(scene.road.friction))   # road friction under each wheel
        self.brake = np.zeros(nv)                                        # brake fraction b of each vehicle
        self.steer_now = np.array([vs.steer for vs in scene.vehicles], dtype=float)
        self.v_hub = np.zeros((nv, NW, 3))   # hub velocities at the last step start (brake: wheel inertia)
        self.t_hub = np.full((nv, NW), -math.inf)
        # rolling resistance and brake: a torque pair wheel/knuckle per wheel that turns (when either acts)
        self.wheel_torques = []
        for v, (veh, vs) in enumerate(zip(self.vehs, scene.vehicles)):
            fr = float(vs.spec.rolling_resistance)
            braked = BRAKED in modes[v] or bool((self.AT[v, :, DI.A_BRAKE_TO] > 0.0).any())
            if (fr > 0.0 or braked) and not self.items[v]["always_locked"]:
                it = self.items[v]
                for k in range(NW):
                    tw = mbs.CreateTorque(itemNumber=it["wheels"][k]["bodyNumber"], loadVector=[0.0, 0.0, 0.0],
                                          bodyFixed=False, show=False)
                    tk = mbs.CreateTorque(itemNumber=it["knuckles"][k]["bodyNumber"], loadVector=[0.0, 0.0, 0.0],
                                          bodyFixed=False, show=False)
                    radius = veh.TYR[k, T_R1] + veh.TYR[k, T_R2]
                    eta = veh.TYR[k, T_ETA]
                    self.wheel_torques.append((v, k, fr, eta, radius, tw, tk))
        # contact arrays, exactly as the multibody model prepares them
        imp = scene.impact
        self.cchi, self.mu_c = chi(imp.force_law, imp.restitution), imp.friction
        self.fcode = friction_code(imp.friction_law)
        self.CSH = CSH = np.array([v.chassis_shape for v in self.vehs])
        self.claw = float(C.CONTACT_LAWS.index(opts["contact_law"]))
        self.rest, why = clamp_restitution(imp.restitution)
        why = speed_law_setting(imp, opts["contact_law"], why)
        if imp.restitution_law == SPEED:  # the law at each pair's closing speed (chassis_contact, §13b)
            self.rest = E_SPEED_LAW
        self.law_warnings = [why] if why else []
        STR = []
        for veh, vs in zip(self.vehs, scene.vehicles):
            row, notes = structure_row(vs.spec)
            STR.append(row)
            veh.notes.extend(n for n in notes if n not in veh.notes)
        self.PP = C.pair_table(nv, len(scene.barriers), opts["contact_stiffness"], opts["contact_exponent"],
                               np.array(STR))
        self.CT = C.contact_arrays(CSH, self.PP, C.barrier_rows(scene.barriers), nv)
        # chassis-road contact (common/road_contact.py, as the multibody model): stiffness from each vehicle's
        # total mass, regularised Coulomb friction
        self.KR = R.stiffness([veh.mass for veh in self.vehs], R.N_ROAD)
        self.road_chi = R.road_chi()
        self.RSG = np.zeros((nv, R.N_RSG))
        self.Y = np.zeros((nv, 13))        # chassis state in the multibody layout: r, p, r_dot, w' (nq = 7)
        self.struck = [False] * nv   # first contact seen (locked_after_impact)
        self.struck_seen = [False] * nv
        self.timed = [bool(x) for x in self.timed]
        # vehicles whose wheel state, brake or steer can change in the run
        self.driven = [v for v in range(nv) if self.timed[v] or self.items[v]["locks"]]
        mbs.Assemble()
        # the chassis states for the contact code: exudyn's coordinate vectors (chassis_state.py)
        self.chassis_idx = np.array([mbs.GetNodeODE2Index(it["chassis"]["nodeNumber"]) for it in self.items],
                                    dtype=np.int64)
        self.q_ref = np.array(mbs.systemData.GetODE2Coordinates(configuration=exu.ConfigurationType.Reference))

    # ------------------------------------------------------------------ state access
    def _chassis(self, v):
        out = self.exu.OutputVariableType
        nd = self.items[v]["chassis"]["nodeNumber"]
        g = self.mbs.GetNodeOutput
        A = np.asarray(g(nd, out.RotationMatrix)).reshape(3, 3)
        r, vel, om = g(nd, out.Position), g(nd, out.Velocity), g(nd, out.AngularVelocity)
        return np.asarray(r), A, np.asarray(vel), np.asarray(om)

    def _pose(self, v):
        """(x, y, z, heading (continuous), roll, pitch, vx, vy, yaw_rate, vz): vehicle CG of all nine bodies,
        chassis angles (ZYX), CG velocity, chassis yaw rate (as multibody.integrator.pose)."""
        out = self.exu.OutputVariableType
        it = self.items[v]
        m = it["mass"]
        c = np.zeros(6)
        for b, nd in enumerate(it["nodes"]):
            c[:3] += m[b] * np.asarray(self.mbs.GetNodeOutput(nd, out.Position))
            c[3:] += m[b] * np.asarray(self.mbs.GetNodeOutput(nd, out.Velocity))
        c /= m.sum()
        r, A, vel, om = self._chassis(v)
        pitch = math.asin(max(-1.0, min(1.0, -A[2, 0])))
        roll = math.atan2(A[2, 1], A[2, 2])
        return (c[0], c[1], c[2], self.head[v], roll, pitch, c[3], c[4], om[2], c[5])

    def _energy(self, v):
        """Mechanical energy of vehicle v [J]: kinetic energy of its nine bodies (translation and rotation
        about their principal axes) and their height in gravity; the guard's measure for a tumbling car,
        whose planar energy alone trades with roll and pitch in free flight (docs/physics.md §19)."""
        out = self.exu.OutputVariableType
        g = self.mbs.GetNodeOutput
        e = 0.0
        for b, nd in enumerate(self.items[v]["nodes"]):
            m, inertia = self.vehs[v].BODY[b, 0], self.vehs[v].BODY[b, 1:4]
            A = np.asarray(g(nd, out.RotationMatrix)).reshape(3, 3)
            vel, om = np.asarray(g(nd, out.Velocity)), A.T @ np.asarray(g(nd, out.AngularVelocity))
            e += 0.5 * m * float(vel @ vel) + 0.5 * float(inertia @ (om * om)) \
                + m * G * float(np.asarray(g(nd, out.Position))[2])
        return e

    def _update_headings(self):
        for v in range(self.nv):
            A = self.chassisA[v]
            h = math.atan2(A[1, 0], A[0, 0])
            d = h - self.head[v]
            self.head[v] += math.atan2(math.sin(d), math.cos(d))

    def _contact_loads(self):
        """Read the chassis states exudyn holds now and evaluate every contact there: returns (FX (nv, 7):
        global force, moment about the chassis CG, power per chassis; the pairs' outputs psg; the road outputs
        RSG), all copies."""
        sd = self.mbs.systemData
        chassis_states(self.q_ref, sd.GetODE2Coordinates(), sd.GetODE2Coordinates_t(), self.chassis_idx, self.Y,
                       self.chassisA)
        CSH, BOXR, BOXA, BOXE, PP, PST, PSG, FX, BPC = self.CT
        psg = PSG[0]
        if PP.shape[0]:
            C.contacts(self.Y, 7, CSH, BOXR, BOXA, BOXE, PP, PST, psg, FX, BPC, self.o["contact_exponent"],
                       self.cchi, self.mu_c, self.fcode, FRICTION_V0, FRICTION_V1, FRICTION_VS, self.o["v_min"],
                       self.claw, self.rest)
        else:
            FX[:, :] = 0.0
        mu = self.scene.road.friction
        if self.zones is None:
            R.road_contacts(self.Y, 7, self.CSH, self.KR, R.N_ROAD, self.road_chi, mu,
                            R.ROAD_FRICTION_LAW, FRICTION_V0, FRICTION_V1, FRICTION_VS, FX, self.RSG)
        else:  # each chassis on the friction of the zone under its CG (§2a)
            for v in range(self.nv):
                mv = DI.road_friction(self.Y[v, 0], self.Y[v, 1], mu, *self.zones)
                w = slice(v, v + 1)
                R.road_contacts(self.Y[w], 7, self.CSH[w], self.KR[w], R.N_ROAD, self.road_chi, mv,
                                R.ROAD_FRICTION_LAW, FRICTION_V0, FRICTION_V1, FRICTION_VS, FX[w], self.RSG[w])
        return FX.copy(), psg.copy(), self.RSG.copy()

    def _apply(self, L):
        mbs = self.mbs
        for v in range(self.nv):
            it = self.items[v]
            mbs.SetLoadParameter(it["force"], "loadVector", L[v, 0:3].tolist())
            mbs.SetLoadParameter(it["torque"], "loadVector", L[v, 3:6].tolist())
        self.L = L

    # ------------------------------------------------------------------ one step: pre-step and post-Newton
    def prestep(self, mbs, t):
        """Start of an attempt of the step [s, t] (the state exudyn holds now is the one at s). A new s means the
        previous step was accepted: its contact bookkeeping is done here, with the loads at this state as its
        end values. The contact loads start at their value at s (the predictor of the step's iteration)."""
        s = mbs.systemData.GetTime(self.exu.ConfigurationType.StartOfStep)
        self.iter = 0
        if s != self.s_cur:
            F, psg, rsg = self._contact_loads()
            self._update_headings()
            if self.s_cur is not None:
                self._accept(self.s_cur, s, F, psg, rsg)
            # slope of the loads over the last step: the predictor extrapolates it (at most one last step on)
            self.dF, self.h_last = ((F - self.F0) / (s - self.s_cur), s - self.s_cur) if self.s_cur is not None \
                else (np.zeros_like(F), 0.0)
            self.s_cur, self.F0, self.psg0, self.rsg0 = s, F, psg, rsg
            self._driver(s, t)
            self._wheel_torques(mbs)
            if s >= self.t_rec - 1e-12:
                self._record(s)
                self.t_rec = s + self.o["record_dt"]
            self.awake = self._awake(s)
        self._apply((self.F0 + self.dF * min(t - s, self.h_last))[:, :6])
        return self.awake

    def postnewton(self, mbs, t):
        """After exudyn's Newton converged for [s, t]: the contact loads at t. The step is repeated with the
        trapezoidal load (F(s) + F(t)) / 2 until it changes by less than load_tolerance; it is repeated with a
        shorter step (exudyn's adaptive step) when a contact opens deeper than onset_tolerance or the load
        iteration does not settle in MAX_LOAD_ITER passes. Returns [error, recommended step] (exudyn's
        PostNewtonUserFunction; error > its discontinuous iterationTolerance repeats the step)."""
        o = self.o
        h = t - self.s_cur
        F1, psg1, rsg1 = self._contact_loads()
        can_shorten = h > 1.5 * o["min_step"]
        if can_shorten:
            d = self._onset_depth(psg1, rsg1)
            if d > o["onset_tolerance"]:
                self.n_shortened += 1
                return [BIG_ERROR, h * max(0.1, min(0.5, o["onset_tolerance"] / d))]
        L = F1[:, :6]
        # converged when the forces settle; the moments are not tested: on parallel flat faces the contact
        # point (a support point of the superellipsoid) moves across the face with the last digits of the
        # contact normal, so the moment changes from pass to pass without a trend
        err = float(np.abs(L[:, :3] - self.L[:, :3]).max()) if L.size else 0.0
        if err <= o["load_tolerance"] * max(float(np.abs(L[:, :3]).max()), 1.0) + LOAD_ABS_TOL:
            self.F1, self.psg1, self.rsg1 = F1, psg1, rsg1
            return [0.0, -1.0]
        self.iter += 1
        if self.iter >= MAX_LOAD_ITER:
            if can_shorten:
                self.n_shortened += 1
                return [BIG_ERROR, 0.5 * h]
            self.n_unsettled += 1      # at min_step: exudyn accepts the step after its last iteration
        self.n_load_iter += 1
        self._apply(L)
        return [max(err, BIG_ERROR), -1.0]

    def _onset_depth(self, psg1, rsg1):
        """Deepest penetration of a contact not yet open (pairs, road)."""
        PST = self.CT[5]
        d = 0.0
        for p in range(PST.shape[0]):
            if PST[p, C.S_ACT] == 0.0:
                d = max(d, psg1[p, C.G_DEL])
        for v in range(self.nv):
            if not self.road_on[v]:
                d = max(d, rsg1[v, R.R_DEL])
        return d

    def _driver(self, s, t):
        """Driver actions and friction zones for the step [s, t] (docs/physics.md §2a), read at its middle
        from common/driver_inputs: the wheel state (locked_after_impact through effective_mode with the
        vehicle's first contact) switches the spin locks, the steer angle turns the knuckles (Ackermann angles
        of vehicle_3d.steer_angles), the brake fraction goes to _wheel_torques; each wheel's road friction
        is that of the zones at its contact point half a step on (the predicted middle of the step), set as
        the rolling disc's dry friction and held over the step."""
        tm = 0.5 * (s + t)
        for v in self.driven:
            it = self.items[v]
            # without actions the wheel state changes at most once, at the first contact
            if not self.timed[v] and self.struck[v] == self.struck_seen[v]:
                continue
            self.struck_seen[v] = self.struck[v]
            mode, b, st = DI.driver_inputs(self.AT[v], self.nAT[v], tm)
            mode = DI.effective_mode(mode, self.struck[v])
            self.mode[v], self.brake[v] = mode, b
            lock = mode == LOCKED
            if it["locks"] and lock != self.locked[v]:
                self.set_locks(self.mbs, it, lock)
                self.locked[v] = lock
            if st != self.steer_now[v]:
                self.steer(self.mbs, it, steer_angles(self.vehs[v], st))
                self.steer_now[v] = st
        if self.zones is None:
            return
        out = self.exu.OutputVariableType
        g = self.mbs.GetNodeOutput
        mu_road = self.scene.road.friction
        for v in range(self.nv):
            it = self.items[v]
            for k in range(NW):
                nw = it["wheels"][k]["nodeNumber"]
                r, vel = g(nw, out.Position), g(nw, out.Velocity)
                mu = DI.road_friction(r[0] + vel[0] * (t - s) / 2, r[1] + vel[1] * (t - s) / 2, mu_road,
                                      *self.zones)
                if mu != self.mu_wheel[v, k]:
                    self.mbs.SetObjectParameter(it["discs"][k], "dryFriction", [mu, mu])
                    self.mu_wheel[v, k] = mu

    def _wheel_torques(self, mbs):
        """Rolling resistance and brake moments (common/tyre_moments.py) against the wheel's spin relative to
        its knuckle, with the tyre's radius as the arm, held over the step. `braked`: the UA tyre's brake
        moment (eta of the locking torque, as before actions existed); a brake fraction b on a rolling wheel
        (§2a): b times the friction left beside the lateral force, b R sqrt((mu F_z)^2 - F_y^2), the rolling
        resistance its floor."""
        if not self.wheel_torques:
            return
        out = self.exu.OutputVariableType
        g = self.mbs.GetNodeOutput
        for v, k, fr, eta, radius, tw, tk in self.wheel_torques:
            it = self.items[v]
            mode, b = self.mode[v], self.brake[v]
            if self.locked[v] or (fr == 0.0 and mode != BRAKED and b == 0.0):
                M = np.zeros(3)
            else:
                mu = self.mu_wheel[v, k]
                nw, nk = it["wheels"][k]["nodeNumber"], it["knuckles"][k]["nodeNumber"]
                Aw = np.asarray(g(nw, out.RotationMatrix)).reshape(3, 3)
                axis = Aw[:, 1]
                w_rel = float((np.asarray(g(nw, out.AngularVelocity)) - np.asarray(g(nk, out.AngularVelocity)))
                              @ axis)
                f = mbs.GetObjectOutput(it["discs"][k], out.ForceLocal)
                fz = max(float(f[2]), 0.0)
                m = rolling_resistance_moment(fr, fz, radius, w_rel)
                if mode == BRAKED:
                    m += brake_moment(eta, mu, fz, radius, w_rel)
                elif b > 0.0:
                    fy = float(f[FY_LOCAL])
                    mb = brake_moment(b, 1.0, math.sqrt(max((mu * fz) ** 2 - fy * fy, 0.0)), radius, w_rel)
                    # the share of the brake moment that decelerates the wheel's own spin, I_yy a_fwd / R
                    # (a_fwd: the hub's acceleration over the last step): the road force is then b times the
                    # friction left, not 2 % less (a Clio wheel's I_yy / R^2 = 4.7 kg)
                    vel = np.asarray(g(nw, out.Velocity))
                    fwd = np.cross(axis, (0.0, 0.0, 1.0))
                    dt = self.s_cur - self.t_hub[v, k]     # a hub velocity of the previous step only
                    a_fwd = float((vel - self.v_hub[v, k]) @ fwd) / dt if 0.0 < dt <= 1.5 * self.o["step"] else 0.0
                    self.v_hub[v, k], self.t_hub[v, k] = vel, self.s_cur
                    mb += self.vehs[v].BODY[5 + k, 2] * a_fwd / radius * math.tanh(abs(w_rel) / OMEGA_BRAKE)
                    m = mb if abs(mb) > abs(m) else m
                M = m * axis
            mbs.SetLoadParameter(tw, "loadVector", M.tolist())
            mbs.SetLoadParameter(tk, "loadVector", (-M).tolist())

    def _accept(self, s, t, F1, psg1, rsg1):
        """Bookkeeping of the accepted step [s, t] (common/contact_episodes.py, as multibody's integrator):
        episodes open at the first penetration (delta_dot0 stored, onset time interpolated in the step), close at
        separation; impulse of the applied (trapezoidal) load, work by the trapezoidal rule of the contact power,
        peak force and penetration at both ends. Road contacts: their intervals only (contact_intervals)."""
        h = t - s
        self.nsteps += 1
        self.h_min_used = min(self.h_min_used, h)
        CSH, BOXR, BOXA, BOXE, PP, PST, PSG, FX, BPC = self.CT
        psg0 = self.psg0
        for p in range(PP.shape[0]):
            i, j = int(PP[p, C.P_I]), int(PP[p, C.P_J])
            d0, d1 = psg0[p, C.G_DEL], psg1[p, C.G_DEL]
            if PST[p, C.S_ACT] == 0.0:
                if d1 <= 0.0:
                    continue
                EP.reset_sums(PST, p)
                EP.open_episode(PST, p, s + h * min(max(-d0 / (d1 - d0), 0.0), 1.0),
                                max(psg1[p, C.G_DDOT], self.o["v_min"]), self._velocity(i), self._velocity(j))
                self.max_onset = max(self.max_onset, d1)
                if math.isnan(self.contact_time):
                    self.contact_time = PST[p, C.S_T0]
                    for v in range(self.nv):
                        pv = self._pose(v)
                        self.contact[v] = [pv[0], pv[1], pv[3], math.hypot(pv[6], pv[7])]
                for v in (i, j):
                    if v < self.nv:
                        self.struck[v] = True   # locked_after_impact locks in the next pre-step (_driver)
            for q in (psg0, psg1):
                EP.accumulate(PST, p, 0.5 * h, q[p])
                EP.track_peak(PST, p, q[p])
            if d1 <= 0.0:
                t1 = s + h * min(max(d0 / (d0 - d1), 0.0), 1.0) if d0 > 0.0 else s
                self._close(p, t1, 0.0, psg1)
        for v in range(self.nv):
            on = rsg1[v, R.R_DEL] > 0.0
            if on and not self.road_on[v]:
                d0, d1 = self.rsg0[v, R.R_DEL], rsg1[v, R.R_DEL]
                self.road_t0[v] = s + h * min(max(-d0 / (d1 - d0), 0.0), 1.0)
                self.road_contacts += 1
            elif self.road_on[v] and not on:
                self.intervals.append((self.road_t0[v], t))
            self.road_on[v] = on
            self.road_pen = max(self.road_pen, rsg1[v, R.R_DEL])

    def _velocity(self, v):
        """(vx, vy, yaw rate) of vehicle v's CG; zeros for a barrier (v >= number of vehicles)."""
        if v >= self.nv:
            return (0.0, 0.0, 0.0)
        p = self._pose(v)
        return (float(p[6]), float(p[7]), float(p[8]))

    def _close(self, p, s, is_open, psg):
        PP, PST = self.CT[4], self.CT[5]
        self.intervals.append((PST[p, C.S_T0], s))
        self.n_episodes = EP.close_episode(self.IMP, self.n_episodes, PP, PST, p, s, psg[p, C.G_DDOT], is_open,
                                           self._velocity(int(PP[p, C.P_I])), self._velocity(int(PP[p, C.P_J])))

    def _record(self, s):
        for v in range(self.nv):
            self.traj[v].append((s,) + tuple(self._pose(v)) + (self.RSG[v, R.R_ZMIN], self._energy(v)))

    def _awake(self, s):
        """False (stop after this step) once every chassis has been still for t_sleep and no contact is open."""
        if not self.scene.stop_at_rest:
            return True
        PST = self.CT[5]
        active = bool(PST.shape[0]) and bool((PST[:, C.S_ACT] > 0.0).any())
        still = not active and all(math.hypot(self.Y[v, 7], self.Y[v, 8]) < self.o["v_rest"]
                                   and abs((self.chassisA[v] @ self.Y[v, 10:13])[2]) < self.o["w_rest"]
                                   for v in range(self.nv))
        if not still:
            self.t_still = None
            return True
        if self.t_still is None:
            self.t_still = s
        return s - self.t_still < self.o["t_sleep"]

    # ------------------------------------------------------------------ the run
    def run(self, t0):
        exu, mbs, o, scene = self.exu, self.mbs, self.o, self.scene
        nv = self.nv
        self.head = np.array([vs.heading for vs in scene.vehicles], dtype=float)
        self.chassisA = np.tile(np.eye(3), (nv, 1, 1))
        self.locked = np.array([vs.wheels == "locked" for vs in scene.vehicles])
        self.mode = np.array([DI.effective_mode(DI.WHEEL_CODES[vs.wheels], False) for vs in scene.vehicles])
        self.contact = np.full((nv, 4), np.nan)
        self.contact_time = math.nan
        self.traj = [[] for _ in range(nv)]
        self.IMP, self.n_episodes, self.intervals = np.zeros((EP.MAX_IMP, EP.N_IMP)), 0, []
        self.t_rec, self.t_still, self.nsteps = 0.0, None, 0
        self.max_onset = self.road_pen = 0.0
        self.s_cur, self.awake, self.iter = None, True, 0
        self.n_load_iter = self.n_shortened = self.road_contacts = self.n_unsettled = 0
        self.h_min_used = math.inf
        self.road_on = np.zeros(nv, dtype=bool)
        self.road_t0 = np.zeros(nv)
        ss = exu.SimulationSettings()
        ti = ss.timeIntegration
        ti.endTime = scene.duration
        ti.numberOfSteps = max(1, int(round(scene.duration / o["step"])))
        ti.generalizedAlpha.spectralRadius = o["spectral_radius"]
        ti.verboseMode = 0
        ss.solution.file.write = False
        ss.show.statistics = False
        ss.show.computationTime = False
        # 9 bodies per car couple only through their joints: the sparse solver halves the run time
        # against exudyn's default dense one (side collision 1.93 -> 1.02 s, identical rest poses)
        ss.linearSolver.solverType = exu.LinearSolverType.EigenSparse
        # step: `step` at most; exudyn's adaptive step shortens it when postnewton asks (contact onset, a load
        # iteration that does not settle) or Newton fails, and doubles it again after ADAPT_RECOVERY steps
        ti.adaptiveStep = True
        ti.minimumStepSize = o["min_step"]
        ti.adaptiveStepRecoverySteps = ADAPT_RECOVERY
        ti.adaptiveStepRecoveryIterations = 1000
        ti.discontinuous.useRecommendedStepSize = True
        self.o = dict(o, step=scene.duration / ti.numberOfSteps)
        mbs.SetPreStepUserFunction(self.prestep)
        mbs.SetPostNewtonUserFunction(self.postnewton)
        warnings, ok = list(self.law_warnings), True
        import exudyn.solver
        # the pre-step function allocates (numpy) every step by design: exudyn's allocation-count warning
        # would be printed on every run (exudyn 1.13 checks only the threshold, not the flag)
        exudyn.solver.solverCheckMemoryAllocations = False
        exudyn.solver.solverCheckMemoryAllocationsThreshold = float("inf")
        solved = mbs.SolveDynamic(ss)
        t_end = float(mbs.systemData.GetTime())
        if solved is False:
            ok = False
            warnings.append(f"exudyn's solver stopped at t = {t_end:.4f} s (Newton did not converge)")
        # the last step: its bookkeeping, close open contacts, last record
        F, psg, rsg = self._contact_loads()
        self._update_headings()
        if self.s_cur is not None and t_end > self.s_cur:
            self._accept(self.s_cur, t_end, F, psg, rsg)
        PST = self.CT[5]
        for p in range(self.PP.shape[0]):
            if PST[p, C.S_ACT] > 0.0:
                self._close(p, t_end, 1.0, psg)
        if self.rest == E_SPEED_LAW:
            warnings += C.speed_law_warnings(PST)
        for v in range(nv):
            if self.road_on[v]:
                self.intervals.append((self.road_t0[v], t_end))
        overlap = C.end_overlap(self.names, self.PP, psg)
        self._record(t_end)
        rest, final = np.zeros((nv, 3)), np.zeros((nv, 3))
        trajectories = {}
        keys = ("t", "x", "y", "z", "heading", "roll", "pitch", "vx", "vy", "yaw_rate", "vz", "z_min", "energy")
        for v, n in enumerate(self.names):
            p = self._pose(v)
            rest[v] = [p[0], p[1], p[3]]
            final[v] = [p[6], p[7], p[8]]
            arr = np.array(self.traj[v], dtype=float)
            trajectories[n] = {k: arr[:, c].copy() for c, k in enumerate(keys)}
        if not np.all(np.isfinite(rest)):
            ok = False
            warnings.append("the state became NaN")
        mass = np.array([it["mass"].sum() for it in self.items])
        heads = [(trajectories[n]["t"], trajectories[n]["heading"]) for n in self.names]
        rows = EP.impact_rows(self.names, mass, self.IMP[:min(self.n_episodes, EP.MAX_IMP)].copy(), heads)
        if any(r["open"] for r in rows):
            warnings.append("a contact was still active at the end of the run")
        if self.n_unsettled:
            ok = False
            warnings.append(f"the contact loads did not settle at the shortest step ({o['min_step']:g} s) in "
                            f"{self.n_unsettled} step(s)")
        if self.n_episodes > EP.MAX_IMP:
            warnings.append(f"more than {EP.MAX_IMP} contact episodes: only the first {EP.MAX_IMP} are reported")
        try:
            it = mbs.sys["dynamicSolver"].it
            newton, disc = int(it.newtonStepsCount), int(it.discontinuousIterationsCount)
        except Exception:  # the solver's statistics are a convenience; their layout is not a stable API
            newton = disc = -1
        fz = exu.OutputVariableType.ForceLocal
        loads = {n: [float(mbs.GetObjectOutput(d, fz)[2]) for d in self.items[v]["discs"]]
                 for v, n in enumerate(self.names)}
        diagnostics = {"steps": self.nsteps, "wheel_loads_final": loads, "wheel_order": list(CORNERS),
                       "step_size": self.o["step"], "min_step_used": self.h_min_used,
                       "newton_iterations": newton, "discontinuous_iterations": disc,
                       "load_iterations": self.n_load_iter, "rejected_steps": self.n_shortened,
                       "t_end": t_end, "episodes": self.n_episodes,
                       "road_contacts": self.road_contacts, "max_road_penetration": self.road_pen,
                       "max_onset_penetration": self.max_onset,
                       # the largest overlap of the undeformed shapes in contact, the dynamic crush under the
                       # structure law (S_MAXPEN of the episodes, as multibody), not G_DEL: that is the crush
                       # beyond the permanent set, only the elastic part (0.02 m of NHTSA 10146's 0.56 m)
                       "max_penetration": float(self.IMP[:min(self.n_episodes, EP.MAX_IMP), EP.I_MAXPEN].max(
                           initial=0.0)),
                       "vehicle_notes": {n: self.vehs[v].notes for v, n in enumerate(self.names)},
                       "solver": "exudyn generalized-alpha (index 3), adaptive step, trapezoidal contact loads"}
        wall = time.perf_counter() - t0
        out = Outcome(self.names, rest, final, self.contact, self.contact_time, trajectories, rows, diagnostics,
                      warnings, ok, "exudyn", wall, contact_intervals=sorted(self.intervals))
        if ok and overlap is not None:
            out.fail("interpenetration", overlap)
        return out
