"""The time loop: Dormand-Prince 5(4) with FSAL and PI-free step control, hand-rolled in numba, over all
vehicles of a scene at once (one step size, error norm over the awake vehicles).

Scene awareness: step sizes grow up to h_max while nothing happens; a vehicle whose chassis has been
still (speed < v_rest, angular speed < w_rest) for t_sleep goes to sleep (velocities zeroed, no more
force evaluations); the run ends when every vehicle sleeps (stop_at_rest) or at t_end. Events: after
each accepted step the planar outlines of every pair of vehicles (and vehicle/barrier) are tested
(crashlab.geometry.penetration); on overlap the step is bisected (re-integrated from its start) until
the overlap is in (0, onset_tol], so the run stops exactly at contact onset (the hook for issue 5).
Euler parameters are renormalised after every accepted step.
"""
import math

import numpy as np
from numba import njit

from crashlab.geometry import penetration, rect_corners

from .equations import (
    AUX_DRIFT_ANG,
    AUX_DRIFT_POS,
    AUX_FZ,
    B_MASS,
    C_ATOL,
    C_H0,
    C_HMAX,
    C_ONSET_TOL,
    C_REC_DT,
    C_RTOL,
    C_STOP_AT_REST,
    C_T_SLEEP,
    C_TEND,
    C_V_REST,
    C_W_REST,
    MAX_ROWS,
    N_AUX,
    rhs,
)

# Dormand-Prince 5(4) tableau
_C = np.array([0.0, 1 / 5, 3 / 10, 4 / 5, 8 / 9, 1.0, 1.0])
_A = np.array([
    [0, 0, 0, 0, 0, 0],
    [1 / 5, 0, 0, 0, 0, 0],
    [3 / 40, 9 / 40, 0, 0, 0, 0],
    [44 / 45, -56 / 15, 32 / 9, 0, 0, 0],
    [19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729, 0, 0],
    [9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656, 0],
    [35 / 384, 0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84]])
_E = np.array([71 / 57600, 0.0, -71 / 16695, 71 / 1920, -17253 / 339200, 22 / 525, -1 / 40])

STATUS_OK, STATUS_CONTACT, STATUS_NAN, STATUS_STEP = 0, 1, 2, 3
(D_STEPS, D_REJECTED, D_NFEV, D_T_END, D_STATUS, D_CONTACT_T, D_PAIR_I, D_PAIR_J, D_MAX_DRIFT_POS,
 D_MAX_DRIFT_ANG, D_MAX_NORM_ERR, D_NREC, D_H_MIN, D_H_MAX) = range(14)
N_DIAG = 14
# trajectory record columns
(R_T, R_X, R_Y, R_Z, R_HEAD, R_ROLL, R_PITCH, R_VX, R_VY, R_YAW_RATE) = range(10)
R_FZ = 10
N_REC = 14


class Work:
    pass


@njit(cache=True)
def make_work(nv, nb):
    return (np.empty((nv, nb, 3, 3)), np.empty((nv, nb, 3)), np.empty((nv, nb, 3)), np.empty((nv, nb, 3)),
            np.empty((nv, nb, 6)), np.empty((nv, MAX_ROWS, 12)), np.empty((nv, MAX_ROWS)),
            np.empty((nv, MAX_ROWS)), np.empty((nv, MAX_ROWS, 2), np.int64), np.empty((nv, MAX_ROWS), np.bool_),
            np.empty((nv, MAX_ROWS, MAX_ROWS)), np.empty((nv, MAX_ROWS)))


@njit(cache=True)
def eval_all(Y, K, s, awake, BODY, JNT, SPR, TYR, cfg, wk, aux):
    A, R, V, W, Q, D, phi, gam, rowb, ispos, S, lam = wk
    for v in range(Y.shape[0]):
        if awake[v]:
            rhs(Y[v], K[s, v], BODY[v], JNT[v], SPR[v], TYR[v], cfg, A[v], R[v], V[v], W[v], Q[v], D[v],
                phi[v], gam[v], rowb[v], ispos[v], S[v], lam[v], aux[v])
        else:
            K[s, v, :] = 0.0


