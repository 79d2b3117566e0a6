"""The drivers' inputs in the multibody time loop (common/driver_inputs.py, docs/physics.md §2a): the Ackermann
steer of the front knuckles (the rheonomic steering row and its jump at a change of the steer law), the times at
which a driver's law changes (no step straddles one), and the wheel states (rolling, braked, locked: a locked
wheel's knuckle-wheel joint is locked at its present orientation)."""
import math

import numpy as np
from numba import njit

from crashlab.models.common.driver_inputs import driver_inputs, effective_mode, next_change, steer_rate
from crashlab.models.common.rotations import cross, dot, rotation_entries, rotation_into
from crashlab.models.common.vehicle_3d import NW, T_MODE
from crashlab.models.common.wheel_states import LOCKED

from .joints import J_DDELTA, J_I, J_J, J_TYPE, J_XI, J_XJ, J_YI, REVOLUTE, REVOLUTE_LOCKED


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
def drive(A, n, geo, JNT, te):
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
def dackermann(L, yk, steer):
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
        dr = r1 * dackermann(geo[0], geo[1 + k], s1) - r0 * dackermann(geo[0], geo[1 + k], s0)
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
