"""Model `multibody`: the thesis's 3D multibody vehicle (chapter 2) driving on a flat road, with
continuous vehicle-vehicle and vehicle-barrier contact (issue 5, common/chassis_contact.py).
"""
from __future__ import annotations

import math
import time
from typing import Literal

import numpy as np

from crashlab.model import CollisionModel
from crashlab.models.common import road_contact as RC
from crashlab.models.common.chassis_contact import (
    CONTACT_LAWS,
    N_PP,
    barrier_rows,
    contact_arrays,
    pair_table,
)
from crashlab.models.common.contact_episodes import (
    I_MAXPEN,
    I_T0,
    I_T1,
    N_IMP,
    contact_intervals,
    episode_capacity,
    impact_rows,
)
from crashlab.models.common.contact_force import FRICTION_V0, FRICTION_V1, FRICTION_VS, chi, friction_code
from crashlab.models.common.contact_report import end_overlap, row_warnings, speed_law_warnings
from crashlab.models.common.crush_structure import clamp_restitution, speed_law_setting, structure_row
from crashlab.models.common.driver_inputs import (
    A_MODE,
    A_STEER_FROM,
    A_STEER_TO,
    A_T,
    A_T_END,
    N_ACTION_COLUMNS,
    driver_inputs,
    effective_mode,
    pack_action_tables,
    pack_zones,
)
from crashlab.models.common.impact_rows import struck_compliance
from crashlab.models.common.rotations import from_matrix, matrix, rot_z
from crashlab.models.common.vehicle_3d import (
    CORNERS,
    NB,
    NW,
    T_R1,
    T_R2,
    build_scene_vehicles,
    steer_angles,
)
from crashlab.models.common.wheel_states import LOCKED
from crashlab.options import ModelOptions, option
from crashlab.outcome import Outcome
from crashlab.restitution import E_SPEED_LAW, SPEED
from crashlab.units import G

from . import dormand_prince as DP
from . import equations as E
from . import integrator as I
from . import recording as REC
from .joints import vehicle_joints
from .tyre import deflection, tyres_for


