"""Equations of motion of one vehicle (docs/physics.md §7): Newton-Euler with Euler parameters,
constraints with Lagrange multipliers and Baumgarte stabilisation, solved by the Schur complement.

State y of one vehicle (nb bodies, nw wheels):
  y[7b:7b+3] r_b (global), y[7b+3:7b+7] p_b (Euler parameters)                      b < nb
  y[NQ+6b:NQ+6b+3] r_dot_b (global), y[NQ+6b+3:NQ+6b+6] w'_b (body-fixed)           NQ = 7 nb
  y[NV+2k], y[NV+2k+1] transient slips s, a of wheel k (tyre.py)                    NV = 13 nb
  y[NV+2nw] work of the non-conservative forces (dampers, tyre friction, brakes)   (energy balance)
Per body M = diag(m I3, J') (principal axes), g = [f ; n' - w' x J'w'].
  [M  D^T] [v_dot]   [g                         ]
  [D   0 ] [lam  ] = [gamma - 2 alpha Phi_dot - beta^2 Phi]
solved as (D M^-1 D^T) lam = D M^-1 g - rhs (block-sparse Cholesky over the joints, constraint_solve.py: a
row touches only two bodies, a block of the Schur matrix is non-zero only for joints sharing a body), then
v_dot = M^-1 (g - D^T lam).
"""

import numpy as np
from numba import njit

from crashlab.models.common.driver_inputs import road_friction
from crashlab.models.common.rotations import cross, p_dot, rotation_into
from crashlab.models.common.vehicle_3d import B_IXX, B_IYY, B_IZZ, B_MASS, T_KZ

from .constraint_solve import assemble, block_pattern, factor, solve
from .joints import J_I, J_J, joint_rows
from .spring_damper import spring_damper, spring_energy
from .tyre import deflection, tyre

# configuration vector (per run)
(C_G, C_MU, C_ALPHA, C_BETA, C_DAMPING, C_FRICTION, C_RTOL, C_ATOL, C_HMAX, C_H0, C_TEND, C_STOP_AT_REST,
 C_V_REST, C_W_REST, C_T_SLEEP, C_REC_DT, C_ONSET_TOL) = range(17)
# vehicle contact (common/chassis_contact.py): exponent n, hysteresis chi, vehicle/vehicle friction mu and law code,
# friction tolerances v0, v1, v_s, smallest onset approach velocity
(C_NEXP, C_CHI, C_MU_C, C_FCODE, C_FV0, C_FV1, C_FVS, C_VMIN) = range(17, 25)
# chassis-road contact (common/road_contact.py): hysteresis chi and exponent n of the road law
(C_ROAD_CHI, C_ROAD_N) = range(25, 27)
# chassis contact law (chassis_contact.LAW_*) and the restitution of the structure law's unloading (§13a)
(C_LAW, C_REST) = range(27, 29)
# beta of the PI step-size control (integrator.simulate)
C_PI_BETA = 29
N_CFG = 30
# aux outputs of one evaluation (per vehicle)
AUX_FZ, AUX_DRIFT_POS, AUX_DRIFT_ANG = 0, 4, 5
N_AUX = 6
MAX_ROWS = 48
MAX_JOINTS = 16


def sizes(nb, nw):
    nq = 7 * nb
    nv = 13 * nb
    return nq, nv, nv + 2 * nw + 1


@njit(cache=True)
def unpack(y, nb, A, R, V, W):
    nq = 7 * nb
    for b in range(nb):
        o = 7 * b
        rotation_into(y[o + 3], y[o + 4], y[o + 5], y[o + 6], A, b)
        for k in range(3):
            R[b, k] = y[o + k]
            V[b, k] = y[nq + 6 * b + k]
            W[b, k] = y[nq + 6 * b + 3 + k]


