"""Planar impulse-momentum collision laws (docs/physics.md §3): Kudlich-Slibar (PC-Crash) and Brach.

Sign conventions: n is the unit contact normal from vehicle 1 to vehicle 2, t = k x n the tangent;
r1, r2 lead from each CG to the point of impact; g = relative velocity of 2 with respect to 1 at the
point (g_n < 0: approaching); the impulse P = Pn n + Pt t acts on vehicle 2 and -P on vehicle 1.
Inverse masses and inertias allow a rigid barrier (w = iI = 0).
"""

from numba.extending import register_jitable

KUDLICH_SLIBAR = 0
BRACH = 1
FULL = 0
SLIDING = 1


@register_jitable
def impact_matrix(w1, iI1, w2, iI2, r1x, r1y, r2x, r2y, nx, ny):
    """K_nn, K_tt, K_nt: the change of relative velocity at the point per unit impulse (§3)."""
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
    """Normal and tangential impulse (Pn, Pt) on vehicle 2, and FULL or SLIDING (§3)."""
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
        pn, pt = energy_limited(knn, ktt, knt, gn, gt, e, pn, pt)
        return pn, pt, FULL
    # sliding: tangential impulse capped at mu Pn, against the initial slip s = -sgn(g_t) (§3); without
    # initial slip, against the slip the impact would start (the sign of the law's Pt). Friction that
    # pushes along the slip would create energy, so the other sign is never taken.
    s = -1.0 if gt > 0.0 else 1.0
    if gt == 0.0:
        s = 1.0 if pt > 0.0 else -1.0
    den = knn + s * mu * knt
    if den > 0.0:
        pn = -(1.0 + e) * gn / den
        pn, pt = energy_limited(knn, ktt, knt, gn, gt, e, pn, s * mu * pn)
        return pn, pt, SLIDING
    pn = -(1.0 + e) * gn / knn
    return pn, 0.0, SLIDING


@register_jitable
def _dissipation_sign(knn, ktt, knt, gn, gt, e, r):
    """(T' - T) times a positive factor, for the impulse of tangential ratio r = Pt/Pn with g'_n = -e g_n,
    and the size of its terms (for a round-off tolerance)."""
    c = -(1.0 + e) * gn
    a2, a1, a0 = 2.0 * gt * knt + c * ktt, 2.0 * gt * knn - 2.0 * e * gn * knt, (1.0 - e) * gn * knn
    return a2 * r * r + a1 * r + a0, abs(a2 * r * r) + abs(a1 * r) + abs(a0)


@register_jitable
def energy_limited(knn, ktt, knt, gn, gt, e, pn, pt):
    """(Pn, Pt) unchanged when the impact dissipates energy (T' - T = ½ Π·(g + g') <= 0, §3); otherwise
    the tangential/normal ratio is reduced toward 0 (the frictionless impact, always dissipative), keeping
    g'_n = -e g_n, to the largest ratio that creates no energy (Brach's energy bound on the impulse ratio).
    The Newton-type sticking impulse with e > 0, and a sliding impulse whose friction reverses the slip
    by more than it had, can otherwise create energy."""
    if pn <= 0.0:
        return pn, pt
    r = pt / pn
    f, size = _dissipation_sign(knn, ktt, knt, gn, gt, e, r)
    if f <= 1e-12 * size:
        return pn, pt
    lo, hi = 0.0, r
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        if _dissipation_sign(knn, ktt, knt, gn, gt, e, mid)[0] <= 0.0:
            lo = mid
        else:
            hi = mid
    pn = -(1.0 + e) * gn / (knn + lo * knt)
    return pn, lo * pn
