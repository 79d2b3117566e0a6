"""Kinematic joints as constraint rows (docs/physics.md §7), with velocity Jacobians in the body-fixed
angular-velocity form: each row k has Phi_k, D_k = [d/d r_dot_i, d/d w'_i, d/d r_dot_j, d/d w'_j] (12
numbers) and gamma_k = -(D_dot v)_k, so that Phi_ddot = D v_dot - gamma.

Basic rows: n1(a_i, a_j) (two body-fixed unit vectors perpendicular), n2(a_i, d) (a_i perpendicular to
the joint vector d = r_j + s_Q - r_i - s_P), sph (d = 0, three rows). Joints:
  SPHERICAL     sph                                                   3 rows
  REVOLUTE      sph + n1(x_i, z_j) + n1(y_i, z_j)                     5 rows  (z = joint axis)
  CYLINDRICAL   n1(x_i, z_j) + n1(y_i, z_j) + n2(x_i, d) + n2(y_i, d)  4 rows
  TRANSLATIONAL CYLINDRICAL + n1(y_i, x_j)  (no rotation about z)     5 rows
  REVOLUTE_LOCKED  REVOLUTE + n1(y_i, x_j)  (a locked wheel)           6 rows
Joint table row (J_* indices): type, body i, body j, s'_P (on i), s'_Q (on j), joint frame on i
(x_i, y_i, z_i as body-fixed unit vectors), on j (x_j, z_j).
"""
import math

import numpy as np
from numba import njit

from crashlab.models.common.rotations import add, cross, dot, mtv, mv, scale, sub
from crashlab.models.common.vehicle_3d import NW
from crashlab.models.common.wheel_states import LOCKED

SPHERICAL, REVOLUTE, CYLINDRICAL, TRANSLATIONAL, REVOLUTE_LOCKED = 0, 1, 2, 3, 4
(J_TYPE, J_I, J_J) = range(3)
J_SP, J_SQ, J_XI, J_YI, J_ZI, J_XJ, J_ZJ = 3, 6, 9, 12, 15, 18, 21
# steer rate d(delta)/dt of a TRANSLATIONAL chassis-knuckle joint whose axes x_i, y_i turn with the driver's
# steer (rheonomic steering constraint, docs/physics.md §2a; 0 for a fixed steer angle)
J_DDELTA = 24
N_J = 25


@njit(cache=True, inline="always")
def _v3(a, k):
    return (a[k], a[k + 1], a[k + 2])


@njit(cache=True, inline="always")
def _acc0(A, b, w, s):
    """Acceleration of a body-fixed vector at zero angular acceleration: A (w' x (w' x s'))."""
    return mv(A, b, cross(w, cross(w, s)))


@njit(cache=True)
def _put(D, row, gi, gj):
    for k in range(12):
        D[row, k] = 0.0
    D[row, 3], D[row, 4], D[row, 5] = gi[0], gi[1], gi[2]
    D[row, 9], D[row, 10], D[row, 11] = gj[0], gj[1], gj[2]


@njit(cache=True)
def n1_row(A, i, j, wi, wj, ai_, aj_, D, phi, gam, row):
    """a_i . a_j = 0 for body-fixed a'_i on i and a'_j on j."""
    ai, aj = mv(A, i, ai_), mv(A, j, aj_)
    phi[row] = dot(ai, aj)
    _put(D, row, cross(ai_, mtv(A, i, aj)), cross(aj_, mtv(A, j, ai)))
    adi, adj = mv(A, i, cross(wi, ai_)), mv(A, j, cross(wj, aj_))
    gam[row] = -(dot(_acc0(A, i, wi, ai_), aj) + dot(ai, _acc0(A, j, wj, aj_)) + 2.0 * dot(adi, adj))