@njit(cache=True)
def rhs(y, dy, BODY, JNT, SPR, TYR, cfg, A, R, V, W, Q, D, phi, gam, rowb, ispos, S, lam, aux, fext, phit, brake,
        ZC, ZS, ZM, ZB, MD, jst, JB, NZ, IM):
    """fext: external load on the chassis (body 0): global force [0:3], global moment about its CG [3:6],
    its power [6] (added to the non-conservative work). brake: the driver's brake fraction b of the rolling
    wheels now; ZC, ZS, ZM, ZB: the road's friction zones (common/driver_inputs.pack_zones): each tyre takes
    the friction at its contact point (docs/physics.md §2a). MD, jst, JB, NZ: work arrays of the constraint
    solve (constraint_solve.py); IM (nb, 6): the inverse masses and inertias."""
    nb, nw = BODY.shape[0], TYR.shape[0]
    nq, nvq = 7 * nb, 13 * nb
    unpack(y, nb, A, R, V, W)
    g = cfg[C_G]
    for b in range(nb):
        o = 7 * b
        pd = p_dot(y[o + 3], y[o + 4], y[o + 5], y[o + 6], (W[b, 0], W[b, 1], W[b, 2]))
        for k in range(3):
            dy[o + k] = V[b, k]
        for k in range(4):
            dy[o + 3 + k] = pd[k]
        w = (W[b, 0], W[b, 1], W[b, 2])
        h = cross(w, (BODY[b, B_IXX] * w[0], BODY[b, B_IYY] * w[1], BODY[b, B_IZZ] * w[2]))
        Q[b, 0], Q[b, 1], Q[b, 2] = 0.0, 0.0, -BODY[b, B_MASS] * g
        Q[b, 3], Q[b, 4], Q[b, 5] = -h[0], -h[1], -h[2]
    # external (contact) load on the chassis
    for k in range(3):
        Q[0, k] += fext[k]
        Q[0, 3 + k] += A[0, 0, k] * fext[3] + A[0, 1, k] * fext[4] + A[0, 2, k] * fext[5]
    pnc = fext[6]
    for s in range(SPR.shape[0]):
        diss, _ = spring_damper(SPR[s], A, R, V, W, Q, cfg[C_DAMPING])
        pnc -= diss
    dsl = np.empty(2)
    for k in range(nw):
        mu = cfg[C_MU]
        if ZM.shape[0] > 0:
            _, C, _ = deflection(TYR[k], A, R)
            mu = road_friction(C[0], C[1], mu, ZC, ZS, ZM, ZB)
        fz, pw = tyre(TYR[k], A, R, V, W, Q, y[nvq + 2 * k], y[nvq + 2 * k + 1], mu, cfg[C_FRICTION],
                      cfg[C_DAMPING], dsl, brake)
        dy[nvq + 2 * k], dy[nvq + 2 * k + 1] = dsl[0], dsl[1]
        aux[AUX_FZ + k] = fz
        pnc += pw
    dy[nvq + 2 * nw] = pnc
    # constraints, leaf joints first (the knuckle-wheel joints come after the chassis-knuckle joints in the
    # table): the Cholesky factor of the Schur matrix then has no fill-in (constraint_solve.py)
    m = 0
    phit[:] = 0.0
    nj = JNT.shape[0]
    for q in range(nj):
        k = nj - 1 - q
        jst[q] = m
        JB[q, 0], JB[q, 1] = int(JNT[k, J_I]), int(JNT[k, J_J])
        m = joint_rows(JNT[k], A, R, V, W, D, phi, gam, rowb, ispos, m, phit)
    jst[nj] = m
    # inverse masses and inertias (M^-1 is diagonal per body)
    for b in range(nb):
        im = 1.0 / BODY[b, B_MASS]
        for k in range(3):
            IM[b, k] = im
            IM[b, 3 + k] = 1.0 / BODY[b, 1 + k]
    dpos, dang = 0.0, 0.0
    a2, b2 = 2.0 * cfg[C_ALPHA], cfg[C_BETA] * cfg[C_BETA]
    for r in range(m):
        i, j = rowb[r, 0], rowb[r, 1]
        phid = phit[r]
        mq = 0.0
        for k in range(3):
            phid += D[r, k] * V[i, k] + D[r, 3 + k] * W[i, k] + D[r, 6 + k] * V[j, k] + D[r, 9 + k] * W[j, k]
        # D M^-1 (per row, for the Schur matrix too) and D M^-1 g
        for k in range(6):
            MD[r, k] = D[r, k] * IM[i, k]
            MD[r, 6 + k] = D[r, 6 + k] * IM[j, k]
            mq += MD[r, k] * Q[i, k] + MD[r, 6 + k] * Q[j, k]
        lam[r] = mq - (gam[r] - a2 * phid - b2 * phi[r])
        if ispos[r]:
            dpos = max(dpos, abs(phi[r]))
        else:
            dang = max(dang, abs(phi[r]))
    aux[AUX_DRIFT_POS], aux[AUX_DRIFT_ANG] = dpos, dang
    # (D M^-1 D^T) lam = D M^-1 g - rhs
    block_pattern(JB, nj, NZ)
    assemble(D, MD, jst, JB, nj, NZ, S)
    factor(S, jst, nj, NZ)
    solve(S, jst, nj, NZ, lam)
    # reactions and accelerations
    for r in range(m):
        i, j = rowb[r, 0], rowb[r, 1]
        for k in range(6):
            Q[i, k] -= D[r, k] * lam[r]
            Q[j, k] -= D[r, 6 + k] * lam[r]
    for b in range(nb):
        o = nq + 6 * b
        for k in range(6):
            dy[o + k] = Q[b, k] * IM[b, k]


@njit(cache=True)
def energy(y, BODY, SPR, TYR, g, A, R, V, W):
    """Mechanical energy: kinetic + gravity + suspension springs (and bump stops) + tyre radial springs."""
    nb = BODY.shape[0]
    unpack(y, nb, A, R, V, W)
    e = 0.0
    for b in range(nb):
        m = BODY[b, B_MASS]
        e += 0.5 * m * (V[b, 0] ** 2 + V[b, 1] ** 2 + V[b, 2] ** 2) + m * g * R[b, 2]
        e += 0.5 * (BODY[b, B_IXX] * W[b, 0] ** 2 + BODY[b, B_IYY] * W[b, 1] ** 2 + BODY[b, B_IZZ] * W[b, 2] ** 2)
    Qd = np.zeros((nb, 6))
    for s in range(SPR.shape[0]):
        _, l = spring_damper(SPR[s], A, R, V, W, Qd, 0.0)
        e += spring_energy(SPR[s], l)
    for k in range(TYR.shape[0]):
        d, _, _ = deflection(TYR[k], A, R)
        if d > 0.0:
            e += 0.5 * TYR[k, T_KZ] * d * d
    return e