class MultibodyModel(CollisionModel):
    """3D multibody vehicles (9 bodies each), UA tyres, Lagrange multipliers with Baumgarte; the options
    (documented defaults, the same for every scene) are `Options` below, the model is described in README.md."""

    name = "multibody"
    compiles = "multibody"  # its numba kernels (the command line announces a cold compile)
    driver_inputs = True    # actions and friction zones (docs/physics.md §2a; README "Driver actions")
    # the guard's interpenetration check compares rectangular outlines; the contact bodies here are
    # superellipsoids (2/eps = 4) whose rounded corners lie up to ~0.3 m inside the rectangle's: an SUV at rest
    # 8 mm into a barrier with its corner towards it "overlapped" by 0.11 m (stress scene random 0:0). The model
    # checks the end state with its own contact shapes instead (same tolerance, guard.PENETRATION_TOL).
    guard_skip = frozenset({"interpenetration"})

    class Options(ModelOptions):
        rtol: float = option(1e-6, "Dormand-Prince 5(4) relative error tolerance", "", accuracy="smaller",
                             gt=0, lt=1)
        atol: float = option(1e-7, "Dormand-Prince 5(4) absolute error tolerance (positions and Euler parameters "
                             "on an absolute 1 m / 1 scale)", "", accuracy="smaller", gt=0)
        baumgarte: float = option(10.0, "alpha = beta of the Baumgarte stabilisation (critically damped constraint "
                                  "error, 0.1 s time constant; README)", "1/s", ge=0)
        h_max: float = option(0.05, "largest integration step", "s", accuracy="smaller", gt=0)
        record_dt: float = option(0.01, "trajectory sampling (at accepted steps, at least this far apart)", "s",
                                  ge=0)
        v_rest: float = option(0.01, "chassis speed below which a vehicle counts as still", "m/s", gt=0)
        w_rest: float = option(0.01, "chassis angular speed below which a vehicle counts as still", "rad/s", gt=0)
        t_sleep: float = option(0.2, "a vehicle still this long goes to sleep (no more evaluations)", "s", ge=0)
        onset_tol: float = option(1e-3, "first-contact control: a new contact starts with at most this "
                                  "penetration (the step is bisected; docs/physics.md §15)", "m",
                                  accuracy="smaller", gt=0)
        settle_time: float = option(3.0, "static settling of each vehicle before the run (locked wheels; cached "
                                    "per vehicle)", "s", ge=0)
        damping: bool = option(True, "test switch: False removes every damper (suspension, tyre radial and tread)")
        friction: bool = option(True, "test switch: False removes the tyre's in-plane forces and moments")
        contact_law: Literal["structure", "generic"] = option(
            "structure", "chassis contact force: 'structure' = the vehicles' CRASH3 crush stiffness A + B C per "
            "unit of engaged width, the two structures in series, unloading to the scene's restitution "
            "(docs/physics.md §13a); 'generic' = K delta^n with the scene's force_law (§13)")
        contact_stiffness: float = option(1.35e6, "generic law: K of one vehicle against a rigid barrier; car-to-car "
                                          "pairs use K_eff = (K1^(-1/n) + K2^(-1/n))^(-n) (README: crush-energy "
                                          "derivation)", "N/m^1.5", gt=0)
        contact_exponent: float = option(1.5, "generic law: n of F_N = K delta^n (1 + chi delta_dot / "
                                         "delta_dot0)", "", ge=1)
        v_min: float = option(1e-3, "smallest approach velocity delta_dot0 stored at onset", "m/s", gt=0)

    def __init__(self, **options):
        super().__init__(**options)
        self._settled = {}

    # ------------------------------------------------------------------ set-up
    def _cfg(self, mu, t_end, stop_at_rest):
        o = self.options
        cfg = np.zeros(E.N_CFG)
        cfg[E.C_G], cfg[E.C_MU], cfg[E.C_ALPHA], cfg[E.C_BETA] = G, mu, o.baumgarte, o.baumgarte
        cfg[E.C_DAMPING], cfg[E.C_FRICTION] = float(o.damping), float(o.friction)
        cfg[E.C_RTOL], cfg[E.C_ATOL], cfg[E.C_HMAX], cfg[E.C_H0] = o.rtol, o.atol, o.h_max, 1e-3
        cfg[E.C_TEND], cfg[E.C_STOP_AT_REST] = t_end, float(stop_at_rest)
        cfg[E.C_V_REST], cfg[E.C_W_REST], cfg[E.C_T_SLEEP] = o.v_rest, o.w_rest, o.t_sleep
        cfg[E.C_REC_DT], cfg[E.C_ONSET_TOL] = o.record_dt, o.onset_tol
        cfg[E.C_NEXP], cfg[E.C_VMIN] = o.contact_exponent, o.v_min
        cfg[E.C_FV0], cfg[E.C_FV1], cfg[E.C_FVS] = FRICTION_V0, FRICTION_V1, FRICTION_VS
        cfg[E.C_ROAD_CHI], cfg[E.C_ROAD_N] = RC.road_chi(), RC.N_ROAD
        cfg[E.C_PI_BETA] = DP.PI_BETA
        return cfg

    def settled(self, veh):
        """Static equilibrium of a vehicle in its own frame (wheels locked, 0.8 friction, dampers on)."""
        key = (veh.BODY.tobytes(), veh.SPR.tobytes(), veh.TYR.tobytes())
        if key not in self._settled:
            modes = [LOCKED] * NW
            cfg = self._cfg(0.8, self.options.settle_time, False)
            cfg[E.C_T_SLEEP] = 2.0 * self.options.settle_time    # never frozen while still creeping
            cfg[E.C_DAMPING] = 1.0
            cfg[E.C_FRICTION] = 1.0
            Y = _initial_local(veh)[None, :].copy()
            nslip = 2 * NW
            diag = np.zeros(REC.N_DIAG)
            I.simulate(Y, veh.BODY[None], vehicle_joints(veh, modes, np.zeros(NW))[None], veh.SPR[None],
                       tyres_for(veh, modes)[None], contact_arrays(veh.chassis_shape[None], np.zeros((0, N_PP)),
                                                                   np.zeros((0, 5)), 1),
                       _no_driver(), cfg, nslip, np.zeros((0, 1, REC.N_REC)), diag, np.zeros(1),
                       np.zeros((1, 4)), np.zeros((1, 4)), False, np.zeros((0, N_IMP)), np.zeros((1, 4)),
                       _road_arrays([veh.mass]), np.zeros(1, np.bool_))
            y = Y[0]
            nq, nvq, _ = E.sizes(NB, NW)
            y[nq:] = 0.0
            self._settled[key] = y.copy()
        return self._settled[key].copy()

    def place(self, veh, ys, vs, deltas, modes):
        """The settled state moved to the scene's start pose and speed (velocity-consistent)."""
        nq, nvq, ny = E.sizes(NB, NW)
        y = ys.copy()
        m = veh.BODY[:, 0]
        r = np.array([ys[7 * b:7 * b + 3] for b in range(NB)])
        cg = (m[:, None] * r).sum(0) / m.sum()
        Rz = rot_z(vs.heading)
        omega = np.array([0.0, 0.0, vs.yaw_rate])
        vel = vs.speed * np.array([math.cos(vs.heading), math.sin(vs.heading), 0.0])
        for b in range(NB):
            rl = r[b] - np.array([cg[0], cg[1], 0.0])
            rg = Rz @ rl
            y[7 * b:7 * b + 3] = rg + np.array([vs.x, vs.y, 0.0])
            A = Rz @ matrix(ys[7 * b + 3:7 * b + 7])
            k = (b - 1) % NW
            if b >= 1:
                A = A @ rot_z(deltas[k])
            y[7 * b + 3:7 * b + 7] = from_matrix(A)
            rel = rg - np.array([0.0, 0.0, rg[2]]) + np.array([0.0, 0.0, cg[2]]) * 0.0
            vb = vel + np.cross(omega, np.array([rel[0], rel[1], 0.0]))
            w = A.T @ omega
            if b >= 5 and modes[k] != LOCKED:
                xc = A @ np.array([1.0, 0.0, 0.0])
                Tw = veh.TYR[k]
                d = max(self._deflection_of(ys, veh, k), 0.0)
                w = w + np.array([0.0, float(vb @ xc) / (Tw[T_R1] + Tw[T_R2] - d / 3.0), 0.0])
            y[nq + 6 * b:nq + 6 * b + 3] = vb
            y[nq + 6 * b + 3:nq + 6 * b + 6] = w
        y[nvq:] = 0.0
        return y

    @staticmethod
    def _deflection_of(ys, veh, k):
        A = np.zeros((NB, 3, 3))
        R = np.zeros((NB, 3))
        for b in range(NB):
            A[b] = matrix(ys[7 * b + 3:7 * b + 7])
            R[b] = ys[7 * b:7 * b + 3]
        return deflection(veh.TYR[k], A, R)[0]

    # ------------------------------------------------------------------ running
    def simulate(self, scene) -> Outcome:
        t0 = time.perf_counter()
        return self.run(scene, self.prepare(scene), t0)

    def prepare(self, scene) -> dict:
        """The packed arrays of a scene (start state Y, parameters, cfg); `run` integrates them."""
        vehs, Ys, Js, Ts = [], [], [], []
        ACT, NACT = pack_action_tables(scene.vehicles)
        GEO = np.zeros((len(scene.vehicles), 4))
        for v, (vs, veh) in enumerate(zip(scene.vehicles, build_scene_vehicles(scene))):
            # the wheel state and steer at t = 0 (common/driver_inputs.py; locked_after_impact rolls until struck)
            mode, _, steer = driver_inputs(ACT[v], NACT[v], 0.0)
            modes = [effective_mode(mode, False)] * NW
            deltas = steer_angles(veh, steer)
            GEO[v] = (veh.wheelbase, veh.axle_y[0], veh.axle_y[1],
                      float(np.any(ACT[v, :NACT[v], A_STEER_FROM] != ACT[v, :NACT[v], A_STEER_TO])))
            vehs.append(veh)
            Ys.append(self.place(veh, self.settled(veh), vs, deltas, modes))
            Js.append(vehicle_joints(veh, modes, deltas))
            Ts.append(tyres_for(veh, modes))
        Y = np.array(Ys)
        BODY = np.array([v.BODY for v in vehs])
        SPR = np.array([v.SPR for v in vehs])
        JNT, TYR = np.array(Js), np.array(Ts)
        BAR = barrier_rows(scene.barriers)
        cfg = self._cfg(scene.road.friction, scene.duration, scene.stop_at_rest)
        imp = scene.impact
        cfg[E.C_CHI] = chi(imp.force_law, imp.restitution)
        cfg[E.C_MU_C], cfg[E.C_FCODE] = imp.friction, friction_code(imp.friction_law)
        cfg[E.C_LAW] = CONTACT_LAWS.index(self.options.contact_law)
        cfg[E.C_REST], why = clamp_restitution(imp.restitution)
        why = speed_law_setting(imp, self.options.contact_law, why)
        if imp.restitution_law == SPEED and self.options.contact_law == "structure":
            cfg[E.C_REST] = E_SPEED_LAW  # the law at each pair's closing speed (chassis_contact, §13b)
        STR = []
        for veh, vs in zip(vehs, scene.vehicles):
            row, notes = structure_row(vs.spec)
            STR.append(row)
            veh.notes.extend(n for n in notes if n not in veh.notes)
        CSH = np.array([v.chassis_shape for v in vehs])
        PP = pair_table(len(vehs), len(scene.barriers), self.options.contact_stiffness, self.options.contact_exponent,
                        np.array(STR), [v.mass for v in vehs])
        DV = (ACT, NACT, GEO) + pack_zones(scene.road)
        # a vehicle at rest in the scene starts asleep in its settled state (unless sleeping cannot happen in
        # this run: t_sleep >= duration, e.g. the scaling study's sleeping off)
        can_sleep = self.options.t_sleep < scene.duration
        ASLEEP = np.array([can_sleep and vs.speed == 0 and vs.yaw_rate == 0 for vs in scene.vehicles],
                          dtype=np.bool_)
        return {"Y": Y, "BODY": BODY, "SPR": SPR, "JNT": JNT, "TYR": TYR, "BAR": BAR, "cfg": cfg,
                "vehicles": vehs, "CSH": CSH, "PP": PP, "DV": DV, "ASLEEP": ASLEEP,
                "warnings": [why] if why else []}

    def run(self, scene, prep, t0=None) -> Outcome:
        t0 = time.perf_counter() if t0 is None else t0
        names = scene.vehicle_names
        nv = len(names)
        Y, BODY, SPR, JNT, TYR = prep["Y"].copy(), prep["BODY"], prep["SPR"], prep["JNT"].copy(), prep["TYR"].copy()
        BAR, cfg, vehs = prep["BAR"], prep["cfg"], prep["vehicles"]
        nq, nvq, ny = E.sizes(NB, NW)
        e_start = [self._energy(Y[v], BODY[v], SPR[v], TYR[v]) for v in range(nv)]
        rec = self.options.record_dt
        n_rec = int(scene.duration / rec) + 3 if rec > 0 else 2
        traj = np.zeros((n_rec, nv, REC.N_REC))
        diag = np.zeros(REC.N_DIAG)
        head = np.array([vs.heading for vs in scene.vehicles])
        fz0, fz1 = np.zeros((nv, 4)), np.zeros((nv, 4))
        CT = contact_arrays(prep["CSH"], prep["PP"], BAR, nv)
        IMP = np.zeros((episode_capacity(nv, len(scene.barriers)), N_IMP))
        CONT = np.full((nv, 4), np.nan)
        I.simulate(Y, BODY, JNT, SPR, TYR, CT, prep["DV"], cfg, 2 * NW, traj, diag, head, fz0, fz1, True, IMP,
                   CONT, _road_arrays([v.mass for v in vehs]), prep["ASLEEP"])
        nr = int(diag[REC.D_NREC])
        status = int(diag[REC.D_STATUS])
        warnings, ok = list(prep.get("warnings", [])), True
        if status == I.STATUS_NAN:
            ok, warnings = False, ["the state became NaN"]
        elif status == I.STATUS_STEP:
            ok, warnings = False, ["step size underflow"]
        if cfg[E.C_REST] == E_SPEED_LAW:
            warnings += speed_law_warnings(CT[5])
        rest = np.zeros((nv, 3))
        final = np.zeros((nv, 3))
        contact = CONT
        trajectories = {}
        e_end, w_nc = [], []
        for v, n in enumerate(names):
            p = REC.pose(Y[v], BODY[v], NB)
            rest[v] = [p[0], p[1], head[v]]
            final[v] = [p[6], p[7], p[8]]
            tr = traj[:nr, v]
            trajectories[n] = {"t": tr[:, REC.R_T].copy(), "x": tr[:, REC.R_X].copy(), "y": tr[:, REC.R_Y].copy(),
                               "heading": tr[:, REC.R_HEAD].copy(), "vx": tr[:, REC.R_VX].copy(),
                               "vy": tr[:, REC.R_VY].copy(), "yaw_rate": tr[:, REC.R_YAW_RATE].copy(),
                               "z": tr[:, REC.R_Z].copy(), "roll": tr[:, REC.R_ROLL].copy(),
                               "pitch": tr[:, REC.R_PITCH].copy(), "wheel_loads": tr[:, REC.R_FZ:REC.R_FZ + 4].copy(),
                               "z_min": tr[:, REC.R_ZMIN_REC].copy(), "energy": tr[:, REC.R_EMECH].copy()}
            e_end.append(self._energy(Y[v], BODY[v], SPR[v], TYR[v]))
            w_nc.append(float(Y[v, ny - 1]))
        balance = [(e_end[v] - e_start[v] - w_nc[v]) / max(abs(e_start[v]), 1.0) for v in range(nv)]
        n_imp = min(int(diag[REC.D_NIMP]), len(IMP))
        diagnostics = {
            "steps": int(diag[REC.D_STEPS]), "rejected_steps": int(diag[REC.D_REJECTED]),
            "rhs_evaluations": int(diag[REC.D_NFEV]), "t_end": float(diag[REC.D_T_END]),
            "h_min": float(diag[REC.D_H_MIN]), "h_max": float(diag[REC.D_H_MAX]),
            "max_constraint_drift": float(diag[REC.D_MAX_DRIFT_POS]),
            "max_constraint_drift_angular": float(diag[REC.D_MAX_DRIFT_ANG]),
            "max_euler_norm_error": float(diag[REC.D_MAX_NORM_ERR]),
            "wheel_loads_static": {n: fz0[v].tolist() for v, n in enumerate(names)},
            "wheel_loads_final": {n: fz1[v].tolist() for v, n in enumerate(names)},
            "mechanical_energy_start": e_start, "mechanical_energy_end": e_end, "work_nonconservative": w_nc,
            "energy_balance": balance,
            "vehicle_notes": {n: vehs[v].notes for v, n in enumerate(names)},
            "wheel_order": list(CORNERS),
            "episodes": int(diag[REC.D_NIMP]),
            "max_penetration": float(IMP[:n_imp, I_MAXPEN].max(initial=0.0)),
            "max_onset_penetration": float(diag[REC.D_MAX_ONSET]),
            "onset_bisections": int(diag[REC.D_ONSET_BISECT]),
            "broad_phase": dict(zip(("pair_evaluations", "removed_by_circle", "removed_by_height",
                                     "removed_by_obb", "narrow_phase"), CT[8].tolist())),
        }
        if diag[REC.D_NIMP] > len(IMP):  # later episodes would be missing from the table and the guard
            ok = False
            warnings.append(f"more than {len(IMP)} contact episodes: the run cannot report them all")
        heads = [(traj[:nr, v, REC.R_T].copy(), traj[:nr, v, REC.R_HEAD].copy()) for v in range(nv)]
        imp = IMP[:n_imp].copy()
        rows = impact_rows(names, BODY[:, :, 0].sum(1), imp, struck_compliance(vs.spec for vs in scene.vehicles), heads)
        if any(r["open"] for r in rows):
            warnings.append("a contact was still active at the end of the run")
        warnings += row_warnings(scene, rows, dict(zip(names, BODY[:, :, 0].sum(1))))
        intervals = contact_intervals(imp[:, I_T0], imp[:, I_T1], traj[:nr, :, REC.R_T], traj[:nr, :, REC.R_ROAD])
        diagnostics["road_contact_time"] = {n: float(np.sum(np.diff(traj[:nr, v, REC.R_T])
                                                            * (traj[1:nr, v, REC.R_ROAD] > 0)))
                                            for v, n in enumerate(names)}
        out = Outcome(names, rest, final, contact, float(diag[REC.D_CONTACT_T]), trajectories, rows, diagnostics,
                      warnings, ok, self.name, time.perf_counter() - t0, contact_intervals=intervals)
        overlap = end_overlap(names, prep["PP"], CT[6][6])
        if ok and overlap is not None:
            out.fail("interpenetration", overlap)
        return out

    def _energy(self, y, BODY, SPR, TYR):
        A = np.zeros((NB, 3, 3))
        R, V, W = np.zeros((NB, 3)), np.zeros((NB, 3)), np.zeros((NB, 3))
        return float(E.energy(y, BODY, SPR, TYR, G, A, R, V, W))