@njit(cache=True)
def n2_row(A, i, j, ri, rj, vi, vj, wi, wj, ai_, sp_, sq_, D, phi, gam, row):
    """a_i . d = 0, d = r_j + A_j s'_Q - r_i - A_i s'_P."""
    ai = mv(A, i, ai_)
    d = sub(add(rj, mv(A, j, sq_)), add(ri, mv(A, i, sp_)))
    phi[row] = dot(ai, d)
    gwi = sub(cross(ai_, mtv(A, i, d)), cross(sp_, ai_))
    gwj = cross(sq_, mtv(A, j, ai))
    _put(D, row, gwi, gwj)
    D[row, 0], D[row, 1], D[row, 2] = -ai[0], -ai[1], -ai[2]
    D[row, 6], D[row, 7], D[row, 8] = ai[0], ai[1], ai[2]
    adi = mv(A, i, cross(wi, ai_))
    dd = sub(add(vj, mv(A, j, cross(wj, sq_))), add(vi, mv(A, i, cross(wi, sp_))))
    sdd = sub(_acc0(A, j, wj, sq_), _acc0(A, i, wi, sp_))
    gam[row] = -(dot(_acc0(A, i, wi, ai_), d) + 2.0 * dot(adi, dd) + dot(ai, sdd))


@njit(cache=True)
def sph_rows(A, i, j, ri, rj, wi, wj, sp_, sq_, D, phi, gam, row):
    """d = 0 (three rows)."""
    d = sub(add(rj, mv(A, j, sq_)), add(ri, mv(A, i, sp_)))
    sdd = sub(_acc0(A, j, wj, sq_), _acc0(A, i, wi, sp_))
    for k in range(3):
        e = (1.0 if k == 0 else 0.0, 1.0 if k == 1 else 0.0, 1.0 if k == 2 else 0.0)
        _put(D, row + k, scale(-1.0, cross(sp_, mtv(A, i, e))), cross(sq_, mtv(A, j, e)))
        D[row + k, k] = -1.0
        D[row + k, 6 + k] = 1.0
        phi[row + k] = d[k]
        gam[row + k] = -sdd[k]


@njit(cache=True)
def joint_rows(J, A, R, V, W, D, phi, gam, rowb, ispos, row, phit):
    """Rows of one joint (J: its table row) from `row` on; returns the next free row.
    R, V: (nb, 3) positions and global velocities; W: (nb, 3) body-fixed angular velocities.
    phit[row]: the explicit time derivative dPhi/dt of a row (nonzero only for the steering row of a knuckle
    turned by the driver, J_DDELTA != 0; else 0)."""
    t = int(J[J_TYPE])
    i, j = int(J[J_I]), int(J[J_J])
    ri, rj = (R[i, 0], R[i, 1], R[i, 2]), (R[j, 0], R[j, 1], R[j, 2])
    vi, vj = (V[i, 0], V[i, 1], V[i, 2]), (V[j, 0], V[j, 1], V[j, 2])
    wi, wj = (W[i, 0], W[i, 1], W[i, 2]), (W[j, 0], W[j, 1], W[j, 2])
    sp, sq = _v3(J, J_SP), _v3(J, J_SQ)
    xi, yi, zj, xj = _v3(J, J_XI), _v3(J, J_YI), _v3(J, J_ZJ), _v3(J, J_XJ)
    r0 = row
    if t == SPHERICAL or t == REVOLUTE or t == REVOLUTE_LOCKED:
        sph_rows(A, i, j, ri, rj, wi, wj, sp, sq, D, phi, gam, row)
        for k in range(3):
            ispos[row + k] = True
        row += 3
    if t != SPHERICAL:
        n1_row(A, i, j, wi, wj, xi, zj, D, phi, gam, row)
        n1_row(A, i, j, wi, wj, yi, zj, D, phi, gam, row + 1)
        ispos[row] = False
        ispos[row + 1] = False
        row += 2
    if t == CYLINDRICAL or t == TRANSLATIONAL:
        n2_row(A, i, j, ri, rj, vi, vj, wi, wj, xi, sp, sq, D, phi, gam, row)
        n2_row(A, i, j, ri, rj, vi, vj, wi, wj, yi, sp, sq, D, phi, gam, row + 1)
        ispos[row] = True
        ispos[row + 1] = True
        row += 2
    if t == TRANSLATIONAL or t == REVOLUTE_LOCKED:
        n1_row(A, i, j, wi, wj, yi, xj, D, phi, gam, row)
        ispos[row] = False
        dd = J[J_DDELTA] if t == TRANSLATIONAL else 0.0
        if dd != 0.0:
            _steer_terms(A, i, j, wi, wj, xi, yi, xj, dd, gam, phit, row)
        row += 1
    for k in range(r0, row):
        rowb[k, 0] = i
        rowb[k, 1] = j
    return row


