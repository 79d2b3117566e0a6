"""The time loop: Dormand-Prince 5(4) with FSAL and PI step-size control (PI_BETA), hand-rolled in numba, over all
vehicles of a scene at once (one step size, error norm over the awake vehicles).

Scene awareness: step sizes grow up to h_max while nothing happens; a vehicle whose chassis has been
still (speed < v_rest, angular speed < w_rest) for t_sleep goes to sleep (velocities zeroed, no more
force evaluations; a vehicle the scene starts at rest starts asleep, ASLEEP0); the run ends when every vehicle
sleeps (stop_at_rest) or at t_end. Vehicle pairs of two sleeping vehicles are not evaluated.
Vehicle contact (common/chassis_contact.py) is evaluated in every stage. First-contact control (Flores & Ambrosio 2010,
docs/physics.md §15): a trial step that passes the error test but ends with a pair not yet in contact
penetrating deeper than onset_tol is bisected (re-integrated from its start) until the new penetration
is in (0, onset_tol]; the pair is then active and its approach velocity delta_dot0 is stored until the
pair separates (penetration <= 0 at the end of a step), which closes the contact episode (impulse, peak
force, work, max penetration, delta-V, recorded in IMP: common/contact_episodes.py). Euler parameters are
renormalised after every accepted step.
"""
import math

import numpy as np
from numba import njit

from crashlab.models.common.chassis_contact import G_DDOT, G_DEL, P_I, P_J, S_ACT, contacts_awake
from crashlab.models.common.contact_episodes import accumulate, close_episode, open_episode, reset_sums, track_peak
from crashlab.models.common.driver_inputs import driver_inputs, effective_mode, next_change, steer_rate
from crashlab.models.common.road_contact import R_DEL, R_ZMIN, ROAD_FRICTION_LAW, road_contacts
from crashlab.models.common.rotations import cross, dot, rotation_entries, rotation_into
from crashlab.models.common.vehicle_3d import NW, T_MODE
from crashlab.models.common.wheel_states import LOCKED

from .equations import (
    AUX_DRIFT_ANG,
    AUX_DRIFT_POS,
    AUX_FZ,
    B_MASS,
    C_ATOL,
    C_CHI,
    C_FCODE,
    C_FV0,
    C_FV1,
    C_FVS,
    C_G,
    C_H0,
    C_HMAX,
    C_LAW,
    C_MU,
    C_MU_C,
    C_NEXP,
    C_ONSET_TOL,
    C_PI_BETA,
    C_REC_DT,
    C_REST,
    C_ROAD_CHI,
    C_ROAD_N,
    C_RTOL,
    C_STOP_AT_REST,
    C_T_SLEEP,
    C_TEND,
    C_V_REST,
    C_VMIN,
    C_W_REST,
    MAX_JOINTS,
    MAX_ROWS,
    N_AUX,
    energy,
    rhs,
)
from .joints import J_DDELTA, J_I, J_J, J_TYPE, J_XI, J_XJ, J_YI, REVOLUTE, REVOLUTE_LOCKED

# Dormand-Prince 5(4) tableau
_A = np.array([
    [0, 0, 0, 0, 0, 0],
    [1 / 5, 0, 0, 0, 0, 0],
    [3 / 40, 9 / 40, 0, 0, 0, 0],
    [44 / 45, -56 / 15, 32 / 9, 0, 0, 0],
    [19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729, 0, 0],
    [9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656, 0],
    [35 / 384, 0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84]])
_C = np.array([0.0, 1 / 5, 3 / 10, 4 / 5, 8 / 9, 1.0, 1.0])
_E = np.array([71 / 57600, 0.0, -71 / 16695, 71 / 1920, -17253 / 339200, 22 / 525, -1 / 40])

# PI step-size control (simulate): beta = 0.08 with exponent 0.2 - 0.75 beta = 0.14 is Soderlind's PI.3.4
# (Gustafsson 1991, ACM TOMS 17:533-554; Hairer & Wanner's DOPRI5 uses 0.04): the step size no longer
# oscillates about the stability limit (side collision: 59 rejected steps instead of 331)
PI_BETA = 0.08
STATUS_OK, STATUS_NAN, STATUS_STEP = 0, 2, 3
(D_STEPS, D_REJECTED, D_NFEV, D_T_END, D_STATUS, D_CONTACT_T, D_PAIR_I, D_PAIR_J, D_MAX_DRIFT_POS,
 D_MAX_DRIFT_ANG, D_MAX_NORM_ERR, D_NREC, D_H_MIN, D_H_MAX, D_NIMP, D_MAX_ONSET, D_ONSET_BISECT) = range(17)
