"""What the multibody time loop records: the diagnostics vector (D_*), the trajectory rows (R_*), the vehicle's
pose (CG of all bodies, chassis angles) and its continuous heading."""
import math

import numpy as np
from numba import njit

from crashlab.models.common.road_contact import R_ZMIN
from crashlab.models.common.rotations import rotation_entries

from .equations import AUX_FZ, B_MASS, energy

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
def headings(Y, BODY, hprev, out):
    for v in range(Y.shape[0]):
        p = pose(Y[v], BODY[v], BODY.shape[1])
        d = p[3] - hprev[v]
        d = (d + math.pi) % (2 * math.pi) - math.pi
        out[v] = hprev[v] + d


@njit(cache=True)
def record(traj, n, t, Y, BODY, head, aux, RSG0, road, SPR, TYR, g):
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
def velocity(Y, BODY, v):
    """(vx, vy, yaw rate) of vehicle v's CG, zeros for a barrier (v >= number of vehicles)."""
    if v >= Y.shape[0]:
        return (0.0, 0.0, 0.0)
    p = pose(Y[v], BODY[v], BODY.shape[1])
    return (p[6], p[7], p[8])
