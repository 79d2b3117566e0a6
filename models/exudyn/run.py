"""One exudyn simulation of a scene (the model's `simulate`): the exudyn system of the scene's vehicles
(build.py) and their contact arrays, exudyn's solver settings and its run with the pre-step and post-Newton
functions (step_loads.py, driver_loads.py), the last step's bookkeeping and the Outcome (records.py)."""
from __future__ import annotations

import math

import numpy as np

from crashlab.models.common import chassis_contact as C
from crashlab.models.common import contact_episodes as EP
from crashlab.models.common import contact_report
from crashlab.models.common import driver_inputs as DI
from crashlab.models.common import road_contact as R
from crashlab.models.common.contact_force import chi, friction_code
from crashlab.models.common.crush_structure import clamp_restitution, speed_law_setting, structure_row
from crashlab.models.common.vehicle_3d import NW, T_ETA, T_R1, T_R2
from crashlab.models.common.wheel_states import BRAKED
from crashlab.restitution import E_SPEED_LAW, SPEED

from .driver_loads import DriverLoads
from .records import Records
from .step_loads import MAX_SHORTEST_ITER, StepLoads

ADAPT_RECOVERY = 5     # accepted steps before exudyn doubles a shortened step again


class ExudynRun(StepLoads, DriverLoads, Records):
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
        if imp.restitution_law == SPEED and opts["contact_law"] == "structure":
            self.rest = E_SPEED_LAW  # the law at each pair's closing speed (chassis_contact, §13b)
        self.law_warnings = [why] if why else []
        STR = []
        for veh, vs in zip(self.vehs, scene.vehicles):
            row, notes = structure_row(vs.spec)
            STR.append(row)
            veh.notes.extend(n for n in notes if n not in veh.notes)
        self.PP = C.pair_table(nv, len(scene.barriers), opts["contact_stiffness"], opts["contact_exponent"],
                               np.array(STR), [veh.mass for veh in self.vehs])
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
        self.IMP = np.zeros((EP.episode_capacity(nv, len(scene.barriers)), EP.N_IMP))
        self.n_episodes, self.intervals = 0, []
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
        ti.discontinuous.maxIterations = MAX_SHORTEST_ITER   # passes at the shortest step (step_loads.postnewton)
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
            if PST[p, C.S_ACT] != C.NONE:
                self._episode(p, t_end, t_end, t_end, psg, finish=True)
        if self.rest == E_SPEED_LAW:
            warnings += contact_report.speed_law_warnings(PST)
        for v in range(nv):
            if self.road_on[v]:
                self.intervals.append((self.road_t0[v], t_end))
        overlap = contact_report.end_overlap(self.names, self.PP, psg)
        return self._outcome(t0, t_end, warnings, ok, overlap)