@njit(cache=True)
def _steer_terms(A, i, j, wi, wj, xi_, yi_, xj_, dd, gam, phit, row):
    """Rheonomic part of the steering row Phi = a . c, a = A_i y_i'(delta), c = A_j x_j', with the steer angle
    delta(t) turning x_i', y_i' about z_i' at rate dd (d(y_i')/d(delta) = -x_i', d(x_i')/d(delta) = y_i';
    delta_ddot = 0: the driver's steer is piecewise linear in time, kinks at step boundaries):
    Phi_t = -dd X . c (X = A_i x_i') and, from Phi_ddot = D v_dot - gamma,
    gamma += 2 dd (A_i (w_i' x x_i')) . c + dd^2 a . c + 2 dd X . c_dot."""
    a, c, X = mv(A, i, yi_), mv(A, j, xj_), mv(A, i, xi_)
    Xd = mv(A, i, cross(wi, xi_))
    cd = mv(A, j, cross(wj, xj_))
    phit[row] = -dd * dot(X, c)
    gam[row] += 2.0 * dd * dot(Xd, c) + dd * dd * dot(a, c) + 2.0 * dd * dot(X, cd)


def vehicle_joints(veh, modes, deltas) -> np.ndarray:
    """Joint table of a 9-body vehicle (common/vehicle_3d.py) for wheel modes (per wheel, wheel_states.WHEEL_CODES
    codes) and steer angles: chassis-knuckle TRANSLATIONAL, knuckle-wheel REVOLUTE (REVOLUTE_LOCKED for a
    locked wheel)."""
    J = np.zeros((2 * NW, N_J))
    for k in range(NW):
        d = deltas[k]
        row = J[k]
        row[J_TYPE], row[J_I], row[J_J] = TRANSLATIONAL, 0, 1 + k
        row[J_SP:J_SP + 3] = [veh.axle_x[k], veh.axle_y[k], veh.joint_z]
        row[J_SQ:J_SQ + 3] = 0.0
        row[J_XI:J_XI + 3] = [math.cos(d), math.sin(d), 0.0]
        row[J_YI:J_YI + 3] = [-math.sin(d), math.cos(d), 0.0]
        row[J_ZI:J_ZI + 3] = [0.0, 0.0, 1.0]
        row[J_XJ:J_XJ + 3] = [1.0, 0.0, 0.0]
        row[J_ZJ:J_ZJ + 3] = [0.0, 0.0, 1.0]
        row = J[NW + k]
        row[J_TYPE] = REVOLUTE_LOCKED if modes[k] == LOCKED else REVOLUTE
        row[J_I], row[J_J] = 1 + k, 5 + k
        row[J_XI:J_XI + 3] = [0.0, 0.0, 1.0]
        row[J_YI:J_YI + 3] = [1.0, 0.0, 0.0]
        row[J_ZI:J_ZI + 3] = [0.0, 1.0, 0.0]
        row[J_XJ:J_XJ + 3] = [0.0, 0.0, 1.0]
        row[J_ZJ:J_ZJ + 3] = [0.0, 1.0, 0.0]
    return J