N_DIAG = 17
# trajectory record columns: ..., wheel loads (4), lowest point of the chassis above the road, and 1 if the
# chassis touched the road during any step since the previous record
(R_T, R_X, R_Y, R_Z, R_HEAD, R_ROLL, R_PITCH, R_VX, R_VY, R_YAW_RATE) = range(10)
R_FZ = 10
R_ZMIN_REC, R_ROAD, R_EMECH = 14, 15, 16      # ..., mechanical energy (equations.energy) [J]
N_REC = 17


@njit(cache=True)
def make_work(nv, nb):
    return (np.empty((nv, nb, 3, 3)), np.empty((nv, nb, 3)), np.empty((nv, nb, 3)), np.empty((nv, nb, 3)),
            np.empty((nv, nb, 6)), np.empty((nv, MAX_ROWS, 12)), np.empty((nv, MAX_ROWS)),
            np.empty((nv, MAX_ROWS)), np.empty((nv, MAX_ROWS, 2), np.int64), np.empty((nv, MAX_ROWS), np.bool_),
            np.empty((nv, MAX_ROWS, MAX_ROWS)), np.empty((nv, MAX_ROWS)), np.zeros((nv, MAX_ROWS)),
            np.empty((nv, MAX_ROWS, 12)), np.zeros((nv, MAX_JOINTS + 1), np.int64),
            np.zeros((nv, MAX_JOINTS, 2), np.int64), np.zeros((nv, MAX_JOINTS, MAX_JOINTS), np.bool_),
            np.empty((nv, nb, 6)))


@njit(cache=True)
def eval_all(Y, K, s, te, awake, BODY, JNT, SPR, TYR, cfg, wk, aux, CT, RD, DV):
    """All forces and accelerations at stage s, time te (the driver's inputs; DV: driver_arrays)."""
    A, R, V, W, Q, D, phi, gam, rowb, ispos, S, lam, phit, MD, jst, JB, NZ, IM = wk
    ACT, NACT, GEO, ZC, ZS, ZM, ZB = DV
    CSH, BOXR, BOXA, BOXE, PP, PST, PSG, FX, BPC = CT
    KR, RSG = RD
    if PP.shape[0] > 0:
        contacts_awake(Y, 7 * BODY.shape[1], CSH, BOXR, BOXA, BOXE, PP, PST, PSG[s], FX, BPC, cfg[C_NEXP],
                       cfg[C_CHI], cfg[C_MU_C], cfg[C_FCODE], cfg[C_FV0], cfg[C_FV1], cfg[C_FVS], cfg[C_VMIN],
                       cfg[C_LAW], cfg[C_REST], awake)
    else:
        FX[:, :] = 0.0
    # chassis-road contact (regularised Coulomb with the road's friction)
    road_contacts(Y, 7 * BODY.shape[1], CSH, KR, cfg[C_ROAD_N], cfg[C_ROAD_CHI], cfg[C_MU], ROAD_FRICTION_LAW,
                  cfg[C_FV0], cfg[C_FV1], cfg[C_FVS], FX, RSG[s])
    for v in range(Y.shape[0]):
        if awake[v]:
            brake = 0.0
            if NACT[v] > 1:
                brake = _drive(ACT[v], NACT[v], GEO[v], JNT[v], te)
            rhs(Y[v], K[s, v], BODY[v], JNT[v], SPR[v], TYR[v], cfg, A[v], R[v], V[v], W[v], Q[v], D[v],
                phi[v], gam[v], rowb[v], ispos[v], S[v], lam[v], aux[v], FX[v], phit[v], brake, ZC, ZS, ZM, ZB,
                MD[v], jst[v], JB[v], NZ[v], IM[v])
        else:
            K[s, v, :] = 0.0


