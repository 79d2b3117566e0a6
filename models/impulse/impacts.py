"""Impact resolution of the impulse kernel: the impulse exchanged at a point of impact (laws.py, docs/physics.md
§3), and its bookkeeping in the impact record (layout.I_*: one row per impact, follow-up contact impulses
merged into it, §5)."""
import math

from numba import njit

from crashlab.models.common.planar_vehicle import P_IZ, P_MASS, engaged_capacity, struck_side
from crashlab.models.common.restitution_law import kernel_restitution
from crashlab.outcome import REIMPACT_SPEED

from .contact import _point_velocity
from .laws import checked_impulse, collision_impulse, impact_matrix
from .layout import (
    I_ALT_DR_I,
    I_ALT_DR_J,
    I_ALT_PN,
    I_ALT_PT,
    I_CAPACITY,
    I_CLOSING,
    I_DR_I,
    I_DR_J,
    I_DVX_I,
    I_DVX_J,
    I_DVY_I,
    I_DVY_J,
    I_ENERGY,
    I_ENGAGE,
    I_ENGAGE_RATIO,
    I_HEAD_I,
    I_HEAD_J,
    I_I,
    I_J,
    I_KIND,
    I_N_FOLLOW,
    I_OWN_DR_I,
    I_OWN_DR_J,
    I_OWN_PN,
    I_OWN_PT,
    I_PLANE,
    I_PN,
    I_PT,
    I_PX,
    I_PY,
    I_REIMPACT,
    I_REVERSED,
    I_SIDE_I,
    I_SIDE_J,
    I_T,
    I_T_END,
    I_WIDTH,
    PUSH,
)


@njit(cache=True)
def _kinetic(P, S, k, nv):
    if k >= nv:
        return 0.0
    return 0.5 * P[k, P_MASS] * (S[k, 3] ** 2 + S[k, 4] ** 2) + 0.5 * P[k, P_IZ] * S[k, 5] ** 2


@njit(cache=True)
def _apply_impulse(P, S, i, j, nv, px, py, nx, ny, e, mu, law, alt):
    """Exchange the impulse at (px, py) with normal n (from i to j). Returns (pn, pt, kind, energy, gn);
    for an impact (alt = the impact's row of `imp`, else an empty array) also writes the slip-reversal
    check and Routh's impulse for the same impact there (laws.checked_impulse; I_REVERSED, I_OWN_*, I_ALT_*)."""
    w1, iI1 = 1.0 / P[i, P_MASS], 1.0 / P[i, P_IZ]
    w2, iI2 = 0.0, 0.0
    if j < nv:
        w2, iI2 = 1.0 / P[j, P_MASS], 1.0 / P[j, P_IZ]
    r1x, r1y = px - S[i, 0], py - S[i, 1]
    r2x, r2y = 0.0, 0.0
    if j < nv:
        r2x, r2y = px - S[j, 0], py - S[j, 1]
    v1x, v1y = _point_velocity(S, i, nv, px, py)
    v2x, v2y = _point_velocity(S, j, nv, px, py)
    gx, gy = v2x - v1x, v2y - v1y
    tx, ty = -ny, nx
    gn, gt = gx * nx + gy * ny, gx * tx + gy * ty
    if gn >= 0.0:
        return 0.0, 0.0, -1, 0.0, gn
    e = kernel_restitution(e, -gn)  # the constant, or the law of the closing speed (docs/physics.md §13b)
    knn, ktt, knt = impact_matrix(w1, iI1, w2, iI2, r1x, r1y, r2x, r2y, nx, ny)
    if alt.shape[0] > 0:
        pn, pt, kind, rev, apn, apt = checked_impulse(knn, ktt, knt, gn, gt, e, mu, law)
        a1, b1 = r1x * ny - r1y * nx, r1x * ty - r1y * tx  # r x n, r x t: yaw-rate change per impulse
        a2, b2 = r2x * ny - r2y * nx, r2x * ty - r2y * tx
        alt[I_REVERSED] = rev
        alt[I_CLOSING] = -gn
        alt[I_OWN_PN], alt[I_OWN_PT], alt[I_ALT_PN], alt[I_ALT_PT] = pn, pt, apn, apt
        alt[I_OWN_DR_I], alt[I_OWN_DR_J] = -(a1 * pn + b1 * pt) * iI1, (a2 * pn + b2 * pt) * iI2
        alt[I_ALT_DR_I], alt[I_ALT_DR_J] = -(a1 * apn + b1 * apt) * iI1, (a2 * apn + b2 * apt) * iI2
    else:
        pn, pt, kind = collision_impulse(knn, ktt, knt, gn, gt, e, mu, law)
    ix, iy = pn * nx + pt * tx, pn * ny + pt * ty
    ke0 = _kinetic(P, S, i, nv) + _kinetic(P, S, j, nv)
    S[i, 3] -= ix * w1
    S[i, 4] -= iy * w1
    S[i, 5] -= (r1x * iy - r1y * ix) * iI1
    if j < nv:
        S[j, 3] += ix * w2
        S[j, 4] += iy * w2
        S[j, 5] += (r2x * iy - r2y * ix) * iI2
    return pn, pt, kind, ke0 - _kinetic(P, S, i, nv) - _kinetic(P, S, j, nv), gn


