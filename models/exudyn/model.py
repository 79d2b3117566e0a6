"""Model `exudyn`: the multibody model's 9-body vehicle built in exudyn (build.py), with the multibody model's
chassis contact (geometry, gap search, force law: crashlab.models.multibody.contact) applied as loads.

exudyn is imported only here and in build.py, inside `simulate` (the registry imports this module only when
the model is asked for; `import crashlab.models.exudyn` itself does not import exudyn).
"""
from __future__ import annotations

import math
import time

import numpy as np

from crashlab.model import CollisionModel
from crashlab.models.multibody import contact as C
from crashlab.models.multibody.contact_force import _fcode, chi
from crashlab.models.multibody.euler_parameters import from_matrix
from crashlab.models.multibody.model import FRICTION_V0, FRICTION_V1, FRICTION_VS, _contact_arrays, impact_rows
from crashlab.models.multibody.tyre import OMEGA_BRAKE, OMEGA_RR, T_ETA, T_R1, T_R2
from crashlab.models.multibody.vehicle_build import NW, build
from crashlab.outcome import Outcome


class ExudynModel(CollisionModel):
    """The multibody model's vehicle (9 rigid bodies, joints, suspension) built with exudyn's items, exudyn's
    rolling-disc penalty tyre, and the multibody model's chassis contact applied as loads.

    Options (documented defaults, the same for every scene):
      step = 1e-3 s              fixed step of exudyn's generalized-alpha (implicit, index 3). Not limited by
                                 stability (implicit; the contact load is explicit but its stiffest car-to-car
                                 mode, ~30 rad/s at 0.3 m crush, needs only h < 0.07 s): it is chosen for the
                                 contact, which the loads see once per step: a 14 m/s approach then starts
                                 with at most 14 mm penetration and the 0.17-0.31 s contacts of the
                                 PC-Crash cases get 170-310 force samples (2e-3 s changes post-impact
                                 speeds by < 0.3 km/h, README).
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
      contact_stiffness = 1.35e6 N/m^1.5   K of one vehicle against a rigid barrier; car-to-car pairs use
                                 K/2^1.5 for equal K (series Hertz springs), the multibody model's default
      contact_exponent = 1.5     n of F_N = K delta^n (1 + chi delta_dot / delta_dot0)
      v_min = 0.001 m/s          smallest approach velocity delta_dot0 stored at onset (multibody default)

    Tyre: exudyn's `CreateRollingDiscPenalty` (an infinitely thin disc of radius r1 + r2 on the plane z = 0)
    instead of our UA tyre. Normal force K_z delta + C_z delta_dot with K_z and C_z of vehicle_build (the
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

    Wheels: rolling (revolute joint), locked (generic joint, all six axes), locked_after_impact (revolute
    joint + a spin-lock generic joint activated at the vehicle's first contact), braked (revolute joint +
    the brake moment above).
    Steer: the knuckles are built at the Ackermann angles of vehicle_build.steer_angles (constant).

    Contact: each step, before exudyn integrates it, the chassis poses are read and the multibody model's
    numba `contact.contacts` (superellipsoid chassis, horizontal gap search, normal_force_chi with the scene's
    force_law and restitution, the scene's friction law and impact friction) gives the force and moment on
    each chassis; they are written into a global force and torque load on the chassis and held over the step
    (an explicit, first-order coupling; equal and opposite, so linear momentum is exchanged exactly).
    """

    name = "exudyn"

    def __init__(self, step=1e-3, spectral_radius=0.8, friction_zone=0.2, record_dt=0.01, v_rest=0.01,
                 w_rest=0.01, t_sleep=0.2, contact_stiffness=1.35e6, contact_exponent=1.5, v_min=1e-3):
        vals = dict(step=step, spectral_radius=spectral_radius, friction_zone=friction_zone, record_dt=record_dt,
                    v_rest=v_rest, w_rest=w_rest, t_sleep=t_sleep, contact_stiffness=contact_stiffness,
                    contact_exponent=contact_exponent, v_min=v_min)
        for k, v in vals.items():
            if isinstance(v, bool) or not isinstance(v, (int, float)):
                raise TypeError(f"exudyn model: option {k} must be a number, got {type(v).__name__}")
        if not (0 < step <= 0.01 and 0 <= spectral_radius <= 1 and friction_zone > 0 and record_dt >= 0
                and v_rest > 0 and w_rest > 0 and t_sleep >= 0 and contact_stiffness > 0
                and contact_exponent >= 1 and v_min > 0):
            raise ValueError("exudyn model: invalid option value (need 0 < step <= 0.01, 0 <= spectral_radius <= 1, "
                             "friction_zone, v_rest, w_rest, contact_stiffness, v_min > 0, contact_exponent >= 1)")
        self.opts = {k: float(v) for k, v in vals.items()}

    def get_options(self):
        return dict(self.opts)

    def simulate(self, scene) -> Outcome:
        t0 = time.perf_counter()
        names = scene.vehicle_names
        try:
            return _Run(self.opts, scene).run(t0)
        except Exception as e:  # exudyn raises RuntimeError/ValueError when Newton fails or a state blows up
            return Outcome.failed(names, f"exudyn model: simulation failed: {type(e).__name__}: {e}", self.name,
                                  time.perf_counter() - t0)