def _no_driver():
    """Driver arrays of a run without actions or zones (the static settling): one start row, wheels locked."""
    ACT = np.zeros((1, 1, N_ACTION_COLUMNS))
    ACT[0, 0, A_T] = ACT[0, 0, A_T_END] = -math.inf
    ACT[0, 0, A_MODE] = LOCKED
    return (ACT, np.ones(1, np.int64), np.zeros((1, 4)), np.zeros((0, 7)), np.zeros(1, np.int64), np.zeros(0),
            np.zeros((0, 5)))


def _road_arrays(masses):
    """The chassis-road tuple of the integrator: stiffness per vehicle, stage outputs RSG[7, nv, N_RSG]."""
    return (RC.stiffness(masses), np.zeros((7, len(masses), RC.N_RSG)))


def _initial_local(veh) -> np.ndarray:
    """First estimate of the static state in the vehicle frame (chassis CG above the origin)."""
    nq, nv, ny = E.sizes(NB, NW)
    y = np.zeros(ny)
    y[0:3] = [0.0, 0.0, veh.z_chassis0]
    for b in range(NB):
        y[7 * b + 3] = 1.0
    for k in range(NW):
        for b in (1 + k, 5 + k):
            y[7 * b:7 * b + 3] = [veh.axle_x[k], veh.axle_y[k], veh.z_wheel0[k]]
    return y