@njit(cache=True)
def ackermann(L, yk, steer):
    """Steer angle of a front wheel at lateral position yk on an Ackermann linkage with `steer` at the axle
    centre (as common/vehicle_3d.steer_angles, compiled)."""
    if steer == 0.0:
        return 0.0
    rr = L / math.tan(steer)
    if rr > 0:
        return math.atan2(L, rr - yk)
    return -math.atan2(L, -(rr - yk))


@njit(cache=True)
def _drive(A, n, geo, JNT, te):
    """The driver's inputs of one vehicle at time te (common/driver_inputs.py): turns the front knuckles'
    steering axes to the Ackermann angles of the steer now, with its rate (the rheonomic steering row,
    joints.J_DDELTA), if the vehicle steers at all (geo[3]); returns the brake fraction."""
    _, brake, steer = driver_inputs(A, n, te)
    if geo[3] > 0.0:
        sd = steer_rate(A, n, te)
        eps = 1e-6
        for k in range(2):
            d = ackermann(geo[0], geo[1 + k], steer)
            row = JNT[k]
            row[J_XI], row[J_XI + 1], row[J_XI + 2] = math.cos(d), math.sin(d), 0.0
            row[J_YI], row[J_YI + 1], row[J_YI + 2] = -math.sin(d), math.cos(d), 0.0
            row[J_DDELTA] = 0.0
            if sd != 0.0:
                row[J_DDELTA] = sd * (ackermann(geo[0], geo[1 + k], steer + eps)
                                      - ackermann(geo[0], geo[1 + k], steer - eps)) / (2 * eps)
    return brake


@njit(cache=True)
def _dackermann(L, yk, steer):
    eps = 1e-6
    return (ackermann(L, yk, steer + eps) - ackermann(L, yk, steer - eps)) / (2 * eps)


@njit(cache=True)
def steer_jump(y, A, n, geo, t, nb):
    """At a change of the driver's steer law at t: turn the front knuckles and wheels about the chassis's
    vertical by the jump of their Ackermann angle (a steer without ramp) and give them the jump of the steer
    rate (a ramp starting or ending), so that the rheonomic steering row (joints._steer_terms) holds at
    position and velocity level from t on instead of being pulled there by Baumgarte."""
    tb = t - 1e-9 * (1.0 + abs(t))
    s0, s1 = driver_inputs(A, n, tb)[2], driver_inputs(A, n, t)[2]
    r0, r1 = steer_rate(A, n, tb), steer_rate(A, n, t)
    if s0 == s1 and r0 == r1:
        return
    nq = 7 * nb
    a = rotation_entries(y[3], y[4], y[5], y[6])
    zc = (a[2], a[5], a[8])
    for k in range(2):
        dd = ackermann(geo[0], geo[1 + k], s1) - ackermann(geo[0], geo[1 + k], s0)
        dr = r1 * _dackermann(geo[0], geo[1 + k], s1) - r0 * _dackermann(geo[0], geo[1 + k], s0)
        q0, sh = math.cos(0.5 * dd), math.sin(0.5 * dd)
        q = (sh * zc[0], sh * zc[1], sh * zc[2])
        for b in (1 + k, 5 + k):
            o = 7 * b + 3
            p0, pv = y[o], (y[o + 1], y[o + 2], y[o + 3])
            c = cross(q, pv)
            y[o] = q0 * p0 - dot(q, pv)
            for i in range(3):
                y[o + 1 + i] = q0 * pv[i] + p0 * q[i] + c[i]
            e = rotation_entries(y[o], y[o + 1], y[o + 2], y[o + 3])
            for i in range(3):
                y[nq + 6 * b + 3 + i] += dr * (e[i] * zc[0] + e[3 + i] * zc[1] + e[6 + i] * zc[2])


@njit(cache=True)
def next_break(ACT, NACT, t):
    """The first time after t at which any vehicle's driver input changes its law (common/driver_inputs.
    next_change: an action's start or its ramp's end); inf if none. No step straddles one."""
    tb = math.inf
    for v in range(ACT.shape[0]):
        tb = min(tb, next_change(ACT[v], NACT[v], t))
    return tb