class _Run:
    """One simulation: the exudyn system of a scene, the contact state and the records."""

    def __init__(self, opts, scene):
        import exudyn as exu

        from .build import build_vehicle
        self.exu = exu
        self.o = opts
        self.scene = scene
        self.names = scene.vehicle_names
        nv = self.nv = len(self.names)
        self.SC = exu.SystemContainer()
        mbs = self.mbs = self.SC.AddSystem()
        ground = mbs.CreateGround()
        self.vehs = [build(vs.spec) for vs in scene.vehicles]
        self.items = [build_vehicle(mbs, ground, veh, vs, scene.road.friction, opts["friction_zone"], True)
                      for veh, vs in zip(self.vehs, scene.vehicles)]
        # rolling resistance and brake: a torque pair wheel/knuckle per wheel that turns (when either acts)
        self.wheel_torques = []
        for v, (veh, vs) in enumerate(zip(self.vehs, scene.vehicles)):
            fr = float(vs.spec.rolling_resistance)
            braked = vs.wheels == "braked"
            if (fr > 0.0 or braked) and vs.wheels != "locked":
                it = self.items[v]
                for k in range(NW):
                    tw = mbs.CreateTorque(itemNumber=it["wheels"][k]["bodyNumber"], loadVector=[0.0, 0.0, 0.0],
                                          bodyFixed=False, show=False)
                    tk = mbs.CreateTorque(itemNumber=it["knuckles"][k]["bodyNumber"], loadVector=[0.0, 0.0, 0.0],
                                          bodyFixed=False, show=False)
                    radius = veh.TYR[k, T_R1] + veh.TYR[k, T_R2]
                    fb = veh.TYR[k, T_ETA] * scene.road.friction if braked else 0.0
                    self.wheel_torques.append((v, k, fr * radius, fb * radius, tw, tk))
        # contact arrays, exactly as the multibody model prepares them
        imp = scene.impact
        self.cchi, self.mu_c, self.fcode = chi(imp.force_law, imp.restitution), imp.friction, _fcode(imp.friction_law)
        CSH = np.array([v.chassis_shape for v in self.vehs])
        Kv, n = opts["contact_stiffness"], opts["contact_exponent"]
        pairs = [(i, j, (Kv ** (-1 / n) + Kv ** (-1 / n)) ** (-n)) for i in range(nv) for j in range(i + 1, nv)]
        pairs += [(i, nv + k, Kv) for i in range(nv) for k in range(len(scene.barriers))]
        self.PP = np.array(pairs, dtype=float).reshape(-1, C.N_PP)
        BAR = np.array([[b.x, b.y, b.heading, b.length / 2, b.width / 2] for b in scene.barriers]).reshape(-1, 5)
        self.CT = _contact_arrays(CSH, self.PP, BAR, nv)
        self.Y = np.zeros((nv, 13))        # chassis state in the multibody layout: r, p, r_dot, w' (nq = 7)
        self.lock_pending = np.array([vs.wheels == "locked_after_impact" for vs in scene.vehicles])
        mbs.Assemble()

    # ------------------------------------------------------------------ state access
    def _chassis(self, v):
        out = self.exu.OutputVariableType
        nd = self.items[v]["chassis"]["nodeNumber"]
        g = self.mbs.GetNodeOutput
        A = np.asarray(g(nd, out.RotationMatrix)).reshape(3, 3)
        r, vel, om = g(nd, out.Position), g(nd, out.Velocity), g(nd, out.AngularVelocity)
        return np.asarray(r), A, np.asarray(vel), np.asarray(om)

    def _pose(self, v):
        """(x, y, z, heading (continuous), roll, pitch, vx, vy, yaw_rate): vehicle CG of all nine bodies,
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
        return (c[0], c[1], c[2], self.head[v], roll, pitch, c[3], c[4], om[2])

    def _update_headings(self):
        for v in range(self.nv):
            A = self.chassisA[v]
            h = math.atan2(A[1, 0], A[0, 0])
            d = h - self.head[v]
            self.head[v] += math.atan2(math.sin(d), math.cos(d))

    # ------------------------------------------------------------------ one step (pre-step user function)
    def prestep(self, mbs, t):
        h = self.o["step"]
        s = t - h                                   # the state exudyn holds now is the one at the step start
        self.nsteps += 1
        for v in range(self.nv):
            r, A, vel, om = self._chassis(v)
            self.chassisA[v] = A
            y = self.Y[v]
            y[0:3] = r
            y[3:7] = from_matrix(A)
            y[7:10] = vel
            y[10:13] = A.T @ om
        self._update_headings()
        CSH, BOXR, BOXA, BOXE, PP, PST, PSG, FX, BPC = self.CT
        psg = PSG[0]
        if PP.shape[0]:
            C.contacts(self.Y, 7, CSH, BOXR, BOXA, BOXE, PP, PST, psg, FX, BPC, self.o["contact_exponent"],
                       self.cchi, self.mu_c, self.fcode, FRICTION_V0, FRICTION_V1, FRICTION_VS, self.o["v_min"])
        for v in range(self.nv):
            it = self.items[v]
            mbs.SetLoadParameter(it["force"], "loadVector", FX[v, 0:3].tolist())
            mbs.SetLoadParameter(it["torque"], "loadVector", FX[v, 3:6].tolist())
        self._wheel_torques(mbs)
        self._episodes(s, h)
        if s >= self.t_rec - 1e-12:
            self._record(s)
            self.t_rec = s + self.o["record_dt"]
        return self._awake(s)

    def _wheel_torques(self, mbs):
        """Rolling resistance f_r F_z R tanh(w / OMEGA_RR) and brake eta mu F_z R tanh(w / OMEGA_BRAKE) against
        the wheel's spin w relative to its knuckle (multibody tyre.py), held over the step."""
        if not self.wheel_torques:
            return
        out = self.exu.OutputVariableType
        g = self.mbs.GetNodeOutput
        for v, k, fr_r, fb_r, tw, tk in self.wheel_torques:
            it = self.items[v]
            if self.locked[v]:
                M = np.zeros(3)
            else:
                nw, nk = it["wheels"][k]["nodeNumber"], it["knuckles"][k]["nodeNumber"]
                Aw = np.asarray(g(nw, out.RotationMatrix)).reshape(3, 3)
                axis = Aw[:, 1]
                w_rel = float((np.asarray(g(nw, out.AngularVelocity)) - np.asarray(g(nk, out.AngularVelocity)))
                              @ axis)
                fz = max(float(mbs.GetObjectOutput(it["discs"][k], out.ForceLocal)[2]), 0.0)
                M = -fz * (fr_r * math.tanh(w_rel / OMEGA_RR) + fb_r * math.tanh(w_rel / OMEGA_BRAKE)) * axis
            mbs.SetLoadParameter(tw, "loadVector", M.tolist())
            mbs.SetLoadParameter(tk, "loadVector", (-M).tolist())

    def _episodes(self, s, h):
        """Contact episodes (as multibody.integrator): open at the first penetration (delta_dot0 stored), close
        at separation; accumulate impulse, work, peak force and penetration of the load held over [s, s+h]."""
        CSH, BOXR, BOXA, BOXE, PP, PST, PSG, FX, BPC = self.CT
        psg = PSG[0]
        for p in range(PP.shape[0]):
            i, j = int(PP[p, C.P_I]), int(PP[p, C.P_J])
            d = psg[p, C.G_DEL]
            if PST[p, C.S_ACT] == 0.0 and d > 0.0:
                PST[p, C.S_ACT] = 1.0
                PST[p, C.S_DD0] = max(psg[p, C.G_DDOT], self.o["v_min"])
                PST[p, C.S_T0] = s
                PST[p, C.S_JX:C.S_WORK + 1] = 0.0
                self.max_onset = max(self.max_onset, d)
                PST[p, C.S_VI:C.S_VI + 3] = [self._pose(i)[q] for q in (6, 7, 8)]
                if j < self.nv:
                    PST[p, C.S_VJ:C.S_VJ + 3] = [self._pose(j)[q] for q in (6, 7, 8)]
                if math.isnan(self.contact_time):
                    self.contact_time = s
                    for v in range(self.nv):
                        pv = self._pose(v)
                        self.contact[v] = [pv[0], pv[1], pv[3], math.hypot(pv[6], pv[7])]
                for v in (i, j):
                    if v < self.nv and self.lock_pending[v]:
                        from .build import lock
                        lock(self.mbs, self.items[v])
                        self.lock_pending[v] = False
                        self.locked[v] = True
            elif PST[p, C.S_ACT] > 0.0 and d <= 0.0:
                self._close(p, s, 0.0)
            if PST[p, C.S_ACT] > 0.0:
                PST[p, C.S_JX] += h * psg[p, C.G_FX]
                PST[p, C.S_JX + 1] += h * psg[p, C.G_FY]
                PST[p, C.S_JX + 2] += h * psg[p, C.G_FZ]
                PST[p, C.S_WORK] += h * psg[p, C.G_POW]
                if psg[p, C.G_FN] > PST[p, C.S_PEAK]:
                    PST[p, C.S_PEAK] = psg[p, C.G_FN]
                    PST[p, C.S_PX], PST[p, C.S_PY], PST[p, C.S_PTH] = psg[p, C.G_PX], psg[p, C.G_PY], psg[p, C.G_TH]
                PST[p, C.S_MAXPEN] = max(PST[p, C.S_MAXPEN], d)
                self.max_pen = max(self.max_pen, d)

    def _close(self, p, s, is_open):
        CSH, BOXR, BOXA, BOXE, PP, PST, PSG, FX, BPC = self.CT
        i, j = int(PP[p, C.P_I]), int(PP[p, C.P_J])
        r = np.zeros(C.N_IMP)
        r[C.I_I], r[C.I_J], r[C.I_T0], r[C.I_T1] = i, j, PST[p, C.S_T0], s
        r[C.I_JX:C.I_JX + 3] = PST[p, C.S_JX:C.S_JX + 3]
        r[C.I_PEAK], r[C.I_MAXPEN], r[C.I_ENERGY] = PST[p, C.S_PEAK], PST[p, C.S_MAXPEN], -PST[p, C.S_WORK]
        r[C.I_PX], r[C.I_PY], r[C.I_TH] = PST[p, C.S_PX], PST[p, C.S_PY], PST[p, C.S_PTH]
        pi = self._pose(i)
        r[C.I_DVI:C.I_DVI + 3] = [pi[6] - PST[p, C.S_VI], pi[7] - PST[p, C.S_VI + 1], pi[8] - PST[p, C.S_VI + 2]]
        if j < self.nv:
            pj = self._pose(j)
            r[C.I_DVJ:C.I_DVJ + 3] = [pj[6] - PST[p, C.S_VJ], pj[7] - PST[p, C.S_VJ + 1],
                                      pj[8] - PST[p, C.S_VJ + 2]]
        r[C.I_DD0], r[C.I_DD1], r[C.I_OPEN] = PST[p, C.S_DD0], PSG[0][p, C.G_DDOT], is_open
        if len(self.imp) < C.MAX_IMP:
            self.imp.append(r)
        self.n_episodes += 1
        PST[p, C.S_ACT] = 0.0
        PST[p, C.S_JX:C.S_WORK + 1] = 0.0

    def _record(self, s):
        for v in range(self.nv):
            self.traj[v].append((s,) + tuple(self._pose(v)))

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
        self.chassisA = [np.eye(3) for _ in range(nv)]
        self.locked = np.array([vs.wheels == "locked" for vs in scene.vehicles])
        self.contact = np.full((nv, 4), np.nan)
        self.contact_time = math.nan
        self.traj = [[] for _ in range(nv)]
        self.imp, self.n_episodes = [], 0
        self.t_rec, self.t_still, self.nsteps = 0.0, None, 0
        self.max_onset = self.max_pen = 0.0
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
        # the step is fixed: no automatic step-size change (the contact load is held over one step of known size)
        ti.adaptiveStep = False
        self.o = dict(o, step=scene.duration / ti.numberOfSteps)
        mbs.SetPreStepUserFunction(self.prestep)
        warnings, ok = [], True
        import exudyn.solver
        # the pre-step function allocates (numpy) every step by design: exudyn's allocation-count warning
        # would be printed on every run
        exudyn.solver.solverCheckMemoryAllocations = False
        solved = mbs.SolveDynamic(ss)
        t_end = float(mbs.systemData.GetTime())
        if solved is False:
            ok = False
            warnings.append(f"exudyn's solver stopped at t = {t_end:.4f} s (Newton did not converge)")
        # final state: close open contacts, last record
        for v in range(nv):
            self.chassisA[v] = self._chassis(v)[1]
        self._update_headings()
        PST = self.CT[5]
        for p in range(self.PP.shape[0]):
            if PST[p, C.S_ACT] > 0.0:
                self._close(p, t_end, 1.0)
        self._record(t_end)
        rest, final = np.zeros((nv, 3)), np.zeros((nv, 3))
        trajectories = {}
        keys = ("t", "x", "y", "z", "heading", "roll", "pitch", "vx", "vy", "yaw_rate")
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
        rows = impact_rows(self.names, mass, np.array(self.imp).reshape(-1, C.N_IMP), heads)
        if any(r["open"] for r in rows):
            warnings.append("a contact was still active at the end of the run")
        if self.n_episodes > C.MAX_IMP:
            warnings.append(f"more than {C.MAX_IMP} contact episodes: only the first {C.MAX_IMP} are reported")
        try:
            newton = int(mbs.sys["dynamicSolver"].it.newtonStepsCount)
        except Exception:  # the solver's statistics are a convenience; their layout is not a stable API
            newton = -1
        fz = exu.OutputVariableType.ForceLocal
        loads = {n: [float(mbs.GetObjectOutput(d, fz)[2]) for d in self.items[v]["discs"]]
                 for v, n in enumerate(self.names)}
        diagnostics = {"steps": self.nsteps, "wheel_loads_final": loads, "wheel_order": ["FL", "FR", "RL", "RR"],
                       "step_size": self.o["step"], "newton_iterations": newton,
                       "t_end": t_end, "contact_episodes": self.n_episodes,
                       "max_onset_penetration": self.max_onset, "max_penetration": self.max_pen,
                       "vehicle_notes": {n: self.vehs[v].notes for v, n in enumerate(self.names)},
                       "solver": "exudyn generalized-alpha (index 3), fixed step"}
        wall = time.perf_counter() - t0
        diagnostics["wall_time_s"] = wall
        return Outcome(self.names, rest, final, self.contact, self.contact_time, trajectories, rows, diagnostics,
                       warnings, ok, "exudyn", wall)