@njit(cache=True)
def dp_step(Y, h, K, Ytmp, Ynew, awake, BODY, JNT, SPR, TYR, cfg, wk, aux):
    """One Dormand-Prince step from Y (K[0] = f(Y) given); fills Ynew and K[1..6] (K[6] = f(Ynew))."""
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
        eval_all(Ytmp, K, s, awake, BODY, JNT, SPR, TYR, cfg, wk, aux)


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
    e0, e1, e2, e3 = y[3], y[4], y[5], y[6]
    a00 = e0 * e0 + e1 * e1 - e2 * e2 - e3 * e3
    a10 = 2 * (e1 * e2 + e0 * e3)
    a20 = 2 * (e1 * e3 - e0 * e2)
    a21 = 2 * (e2 * e3 + e0 * e1)
    a22 = e0 * e0 - e1 * e1 - e2 * e2 + e3 * e3
    yaw = math.atan2(a10, a00)
    pitch = math.asin(max(-1.0, min(1.0, -a20)))
    roll = math.atan2(a21, a22)
    # yaw rate = (A w')_z
    w = y[nq + 3:nq + 6]
    r = a20 * w[0] + a21 * w[1] + a22 * w[2]
    return (c[0] / m, c[1] / m, c[2] / m, yaw, roll, pitch, c[3] / m, c[4] / m, r)


@njit(cache=True)
def _outline(Y, v, BODY, OUTL, head):
    p = pose(Y[v], BODY[v], BODY.shape[1])
    return rect_corners(p[0], p[1], head[v], OUTL[v, 0], OUTL[v, 1], OUTL[v, 2])


@njit(cache=True)
def max_overlap(Y, BODY, OUTL, BAR, head):
    """Largest overlap of the planar outlines over all pairs (and barriers); returns (depth, i, j)."""
    nv = Y.shape[0]
    best, bi, bj = -1e300, -1, -1
    for i in range(nv):
        ci = _outline(Y, i, BODY, OUTL, head)
        for j in range(i + 1, nv):
            d = penetration(ci, _outline(Y, j, BODY, OUTL, head))[0]
            if d > best:
                best, bi, bj = d, i, j
        for k in range(BAR.shape[0]):
            cb = rect_corners(BAR[k, 0], BAR[k, 1], BAR[k, 2], BAR[k, 3], BAR[k, 3], BAR[k, 4])
            d = penetration(ci, cb)[0]
            if d > best:
                best, bi, bj = d, i, nv + k
    return best, bi, bj


@njit(cache=True)
def _headings(Y, BODY, hprev, out):
    for v in range(Y.shape[0]):
        p = pose(Y[v], BODY[v], BODY.shape[1])
        d = p[3] - hprev[v]
        d = (d + math.pi) % (2 * math.pi) - math.pi
        out[v] = hprev[v] + d


@njit(cache=True)
def _record(traj, n, t, Y, BODY, head, aux):
    if n >= traj.shape[0]:
        return n
    for v in range(Y.shape[0]):
        p = pose(Y[v], BODY[v], BODY.shape[1])
        traj[n, v, R_T] = t
        traj[n, v, R_X], traj[n, v, R_Y], traj[n, v, R_Z] = p[0], p[1], p[2]
        traj[n, v, R_HEAD], traj[n, v, R_ROLL], traj[n, v, R_PITCH] = head[v], p[4], p[5]
        traj[n, v, R_VX], traj[n, v, R_VY], traj[n, v, R_YAW_RATE] = p[6], p[7], p[8]
        for k in range(4):
            traj[n, v, R_FZ + k] = aux[v, AUX_FZ + k]
    return n + 1