@njit(cache=True)
def apply_modes(y, JNT, TYR, A, n, t, struck, nb):
    """Set one vehicle's wheel states to the driver's state at t (locked_after_impact: locked once struck):
    a wheel that locks gets its knuckle-wheel joint locked at its present orientation (lock_joint), one that
    is released gets its revolute joint back; the tyre rows carry the state (braked: ABS torque; rolling: the
    brake fraction). Returns True if anything changed."""
    mode = effective_mode(driver_inputs(A, n, t)[0], struck)
    changed = False
    for k in range(NW):
        row = JNT[NW + k]
        typ = int(row[J_TYPE])
        if mode == LOCKED and typ == REVOLUTE:
            lock_joint(y, row, nb)
            changed = True
        elif mode != LOCKED and typ == REVOLUTE_LOCKED:
            row[J_TYPE] = REVOLUTE
            changed = True
        if int(TYR[k, T_MODE]) != mode:
            TYR[k, T_MODE] = mode
            changed = True
    return changed


@njit(cache=True)
def dp_step(Y, t, h, t_lim, K, Ytmp, Ynew, awake, BODY, JNT, SPR, TYR, cfg, wk, aux, CT, RD, DV):
    """One Dormand-Prince step from Y at t (K[0] = f(Y) given); fills Ynew and K[1..6] (K[6] = f(Ynew)).
    Stage times are held just below t_lim (the next change of the driver's law; the step ends there)."""
    nv, ny = Y.shape
    for s in range(1, 7):
        for v in range(nv):
            if not awake[v]:
                continue
            for i in range(ny):
                acc = 0.0
                for j in range(s):
                    acc += _A[s, j] * K[j, v, i]
                Ytmp[v, i] = Y[v, i] + h * acc
        if s == 6:
            Ynew[:, :] = Ytmp
            for v in range(nv):
                if not awake[v]:
                    Ynew[v] = Y[v]
        eval_all(Ytmp, K, s, min(t + _C[s] * h, t_lim - 1e-12), awake, BODY, JNT, SPR, TYR, cfg, wk, aux, CT, RD,
                 DV)


@njit(cache=True)
def error_norm(Y, Ynew, K, h, awake, nq, nvq, nslip, rtol, atol):
    acc, n = 0.0, 0
    for v in range(Y.shape[0]):
        if not awake[v]:
            continue
        for i in range(nvq + nslip):
            e = 0.0
            for j in range(7):
                e += _E[j] * K[j, v, i]
            e *= h
            if i < nq:
                sc = atol + rtol          # positions and Euler parameters: absolute scale 1 m / 1
            else:
                sc = atol + rtol * max(abs(Y[v, i]), abs(Ynew[v, i]))
            acc += (e / sc) ** 2
            n += 1
    return math.sqrt(acc / max(n, 1))


@njit(cache=True)
def normalise(Y, nb):
    worst = 0.0
    for v in range(Y.shape[0]):
        for b in range(nb):
            o = 7 * b + 3
            n = math.sqrt(Y[v, o] ** 2 + Y[v, o + 1] ** 2 + Y[v, o + 2] ** 2 + Y[v, o + 3] ** 2)
            worst = max(worst, abs(n - 1.0))
            for k in range(4):
                Y[v, o + k] /= n
    return worst


@njit(cache=True)
def pose(y, BODY, nb):
    """(x, y, z, heading, roll, pitch, vx, vy, yaw_rate): vehicle CG (all bodies), chassis angles (ZYX),
    CG velocity (global), chassis yaw rate (global z)."""
    nq = 7 * nb
    m = 0.0
    c = np.zeros(6)
    for b in range(nb):
        mb = BODY[b, B_MASS]
        m += mb
        for k in range(3):
            c[k] += mb * y[7 * b + k]
            c[3 + k] += mb * y[nq + 6 * b + k]
    a = rotation_entries(y[3], y[4], y[5], y[6])
    yaw = math.atan2(a[3], a[0])
    pitch = math.asin(max(-1.0, min(1.0, -a[6])))
    roll = math.atan2(a[7], a[8])
    # yaw rate = (A w')_z
    w = y[nq + 3:nq + 6]
    r = a[6] * w[0] + a[7] * w[1] + a[8] * w[2]
    return (c[0] / m, c[1] / m, c[2] / m, yaw, roll, pitch, c[3] / m, c[4] / m, r)


@njit(cache=True)
def _headings(Y, BODY, hprev, out):
    for v in range(Y.shape[0]):
        p = pose(Y[v], BODY[v], BODY.shape[1])
        d = p[3] - hprev[v]
        d = (d + math.pi) % (2 * math.pi) - math.pi
        out[v] = hprev[v] + d


