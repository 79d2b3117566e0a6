"""Model `multibody`: the thesis's 3D multibody vehicle (chapter 2) driving on a flat road, with
continuous vehicle-vehicle and vehicle-barrier contact (issue 5, contact.py).
"""
from __future__ import annotations

import math
import time

import numpy as np

from crashlab.model import CollisionModel
from crashlab.outcome import Outcome

from . import contact as C
from . import equations as E
from . import integrator as I
from . import road_contact as RC
from .contact_force import _fcode, chi
from .euler_parameters import from_matrix
from .tyre import LOCKED, MODES, T_R1, T_R2, deflection
from .vehicle_build import NB, NW, build_scene_vehicles, initial_local, joints, steer_angles, tyres_for

G = 9.81
# Friction tolerances of the vehicle/vehicle friction laws (contact_force.py defaults, vehicle scale)
FRICTION_V0, FRICTION_V1, FRICTION_VS = 0.01, 0.1, 0.01


def _rot_z(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _matrix(p):
    e0, e1, e2, e3 = p
    return np.array([[e0 * e0 + e1 * e1 - e2 * e2 - e3 * e3, 2 * (e1 * e2 - e0 * e3), 2 * (e1 * e3 + e0 * e2)],
                     [2 * (e1 * e2 + e0 * e3), e0 * e0 - e1 * e1 + e2 * e2 - e3 * e3, 2 * (e2 * e3 - e0 * e1)],
                     [2 * (e1 * e3 - e0 * e2), 2 * (e2 * e3 + e0 * e1), e0 * e0 - e1 * e1 - e2 * e2 + e3 * e3]])


class MultibodyModel(CollisionModel):
    """3D multibody vehicles (9 bodies each), UA tyres, Lagrange multipliers with Baumgarte.

    Options (documented defaults, the same for every scene):
      rtol = 1e-6, atol = 1e-7   Dormand-Prince 5(4) error tolerances (positions on an absolute 1 m scale)
      baumgarte = 10.0           alpha = beta [1/s] (critically damped constraint error, README)
      h_max = 0.05 s             largest step
      record_dt = 0.01 s         trajectory sampling (at accepted steps, at least this far apart)
      v_rest = 0.01 m/s, w_rest = 0.01 rad/s, t_sleep = 0.2 s   a vehicle still this long goes to sleep
      onset_tol = 0.001 m        first-contact control: a new contact starts with at most this penetration
      contact_stiffness = 1.35e6 N/m^1.5   K of one vehicle against a rigid barrier; car-to-car pairs use
                                 K_eff = (K1^(-1/n) + K2^(-1/n))^(-n) (README: crush-energy derivation)
      contact_exponent = 1.5     n of F_N = K delta^n (1 + chi delta_dot / delta_dot0)
      v_min = 0.001 m/s          smallest approach velocity delta_dot0 stored at onset
      settle_time = 3.0 s        static settling of each vehicle before the run (cached per vehicle)
      damping = True             test switch: False removes every damper (suspension, tyre radial/tread)
      friction = True            test switch: False removes the tyre's in-plane forces and moments
    """

    name = "multibody"
    # the guard's interpenetration check compares rectangular outlines; the contact bodies here are
    # superellipsoids (2/eps = 4) whose rounded corners lie up to ~0.3 m inside the rectangle's: an SUV at rest
    # 8 mm into a barrier with its corner towards it "overlapped" by 0.11 m (stress scene random 0:0). The model
    # checks the end state with its own contact shapes instead (same tolerance, guard.PENETRATION_TOL).
    guard_skip = frozenset({"interpenetration"})

    def __init__(self, rtol=1e-6, atol=1e-7, baumgarte=10.0, h_max=0.05, record_dt=0.01, v_rest=0.01,
                 w_rest=0.01, t_sleep=0.2, onset_tol=1e-3, settle_time=3.0, damping=True, friction=True,
                 contact_stiffness=1.35e6, contact_exponent=1.5, v_min=1e-3):
        if not (0 < rtol < 1 and 0 < atol and baumgarte >= 0 and h_max > 0 and record_dt >= 0 and v_rest > 0
                and w_rest > 0 and t_sleep >= 0 and onset_tol > 0 and settle_time >= 0
                and contact_stiffness > 0 and contact_exponent >= 1 and v_min > 0):
            raise ValueError("multibody model: invalid option value")
        self.opts = dict(rtol=float(rtol), atol=float(atol), baumgarte=float(baumgarte), h_max=float(h_max),
                         record_dt=float(record_dt), v_rest=float(v_rest), w_rest=float(w_rest),
                         t_sleep=float(t_sleep), onset_tol=float(onset_tol), settle_time=float(settle_time),
                         damping=bool(damping), friction=bool(friction),
                         contact_stiffness=float(contact_stiffness), contact_exponent=float(contact_exponent),
                         v_min=float(v_min))
        self._settled = {}

    def get_options(self):
        return dict(self.opts)

    # ------------------------------------------------------------------ set-up
    def _cfg(self, mu, t_end, stop_at_rest):
        o = self.opts
        cfg = np.zeros(E.N_CFG)
        cfg[E.C_G], cfg[E.C_MU], cfg[E.C_ALPHA], cfg[E.C_BETA] = G, mu, o["baumgarte"], o["baumgarte"]
        cfg[E.C_DAMPING], cfg[E.C_FRICTION] = float(o["damping"]), float(o["friction"])
        cfg[E.C_RTOL], cfg[E.C_ATOL], cfg[E.C_HMAX], cfg[E.C_H0] = o["rtol"], o["atol"], o["h_max"], 1e-3
        cfg[E.C_TEND], cfg[E.C_STOP_AT_REST] = t_end, float(stop_at_rest)
        cfg[E.C_V_REST], cfg[E.C_W_REST], cfg[E.C_T_SLEEP] = o["v_rest"], o["w_rest"], o["t_sleep"]
        cfg[E.C_REC_DT], cfg[E.C_ONSET_TOL] = o["record_dt"], o["onset_tol"]
        cfg[E.C_NEXP], cfg[E.C_VMIN] = o["contact_exponent"], o["v_min"]
        cfg[E.C_FV0], cfg[E.C_FV1], cfg[E.C_FVS] = FRICTION_V0, FRICTION_V1, FRICTION_VS
        cfg[E.C_ROAD_CHI], cfg[E.C_ROAD_N] = RC.road_chi(), RC.N_ROAD
        return cfg

    def settled(self, veh):
        """Static equilibrium of a vehicle in its own frame (wheels locked, 0.8 friction, dampers on)."""
        key = (veh.BODY.tobytes(), veh.SPR.tobytes(), veh.TYR.tobytes())
        if key not in self._settled:
            modes = [LOCKED] * NW
            cfg = self._cfg(0.8, self.opts["settle_time"], False)
            cfg[E.C_T_SLEEP] = 2.0 * self.opts["settle_time"]    # never frozen while still creeping
            cfg[E.C_DAMPING] = 1.0
            cfg[E.C_FRICTION] = 1.0
            Y = initial_local(veh)[None, :].copy()
            nslip = 2 * NW
            diag = np.zeros(I.N_DIAG)
            I.simulate(Y, veh.BODY[None], joints(veh, modes, np.zeros(NW))[None], veh.SPR[None],
                       tyres_for(veh, modes)[None], _contact_arrays(veh.chassis_shape[None], np.zeros((0, C.N_PP)),
                                                                    np.zeros((0, 5)), 1),
                       np.zeros(1, np.bool_), cfg, nslip, np.zeros((0, 1, I.N_REC)), diag, np.zeros(1),
                       np.zeros((1, 4)), np.zeros((1, 4)), False, np.zeros((0, C.N_IMP)), np.zeros((1, 4)),
                       _road_arrays(veh.chassis_shape[None], [veh.mass]))
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
        Rz = _rot_z(vs.heading)
        omega = np.array([0.0, 0.0, vs.yaw_rate])
        vel = vs.speed * np.array([math.cos(vs.heading), math.sin(vs.heading), 0.0])
        for b in range(NB):
            rl = r[b] - np.array([cg[0], cg[1], 0.0])
            rg = Rz @ rl
            y[7 * b:7 * b + 3] = rg + np.array([vs.x, vs.y, 0.0])
            A = Rz @ _matrix(ys[7 * b + 3:7 * b + 7])
            k = (b - 1) % NW
            if b >= 1:
                A = A @ _rot_z(deltas[k])
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
            A[b] = _matrix(ys[7 * b + 3:7 * b + 7])
            R[b] = ys[7 * b:7 * b + 3]
        return deflection(veh.TYR[k], A, R)[0]

    # ------------------------------------------------------------------ running
    def simulate(self, scene) -> Outcome:
        t0 = time.perf_counter()
        return self.run(scene, self.prepare(scene), t0)

    def prepare(self, scene) -> dict:
        """The packed arrays of a scene (start state Y, parameters, cfg); `run` integrates them."""
        vehs, Ys, Js, Ts, Os = [], [], [], [], []
        for vs, veh in zip(scene.vehicles, build_scene_vehicles(scene)):
            modes = [MODES["rolling"] if vs.wheels == "locked_after_impact" else MODES[vs.wheels]] * NW
            deltas = steer_angles(veh, vs.steer)
            vehs.append(veh)
            Ys.append(self.place(veh, self.settled(veh), vs, deltas, modes))
            Js.append(joints(veh, modes, deltas))
            Ts.append(tyres_for(veh, modes))
            Os.append(veh.outline)
        Y = np.array(Ys)
        BODY = np.array([v.BODY for v in vehs])
        SPR = np.array([v.SPR for v in vehs])
        JNT, TYR, OUTL = np.array(Js), np.array(Ts), np.array(Os, dtype=float)
        BAR = np.array([[b.x, b.y, b.heading, b.length / 2, b.width / 2] for b in scene.barriers]).reshape(-1, 5)
        cfg = self._cfg(scene.road.friction, scene.duration, scene.stop_at_rest)
        imp = scene.impact
        cfg[E.C_CHI] = chi(imp.force_law, imp.restitution)
        cfg[E.C_MU_C], cfg[E.C_FCODE] = imp.friction, _fcode(imp.friction_law)
        CSH = np.array([v.chassis_shape for v in vehs])
        nv = len(vehs)
        Kv, n = self.opts["contact_stiffness"], self.opts["contact_exponent"]
        pairs = [(i, j, (Kv ** (-1 / n) + Kv ** (-1 / n)) ** (-n)) for i in range(nv) for j in range(i + 1, nv)]
        pairs += [(i, nv + k, Kv) for i in range(nv) for k in range(len(scene.barriers))]
        PP = np.array(pairs, dtype=float).reshape(-1, C.N_PP)
        LOCK = np.array([vs.wheels == "locked_after_impact" for vs in scene.vehicles], dtype=np.bool_)
        return {"Y": Y, "BODY": BODY, "SPR": SPR, "JNT": JNT, "TYR": TYR, "OUTL": OUTL, "BAR": BAR, "cfg": cfg,
                "vehicles": vehs, "CSH": CSH, "PP": PP, "LOCK": LOCK}

    def run(self, scene, prep, t0=None) -> Outcome:
        t0 = time.perf_counter() if t0 is None else t0
        names = scene.vehicle_names
        nv = len(names)
        Y, BODY, SPR, JNT, TYR = prep["Y"].copy(), prep["BODY"], prep["SPR"], prep["JNT"].copy(), prep["TYR"]
        BAR, cfg, vehs = prep["BAR"], prep["cfg"], prep["vehicles"]
        nq, nvq, ny = E.sizes(NB, NW)
        e_start = [self._energy(Y[v], BODY[v], SPR[v], TYR[v]) for v in range(nv)]
        rec = self.opts["record_dt"]
        n_rec = int(scene.duration / rec) + 3 if rec > 0 else 2
        traj = np.zeros((n_rec, nv, I.N_REC))
        diag = np.zeros(I.N_DIAG)
        head = np.array([vs.heading for vs in scene.vehicles])
        fz0, fz1 = np.zeros((nv, 4)), np.zeros((nv, 4))
        CT = _contact_arrays(prep["CSH"], prep["PP"], BAR, nv)
        IMP = np.zeros((C.MAX_IMP, C.N_IMP))
        CONT = np.full((nv, 4), np.nan)
        I.simulate(Y, BODY, JNT, SPR, TYR, CT, prep["LOCK"], cfg, 2 * NW, traj, diag, head, fz0, fz1, True, IMP,
                   CONT, _road_arrays(prep["CSH"], [v.mass for v in vehs]))
        nr = int(diag[I.D_NREC])
        status = int(diag[I.D_STATUS])
        warnings, ok = [], True
        if status == I.STATUS_NAN:
            ok, warnings = False, ["the state became NaN"]
        elif status == I.STATUS_STEP:
            ok, warnings = False, ["step size underflow"]
        rest = np.zeros((nv, 3))
        final = np.zeros((nv, 3))
        contact = CONT
        trajectories = {}
        e_end, w_nc = [], []
        for v, n in enumerate(names):
            p = I.pose(Y[v], BODY[v], NB)
            rest[v] = [p[0], p[1], head[v]]
            final[v] = [p[6], p[7], p[8]]
            tr = traj[:nr, v]
            trajectories[n] = {"t": tr[:, I.R_T].copy(), "x": tr[:, I.R_X].copy(), "y": tr[:, I.R_Y].copy(),
                               "heading": tr[:, I.R_HEAD].copy(), "vx": tr[:, I.R_VX].copy(),
                               "vy": tr[:, I.R_VY].copy(), "yaw_rate": tr[:, I.R_YAW_RATE].copy(),
                               "z": tr[:, I.R_Z].copy(), "roll": tr[:, I.R_ROLL].copy(),
                               "pitch": tr[:, I.R_PITCH].copy(), "wheel_loads": tr[:, I.R_FZ:I.R_FZ + 4].copy(),
                               "z_min": tr[:, I.R_ZMIN_REC].copy(), "energy": tr[:, I.R_EMECH].copy()}
            e_end.append(self._energy(Y[v], BODY[v], SPR[v], TYR[v]))
            w_nc.append(float(Y[v, ny - 1]))
        balance = [(e_end[v] - e_start[v] - w_nc[v]) / max(abs(e_start[v]), 1.0) for v in range(nv)]
        diagnostics = {
            "steps": int(diag[I.D_STEPS]), "rejected_steps": int(diag[I.D_REJECTED]),
            "rhs_evaluations": int(diag[I.D_NFEV]), "t_end": float(diag[I.D_T_END]),
            "h_min": float(diag[I.D_H_MIN]), "h_max": float(diag[I.D_H_MAX]),
            "max_constraint_drift": float(diag[I.D_MAX_DRIFT_POS]),
            "max_constraint_drift_angular": float(diag[I.D_MAX_DRIFT_ANG]),
            "max_euler_norm_error": float(diag[I.D_MAX_NORM_ERR]),
            "wheel_loads_static": {n: fz0[v].tolist() for v, n in enumerate(names)},
            "wheel_loads_final": {n: fz1[v].tolist() for v, n in enumerate(names)},
            "mechanical_energy_start": e_start, "mechanical_energy_end": e_end, "work_nonconservative": w_nc,
            "energy_balance": balance,
            "vehicle_notes": {n: vehs[v].notes for v, n in enumerate(names)},
            "wheel_order": ["FL", "FR", "RL", "RR"],
            "contact_episodes": int(diag[I.D_NIMP]),
            "max_onset_penetration": float(diag[I.D_MAX_ONSET]),
            "onset_bisections": int(diag[I.D_ONSET_BISECT]),
            "broad_phase": dict(zip(("pair_evaluations", "removed_by_circle", "removed_by_height",
                                     "removed_by_obb", "narrow_phase"), CT[8].tolist())),
        }
        if diag[I.D_NIMP] >= C.MAX_IMP:  # later episodes would be missing from the table and the guard
            ok = False
            warnings.append(f"more than {C.MAX_IMP} contact episodes: the run cannot report them all")
        heads = [(traj[:nr, v, I.R_T].copy(), traj[:nr, v, I.R_HEAD].copy()) for v in range(nv)]
        rows = impact_rows(names, BODY[:, :, 0].sum(1), IMP[:int(diag[I.D_NIMP])].copy(), heads)
        if any(r["open"] for r in rows):
            warnings.append("a contact was still active at the end of the run")
        imp = IMP[:int(diag[I.D_NIMP])]
        intervals = contact_intervals(imp[:, C.I_T0], imp[:, C.I_T1], traj[:nr, :, I.R_T],
                                      traj[:nr, :, I.R_ROAD])
        diagnostics["road_contact_time"] = {n: float(np.sum(np.diff(traj[:nr, v, I.R_T])
                                                            * (traj[1:nr, v, I.R_ROAD] > 0)))
                                            for v, n in enumerate(names)}
        out = Outcome(names, rest, final, contact, float(diag[I.D_CONTACT_T]), trajectories, rows, diagnostics,
                      warnings, ok, self.name, time.perf_counter() - t0, contact_intervals=intervals)
        overlap = _end_overlap(names, prep["PP"], CT[6][6])
        if ok and overlap is not None:
            out.fail("interpenetration", overlap)
        return out

    def _energy(self, y, BODY, SPR, TYR):
        A = np.zeros((NB, 3, 3))
        R, V, W = np.zeros((NB, 3)), np.zeros((NB, 3)), np.zeros((NB, 3))
        return float(E.energy(y, BODY, SPR, TYR, G, A, R, V, W))


def _end_overlap(names, PP, psg):
    """The guard's interpenetration check with the contact bodies (superellipsoid chassis, barrier boxes) at
    the last evaluation: a reason when a pair ends penetrating deeper than guard.PENETRATION_TOL, else None."""
    from crashlab.guard import PENETRATION_TOL
    nv = len(names)
    for p in range(PP.shape[0]):
        d = psg[p, C.G_DEL]
        if d > PENETRATION_TOL:
            i, j = int(PP[p, C.P_I]), int(PP[p, C.P_J])
            other = names[j] if j < nv else f"barrier {j - nv}"
            return f"{names[i]} and {other} end penetrating by {d:.2f} m (contact bodies)"
    return None


def _road_arrays(CSH, masses):
    """The chassis-road tuple of the integrator: stiffness per vehicle, stage outputs RSG[7, nv, N_RSG]."""
    return (RC.stiffness(masses), np.zeros((7, len(masses), RC.N_RSG)))


def contact_intervals(t0, t1, t_rec, road):
    """Merged (t_start, t_end) [s] of every contact: the chassis-chassis / chassis-barrier episodes (t0, t1)
    and the chassis-road contact (road[k, v] = 1: vehicle v touched the road between records k-1 and k)."""
    iv = [(float(a), float(b)) for a, b in zip(t0, t1)]
    for v in range(road.shape[1]):
        for k in range(road.shape[0]):
            if road[k, v] > 0:
                iv.append((float(t_rec[k - 1, v]) if k > 0 else 0.0, float(t_rec[k, v])))
    iv.sort()
    out = []
    for a, b in iv:
        if out and a <= out[-1][1]:
            out[-1] = (out[-1][0], max(out[-1][1], b))
        else:
            out.append((a, b))
    return out


def _contact_arrays(CSH, PP, BAR, nv):
    """The contact tuple of the integrator: CSH, BOXR, BOXA, BOXE, PP, PST, PSG, FX, BPC (fresh pair state,
    broad-phase counters)."""
    nbar = BAR.shape[0]
    BOXR = np.zeros((nbar, 3))
    BOXA = np.zeros((nbar, 3, 3))
    BOXE = np.zeros((nbar, 3))
    for k in range(nbar):
        BOXR[k] = [BAR[k, 0], BAR[k, 1], C.BARRIER_HALF_HEIGHT]
        BOXA[k] = _rot_z(BAR[k, 2])
        BOXE[k] = [BAR[k, 3], BAR[k, 4], C.BARRIER_HALF_HEIGHT]
    npair = PP.shape[0]
    return (np.ascontiguousarray(CSH, dtype=float), BOXR, BOXA, BOXE, np.ascontiguousarray(PP, dtype=float),
            np.zeros((npair, C.N_PST)), np.zeros((7, npair, C.N_PSG)), np.zeros((nv, 7)),
            np.zeros(C.N_BPC, np.int64))


def _pdof(fx, fy, heading):
    """Principal direction of force on a vehicle [rad] (as the impulse model): where the force comes from,
    in the vehicle frame, 0 = from straight ahead, counter-clockwise positive."""
    ang = math.atan2(-fy, -fx) - heading
    return math.atan2(math.sin(ang), math.cos(ang))


def impact_rows(names, mass, imp, heads=None):
    """Impact table rows (SI), one per vehicle per contact episode (kind "continuous"). Keys as the impulse
    model (t = episode start, dvx, dvy, d_yaw_rate = CG velocity / yaw-rate change over the episode,
    energy = work dissipated by the contact forces over the episode (whole pair), ees from that energy split
    in proportion to 1/mass, pdof from the impulse on the vehicle, point_x/y = contact point at peak force,
    plane_angle = tangent of the contact plane at peak force) plus: peak_force [N] (normal), duration [s],
    impulse [N s] (magnitude of the contact impulse on the vehicle) and its global components impulse_x,
    impulse_y, impulse_z, max_penetration [m],
    approach_speed / separation_speed [m/s] (relative normal velocity at the contact point at onset and at
    separation; restitution = separation/approach), open (contact still active when the run ended)."""
    nv = len(names)
    rows = []
    for r in imp:
        i, j = int(r[C.I_I]), int(r[C.I_J])
        Jx, Jy, Jz = r[C.I_JX], r[C.I_JX + 1], r[C.I_JX + 2]
        inv_i, inv_j = 1.0 / mass[i], (1.0 / mass[j] if j < nv else 0.0)
        plane = r[C.I_TH] + math.pi / 2
        dd0, dd1 = r[C.I_DD0], r[C.I_DD1]
        sides = [(i, names[j] if j < nv else f"barrier{j - nv}", 1.0, C.I_DVI, inv_i)]
        if j < nv:
            sides.append((j, names[i], -1.0, C.I_DVJ, inv_j))
        for q, other, sgn, c_dv, inv_q in sides:
            e_q = max(r[C.I_ENERGY], 0.0) * inv_q / (inv_i + inv_j)
            dvx, dvy = r[c_dv], r[c_dv + 1]
            heading = float(np.interp(r[C.I_T0], heads[q][0], heads[q][1])) if heads is not None else 0.0
            rows.append({"t": r[C.I_T0], "vehicle": names[q], "other": other, "dvx": dvx, "dvy": dvy,
                         "d_yaw_rate": r[c_dv + 2], "energy": r[C.I_ENERGY],
                         "ees": math.sqrt(2.0 * e_q / mass[q]),
                         "pdof": _pdof(sgn * Jx, sgn * Jy, heading),
                         "kind": "continuous", "point_x": r[C.I_PX], "point_y": r[C.I_PY], "plane_angle": plane,
                         "peak_force": r[C.I_PEAK], "duration": r[C.I_T1] - r[C.I_T0],
                         "impulse": math.sqrt(Jx * Jx + Jy * Jy + Jz * Jz), "impulse_x": sgn * Jx,
                         "impulse_y": sgn * Jy, "impulse_z": sgn * Jz, "max_penetration": r[C.I_MAXPEN],
                         "approach_speed": dd0, "separation_speed": -dd1,
                         "restitution": (-dd1 / dd0) if dd0 > 0 else math.nan, "open": bool(r[C.I_OPEN])})
    return rows