@njit(cache=True)
def simulate(Y, BODY, JNT, SPR, TYR, OUTL, BAR, cfg, nslip, traj, diag, head, fz_start, fz_end, check_events):
    """Integrate all vehicles from Y (modified in place) until rest, t_end or contact onset."""
    nv, ny = Y.shape
    nb = BODY.shape[1]
    nq, nvq = 7 * nb, 13 * nb
    wk = make_work(nv, nb)
    K = np.zeros((7, nv, ny))
    Ytmp, Ynew, Y0 = np.empty_like(Y), np.empty_like(Y), np.empty_like(Y)
    aux = np.zeros((nv, N_AUX))
    awake = np.ones(nv, np.bool_)
    still = np.zeros(nv)
    hnew = np.empty(nv)
    rtol, atol, hmax = cfg[C_RTOL], cfg[C_ATOL], cfg[C_HMAX]
    t_end, rec_dt = cfg[C_TEND], cfg[C_REC_DT]
    diag[:] = 0.0
    diag[D_CONTACT_T] = math.nan
    diag[D_H_MIN] = 1e300
    diag[D_MAX_NORM_ERR] = normalise(Y, nb)
    _headings(Y, BODY, head, head)
    eval_all(Y, K, 0, awake, BODY, JNT, SPR, TYR, cfg, wk, aux)
    fz_start[:, :] = aux[:, AUX_FZ:AUX_FZ + 4]
    nfev = 1
    nrec = _record(traj, 0, 0.0, Y, BODY, head, aux)
    t_rec = rec_dt
    t, h = 0.0, cfg[C_H0]
    status = STATUS_OK
    while t < t_end * (1 - 1e-12):
        h = min(h, hmax, t_end - t)
        dp_step(Y, h, K, Ytmp, Ynew, awake, BODY, JNT, SPR, TYR, cfg, wk, aux)
        nfev += 6
        err = error_norm(Y, Ynew, K, h, awake, nq, nvq, nslip, rtol, atol)
        if not (err == err):
            if h < 1e-9:
                status = STATUS_NAN
                break
            h *= 0.1
            diag[D_REJECTED] += 1
            continue
        if err > 1.0:
            diag[D_REJECTED] += 1
            h *= max(0.2, 0.9 * err ** -0.2)
            if h < 1e-10:
                status = STATUS_STEP
                break
            continue
        # accepted
        Y0[:, :] = Y
        Y[:, :] = Ynew
        t += h
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
        # contact onset
        if check_events:
            depth, bi, bj = max_overlap(Y, BODY, OUTL, BAR, head)
            if depth > 0.0:
                tol = cfg[C_ONSET_TOL]
                hprev = head.copy()
                lo, hi = 0.0, h
                Yc = Y.copy()
                for _ in range(60):
                    if depth <= tol:
                        break
                    mid = 0.5 * (lo + hi)
                    K[0] = 0.0
                    eval_all(Y0, K, 0, awake, BODY, JNT, SPR, TYR, cfg, wk, aux)
                    dp_step(Y0, mid, K, Ytmp, Ynew, awake, BODY, JNT, SPR, TYR, cfg, wk, aux)
                    nfev += 7
                    normalise(Ynew, nb)
                    _headings(Ynew, BODY, hprev, hnew)
                    dm, _, _ = max_overlap(Ynew, BODY, OUTL, BAR, hnew)
                    if dm > 0.0:
                        hi = mid
                        depth = dm
                        Yc[:, :] = Ynew
                        head[:] = hnew
                    else:
                        lo = mid
                t = t - h + hi
                Y[:, :] = Yc
                diag[D_CONTACT_T] = t
                diag[D_PAIR_I], diag[D_PAIR_J] = bi, bj
                status = STATUS_CONTACT
                break
        # rest: a vehicle still for t_sleep goes to sleep
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
            nrec = _record(traj, nrec, t, Y, BODY, head, aux)
            t_rec = t + rec_dt
        if cfg[C_STOP_AT_REST] > 0 and not awake.any():
            break
        h *= min(5.0, max(0.2, 0.9 * err ** -0.2)) if err > 0 else 5.0
    for v in range(nv):
        if awake[v]:
            fz_end[v, :] = aux[v, AUX_FZ:AUX_FZ + 4]
    if traj.shape[0] > 0 and (nrec == 0 or traj[nrec - 1, 0, R_T] < t):
        nrec = _record(traj, nrec, t, Y, BODY, head, aux)
    diag[D_T_END] = t
    diag[D_STATUS] = status
    diag[D_NFEV] = nfev
    diag[D_NREC] = nrec
    return t