@njit(cache=True)
def _record(traj, n, t, Y, BODY, head, aux, RSG0, road, SPR, TYR, g):
    if n >= traj.shape[0]:
        return n
    nb = BODY.shape[1]
    Ae, Re, Ve, We = np.empty((nb, 3, 3)), np.empty((nb, 3)), np.empty((nb, 3)), np.empty((nb, 3))
    for v in range(Y.shape[0]):
        traj[n, v, R_EMECH] = energy(Y[v], BODY[v], SPR[v], TYR[v], g, Ae, Re, Ve, We)
        traj[n, v, R_ZMIN_REC] = RSG0[v, R_ZMIN]
        traj[n, v, R_ROAD] = road[v]
        road[v] = 0.0
        p = pose(Y[v], BODY[v], BODY.shape[1])
        traj[n, v, R_T] = t
        traj[n, v, R_X], traj[n, v, R_Y], traj[n, v, R_Z] = p[0], p[1], p[2]
        traj[n, v, R_HEAD], traj[n, v, R_ROLL], traj[n, v, R_PITCH] = head[v], p[4], p[5]
        traj[n, v, R_VX], traj[n, v, R_VY], traj[n, v, R_YAW_RATE] = p[6], p[7], p[8]
        for k in range(4):
            traj[n, v, R_FZ + k] = aux[v, AUX_FZ + k]
    return n + 1


@njit(cache=True)
def lock_wheels(y, JNT, nb):
    """Lock every free revolute joint of one vehicle (lock_joint). Returns True if changed."""
    changed = False
    for jn in range(JNT.shape[0]):
        if int(JNT[jn, J_TYPE]) == REVOLUTE:
            lock_joint(y, JNT[jn], nb)
            changed = True
    return changed


@njit(cache=True)
def lock_joint(y, row, nb):
    """Lock one revolute knuckle-wheel joint (a wheel that locks: locked_after_impact struck, or a driver's
    action): the joint becomes REVOLUTE_LOCKED with its reference axis set to the current relative
    orientation (zero violation), and the wheel's spin relative to its knuckle is removed (an impulsive
    lock)."""
    nq = 7 * nb
    A = np.empty((nb, 3, 3))
    bk, bw = int(row[J_I]), int(row[J_J])
    for b in (bk, bw):
        rotation_into(y[7 * b + 3], y[7 * b + 4], y[7 * b + 5], y[7 * b + 6], A, b)
    # reference: the knuckle's local axis x_i' = row[J_XI] (perpendicular to the spin axis and to
    # y_i') expressed in the wheel frame, so that n1(y_i, x_j) = 0 now
    xg = np.zeros(3)
    for k in range(3):
        xg[k] = A[bk, k, 0] * row[J_XI] + A[bk, k, 1] * row[J_XI + 1] + A[bk, k, 2] * row[J_XI + 2]
    for k in range(3):
        row[J_XJ + k] = A[bw, 0, k] * xg[0] + A[bw, 1, k] * xg[1] + A[bw, 2, k] * xg[2]
    row[J_TYPE] = REVOLUTE_LOCKED
    wk = y[nq + 6 * bk + 3:nq + 6 * bk + 6]
    wg = np.zeros(3)
    for k in range(3):
        wg[k] = A[bk, k, 0] * wk[0] + A[bk, k, 1] * wk[1] + A[bk, k, 2] * wk[2]
    for k in range(3):
        y[nq + 6 * bw + 3 + k] = A[bw, 0, k] * wg[0] + A[bw, 1, k] * wg[1] + A[bw, 2, k] * wg[2]


@njit(cache=True)
def _new_penetration(PST, PSG6):
    """Largest penetration at the end of a trial step among pairs not yet in contact."""
    best = -1e300
    for p in range(PST.shape[0]):
        if PST[p, S_ACT] == 0.0 and PSG6[p, G_DEL] > best:
            best = PSG6[p, G_DEL]
    return best


@njit(cache=True)
def _velocity(Y, BODY, v):
    """(vx, vy, yaw rate) of vehicle v's CG, zeros for a barrier (v >= number of vehicles)."""
    if v >= Y.shape[0]:
        return (0.0, 0.0, 0.0)
    p = pose(Y[v], BODY[v], BODY.shape[1])
    return (p[6], p[7], p[8])


