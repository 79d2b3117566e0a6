"""Planar impulse-momentum collision laws (FORMULAS.md §9): Kudlich-Slibar (PC-Crash) and Brach.

Sign conventions: n is the unit contact normal from vehicle 1 to vehicle 2, t = k x n the tangent;
r1, r2 lead from each CG to the point of impact; g = relative velocity of 2 with respect to 1 at the
point (g_n < 0: approaching); the impulse P = Pn n + Pt t acts on vehicle 2 and -P on vehicle 1.
Inverse masses and inertias allow a rigid barrier (w = iI = 0).
"""
import math

from numba.extending import register_jitable

KUDLICH_SLIBAR = 0
BRACH = 1
FULL = 0
SLIDING = 1


@register_jitable
def impact_matrix(w1, iI1, w2, iI2, r1x, r1y, r2x, r2y, nx, ny):
    """K_nn, K_tt, K_nt: the change of relative velocity at the point per unit impulse (§9)."""
    tx, ty = -ny, nx
    a1 = r1x * ny - r1y * nx  # r x n
    a2 = r2x * ny - r2y * nx
    b1 = r1x * ty - r1y * tx  # r x t
    b2 = r2x * ty - r2y * tx
    knn = w1 + w2 + a1 * a1 * iI1 + a2 * a2 * iI2
    ktt = w1 + w2 + b1 * b1 * iI1 + b2 * b2 * iI2
    knt = a1 * b1 * iI1 + a2 * b2 * iI2
    return knn, ktt, knt


@register_jitable
def collision_impulse(knn, ktt, knt, gn, gt, e, mu, law):
    """Normal and tangential impulse (Pn, Pt) on vehicle 2, and FULL or SLIDING (§9)."""
    d = knn * ktt - knt * knt
    if law == KUDLICH_SLIBAR:
        # common velocity at the end of compression, restitution on the whole impulse: g' = -e g
        pn = -(1.0 + e) * (ktt * gn - knt * gt) / d
        pt = -(1.0 + e) * (knn * gt - knt * gn) / d
    else:
        # Brach: g'_n = -e g_n and common tangential velocity g'_t = 0
        pn = (-(1.0 + e) * gn * ktt + gt * knt) / d
        pt = (-knn * gt + knt * (1.0 + e) * gn) / d
    if abs(pt) <= mu * pn + 1e-12 * abs(pn):
        return pn, pt, FULL
    # sliding: tangential impulse capped at mu Pn, opposing the initial slip; keep the sign that
    # does not reverse the slip (FORMULAS §9 pitfall)
    s = -1.0 if gt > 0.0 else 1.0
    if gt == 0.0:
        s = 1.0 if pt > 0.0 else -1.0
    for _ in range(2):
        den = knn + s * mu * knt
        if den > 0.0:
            pn = -(1.0 + e) * gn / den
            pt = s * mu * pn
            gt_after = gt + knt * pn + ktt * pt
            if gt_after * gt >= -1e-12 * (abs(gt) + 1.0) or gt == 0.0:
                return pn, pt, SLIDING
        s = -s
    pn = -(1.0 + e) * gn / knn
    return pn, 0.0, SLIDING