@njit(cache=True)
def _record_impact(imp, n, t, i, j, nv, P, B, S_before, S, pn, pt, kind, energy, px, py, nx, ny):
    imp[n, I_T], imp[n, I_I], imp[n, I_J] = t, i, j
    imp[n, I_SIDE_I] = struck_side(P[i], S[i, 0], S[i, 1], S[i, 2], px, py)
    imp[n, I_SIDE_J] = struck_side(P[j], S[j, 0], S[j, 1], S[j, 2], px, py) if j < nv else 0.0
    imp[n, I_DVX_I] = S[i, 3] - S_before[i, 3]
    imp[n, I_DVY_I] = S[i, 4] - S_before[i, 4]
    imp[n, I_DR_I] = S[i, 5] - S_before[i, 5]
    if j < nv:
        imp[n, I_DVX_J] = S[j, 3] - S_before[j, 3]
        imp[n, I_DVY_J] = S[j, 4] - S_before[j, 4]
        imp[n, I_DR_J] = S[j, 5] - S_before[j, 5]
    imp[n, I_ENERGY], imp[n, I_PN], imp[n, I_PT], imp[n, I_KIND] = energy, pn, pt, kind
    imp[n, I_PX], imp[n, I_PY], imp[n, I_PLANE] = px, py, math.atan2(nx, -ny)  # tangent t = k x n
    imp[n, I_HEAD_I] = S[i, 2]
    imp[n, I_HEAD_J] = S[j, 2] if j < nv else 0.0
    q = j if j < nv else i
    bar = B[j - nv] if j >= nv else S[i, :0]  # a barrier's row (its own extent), else none
    imp[n, I_WIDTH], imp[n, I_CAPACITY] = engaged_capacity(P[i], S[i], imp[n, I_SIDE_I], P[q], S[q], imp[n, I_SIDE_J],
                                                           bar, -ny, nx)
    imp[n, I_T_END], imp[n, I_N_FOLLOW], imp[n, I_REIMPACT] = t, 0.0, 0.0
    imp[n, I_ENGAGE], imp[n, I_ENGAGE_RATIO] = 0.0, math.nan  # not placed at engagement (the caller sets them)


@njit(cache=True)
def _settle_reimpacts(P, imp, n, nv):
    """After the run: a re-impact's row (I_REIMPACT) whose impulse changes the pair's relative velocity by less than
    crashlab.outcome.REIMPACT_SPEED (|J| < m* REIMPACT_SPEED, m* the reduced mass; a barrier's pair: the vehicle's
    mass) is a push's, as in the 3D models (docs/physics.md §5, §15 "Re-impacts")."""
    for r in range(n):
        if imp[r, I_REIMPACT] == 0.0:
            continue
        i, j = int(imp[r, I_I]), int(imp[r, I_J])
        m = P[i, P_MASS] if j >= nv else P[i, P_MASS] * P[j, P_MASS] / (P[i, P_MASS] + P[j, P_MASS])
        if math.hypot(imp[r, I_PN], imp[r, I_PT]) < REIMPACT_SPEED * m:
            imp[r, I_KIND], imp[r, I_REVERSED], imp[r, I_REIMPACT] = PUSH, 0.0, 0.0


@njit(cache=True)
def _merge_impact(imp, n, t, i, j, nv, S_before, S, pn, pt, energy, nx, ny):
    """Add a follow-up contact impulse of the same pair to impact row n: velocity changes and energy
    summed, the impulse expressed in the row's normal/tangent frame."""
    imp[n, I_DVX_I] += S[i, 3] - S_before[i, 3]
    imp[n, I_DVY_I] += S[i, 4] - S_before[i, 4]
    imp[n, I_DR_I] += S[i, 5] - S_before[i, 5]
    if j < nv:
        imp[n, I_DVX_J] += S[j, 3] - S_before[j, 3]
        imp[n, I_DVY_J] += S[j, 4] - S_before[j, 4]
        imp[n, I_DR_J] += S[j, 5] - S_before[j, 5]
    imp[n, I_ENERGY] += energy
    ix, iy = pn * nx - pt * ny, pn * ny + pt * nx
    mx, my = math.sin(imp[n, I_PLANE]), -math.cos(imp[n, I_PLANE])
    imp[n, I_PN] += ix * mx + iy * my
    imp[n, I_PT] += -ix * my + iy * mx
    imp[n, I_T_END] = t
    imp[n, I_N_FOLLOW] += 1.0


@njit(cache=True)
def _struck(i, j, nv, hit, asleep):
    """The vehicles of an impulse between i and j (a vehicle or a barrier): marked hit (wheels locked after
    the impact lock from here: driver_inputs.effective_mode) and woken."""
    for q in (i, j):
        if q < nv:
            hit[q] = True
            asleep[q] = False