@njit(cache=True)
def _close(IMP, diag, p, PP, PST, PSG6, Y, BODY, t, is_open):
    """Close the contact episode of pair p at t (common/contact_episodes.py), counted in diag[D_NIMP]."""
    diag[D_NIMP] = close_episode(IMP, int(diag[D_NIMP]), PP, PST, p, t, PSG6[p, G_DDOT], is_open,
                                 _velocity(Y, BODY, int(PP[p, P_I])), _velocity(Y, BODY, int(PP[p, P_J])))


@njit(cache=True)
def simulate(Y, BODY, JNT, SPR, TYR, CT, DV, cfg, nslip, traj, diag, head, fz_start, fz_end, check_events,
             IMP, CONT, RD, ASLEEP0):
    """Integrate all vehicles from Y (modified in place) until rest or t_end, with vehicle contact
    (common/chassis_contact.py): first-contact control (no step ends with a new contact deeper than onset_tol),
    per-pair contact episodes recorded in IMP, state at first contact in CONT; chassis-road contact
    (common/road_contact.py, RD = (KR, RSG[7, nv, N_RSG])). ASLEEP0[v]: vehicle v starts asleep in its
    start state (velocities zeroed) unless it penetrates another body at the start; it wakes on contact like
    any sleeping vehicle. DV (model.driver_arrays): the drivers' action tables and the road's friction zones
    (docs/physics.md §2a): no step straddles a change of a driver's law (next_break); at one, the wheel
    states are set anew (apply_modes) and the accelerations re-evaluated. JNT and TYR are changed in place."""
    nv, ny = Y.shape
    nb = BODY.shape[1]
    nq, nvq = 7 * nb, 13 * nb
    CSH, BOXR, BOXA, BOXE, PP, PST, PSG, FX, BPC = CT
    RSG = RD[1]
    road = np.zeros(nv)
    npair = PP.shape[0]
    wk = make_work(nv, nb)
    K = np.zeros((7, nv, ny))
    Ytmp, Ynew, Y0 = np.empty_like(Y), np.empty_like(Y), np.empty_like(Y)
    aux = np.zeros((nv, N_AUX))
    awake = np.ones(nv, np.bool_)
    struck = np.zeros(nv, np.bool_)
    ACT, NACT = DV[0], DV[1]
    t_lim = next_break(ACT, NACT, 0.0)
    still = np.zeros(nv)
    hnew = np.empty(nv)
    rtol, atol, hmax = cfg[C_RTOL], cfg[C_ATOL], cfg[C_HMAX]
    t_end, rec_dt, tol = cfg[C_TEND], cfg[C_REC_DT], cfg[C_ONSET_TOL]
    diag[:] = 0.0
    diag[D_CONTACT_T] = math.nan
    diag[D_H_MIN] = 1e300
    diag[D_MAX_NORM_ERR] = normalise(Y, nb)
    _headings(Y, BODY, head, head)
    eval_all(Y, K, 0, 0.0, awake, BODY, JNT, SPR, TYR, cfg, wk, aux, CT, RD, DV)
    fz_start[:, :] = aux[:, AUX_FZ:AUX_FZ + 4]
    # vehicles starting asleep (the first evaluation above had every vehicle awake: all pairs measured)
    for v in range(nv):
        if not ASLEEP0[v]:
            continue
        touching = False
        for p in range(npair):
            if (int(PP[p, P_I]) == v or int(PP[p, P_J]) == v) and PSG[0, p, G_DEL] > 0.0:
                touching = True
        if not touching:
            awake[v] = False
            fz_end[v, :] = aux[v, AUX_FZ:AUX_FZ + 4]
            Y[v, nq:nvq] = 0.0
            K[0, v, :] = 0.0
    Ytmp[:, :] = Y    # a sleeping vehicle's stage state (dp_step writes only the awake ones)
    nfev = 1
    nrec = _record(traj, 0, 0.0, Y, BODY, head, aux, RSG[0], road, SPR, TYR, cfg[C_G])
    t_rec = rec_dt
    t, h = 0.0, cfg[C_H0]
    status = STATUS_OK
    bw = _A[6]
    expo = 0.2 - 0.75 * cfg[C_PI_BETA]
    errold, rejected = 1e-4, False
    while t < t_end * (1 - 1e-12):
        h = min(h, hmax, t_end - t)
        h_free = h
        at_break = t + h >= t_lim - 1e-10
        if at_break:
            h = t_lim - t
        dp_step(Y, t, h, t_lim, K, Ytmp, Ynew, awake, BODY, JNT, SPR, TYR, cfg, wk, aux, CT, RD, DV)
        nfev += 6
        err = error_norm(Y, Ynew, K, h, awake, nq, nvq, nslip, rtol, atol)
        if not (err == err):
            if h < 1e-9:
                status = STATUS_NAN
                break
            h *= 0.1
            h_free = h
            diag[D_REJECTED] += 1
            continue
        if err > 1.0:
            diag[D_REJECTED] += 1
            h *= max(0.2, 0.9 * err ** -expo)
            h_free = h
            rejected = True
            if h < 1e-10:
                status = STATUS_STEP
                break
            continue
        # first-contact control (docs/physics.md §15): a step may not end with a new contact deeper than tol
        if check_events and npair > 0 and _new_penetration(PST, PSG[6]) > tol:
            lo, hi = 0.0, h
            found = False
            for _ in range(60):
                mid = 0.5 * (lo + hi)
                dp_step(Y, t, mid, t_lim, K, Ytmp, Ynew, awake, BODY, JNT, SPR, TYR, cfg, wk, aux, CT, RD, DV)
                nfev += 6
                dm = _new_penetration(PST, PSG[6])
                if dm > tol:
                    hi = mid
                elif dm > 0.0:
                    h = mid
                    found = True
                    break
                else:
                    lo = mid
                if hi - lo < 1e-12:
                    break
            if not found:
                h = hi
                dp_step(Y, t, h, t_lim, K, Ytmp, Ynew, awake, BODY, JNT, SPR, TYR, cfg, wk, aux, CT, RD, DV)
                nfev += 6
            diag[D_ONSET_BISECT] += 1
            at_break = False
        # accepted
        Y0[:, :] = Y
        Y[:, :] = Ynew
        t = t_lim if at_break else t + h
        diag[D_STEPS] += 1
        diag[D_H_MIN] = min(diag[D_H_MIN], h)
        diag[D_H_MAX] = max(diag[D_H_MAX], h)
        diag[D_MAX_NORM_ERR] = max(diag[D_MAX_NORM_ERR], normalise(Y, nb))
        for v in range(nv):
            if awake[v]:
                diag[D_MAX_DRIFT_POS] = max(diag[D_MAX_DRIFT_POS], aux[v, AUX_DRIFT_POS])
                diag[D_MAX_DRIFT_ANG] = max(diag[D_MAX_DRIFT_ANG], aux[v, AUX_DRIFT_ANG])
        K[0] = K[6]
        _headings(Y, BODY, head, hnew)
        head[:] = hnew
        # contact episodes: accumulate (DP weights), then open / close
        need_k0 = False
        for p in range(npair):
            for s in range(7):
                if s < 6:
                    accumulate(PST, p, h * bw[s], PSG[s, p])
                track_peak(PST, p, PSG[s, p])
            d6 = PSG[6, p, G_DEL]
            i, j = int(PP[p, P_I]), int(PP[p, P_J])
            if PST[p, S_ACT] == 0.0:
                if d6 > 0.0:
                    open_episode(PST, p, t, max(PSG[6, p, G_DDOT], cfg[C_VMIN]), _velocity(Y, BODY, i),
                                 _velocity(Y, BODY, j))
                    diag[D_MAX_ONSET] = max(diag[D_MAX_ONSET], d6)
                    if not (diag[D_CONTACT_T] == diag[D_CONTACT_T]):
                        diag[D_CONTACT_T] = t
                        diag[D_PAIR_I], diag[D_PAIR_J] = i, j
                        for v in range(nv):
                            pv = pose(Y[v], BODY[v], nb)
                            CONT[v, 0], CONT[v, 1], CONT[v, 2] = pv[0], pv[1], head[v]
                            CONT[v, 3] = math.sqrt(pv[6] ** 2 + pv[7] ** 2)
                    for v in (i, j):
                        if v >= nv:
                            continue
                        if not struck[v]:
                            struck[v] = True
                            if apply_modes(Y[v], JNT[v], TYR[v], ACT[v], NACT[v], t, True, nb):
                                need_k0 = True
                        if not awake[v]:
                            awake[v] = True
                            still[v] = 0.0
                            need_k0 = True
                else:
                    reset_sums(PST, p)
            elif d6 <= 0.0:
                _close(IMP, diag, p, PP, PST, PSG[6], Y, BODY, t, 0.0)
            if PST[p, S_ACT] > 0.0:
                for v in (i, j):
                    if v < nv and not awake[v]:
                        awake[v] = True
                        still[v] = 0.0
                        need_k0 = True
        for p in range(npair):
            for k in range(PSG.shape[2]):
                PSG[0, p, k] = PSG[6, p, k]
        for v in range(nv):
            for s in range(7):
                if RSG[s, v, R_DEL] > 0.0:
                    road[v] = 1.0
            for k in range(RSG.shape[2]):
                RSG[0, v, k] = RSG[6, v, k]
        if at_break:
            # a driver's law changes at t (next_break): new wheel states, new brake / steer law from t on
            for v in range(nv):
                if awake[v] and DV[2][v, 3] > 0.0:
                    steer_jump(Y[v], ACT[v], NACT[v], DV[2][v], t, nb)
                apply_modes(Y[v], JNT[v], TYR[v], ACT[v], NACT[v], t, struck[v], nb)
            t_lim = next_break(ACT, NACT, t)
            need_k0 = True
        if need_k0:
            eval_all(Y, K, 0, t, awake, BODY, JNT, SPR, TYR, cfg, wk, aux, CT, RD, DV)
            nfev += 1
        # rest: a vehicle still for t_sleep goes to sleep (not while it is in contact)
        for v in range(nv):
            if not awake[v]:
                continue
            sp = math.sqrt(Y[v, nq] ** 2 + Y[v, nq + 1] ** 2 + Y[v, nq + 2] ** 2)
            wn = math.sqrt(Y[v, nq + 3] ** 2 + Y[v, nq + 4] ** 2 + Y[v, nq + 5] ** 2)
            if sp < cfg[C_V_REST] and wn < cfg[C_W_REST]:
                still[v] += h
            else:
                still[v] = 0.0
            if still[v] >= cfg[C_T_SLEEP]:
                awake[v] = False
                fz_end[v, :] = aux[v, AUX_FZ:AUX_FZ + 4]
                Y[v, nq:nvq] = 0.0
                K[0, v, :] = 0.0
        if t >= t_rec - 1e-12:
            nrec = _record(traj, nrec, t, Y, BODY, head, aux, RSG[0], road, SPR, TYR, cfg[C_G])
            t_rec = t + rec_dt
        if cfg[C_STOP_AT_REST] > 0 and not awake.any():
            break
        # PI step-size control (Hairer, Norsett & Wanner, Solving ODE I, section II.4, DOPRI5's beta): the error
        # of the previous accepted step damps the oscillation of the step size at the stability limit;
        # no growth right after a rejection
        fac = 0.9 * err ** -expo * errold ** cfg[C_PI_BETA] if err > 0 else 5.0
        fac = min(5.0, max(0.2, fac))
        if rejected:
            fac = min(fac, 1.0)
        h *= fac
        errold = max(err, 1e-4)
        rejected = False
        if at_break:
            h = max(h, h_free)    # the step was shortened to end at the change, not for accuracy
    for p in range(npair):
        if PST[p, S_ACT] > 0.0:
            _close(IMP, diag, p, PP, PST, PSG[6], Y, BODY, t, 1.0)
    for v in range(nv):
        if awake[v]:
            fz_end[v, :] = aux[v, AUX_FZ:AUX_FZ + 4]
    if traj.shape[0] > 0 and (nrec == 0 or traj[nrec - 1, 0, R_T] < t):
        nrec = _record(traj, nrec, t, Y, BODY, head, aux, RSG[0], road, SPR, TYR, cfg[C_G])
    diag[D_T_END] = t
    diag[D_STATUS] = status
    diag[D_NFEV] = nfev
    diag[D_NREC] = nrec
    return t
