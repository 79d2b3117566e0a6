"""Planar impulse-momentum collision laws (docs/physics.md §3): Kudlich-Slibar (PC-Crash), Brach and Routh.

Sign conventions: n is the unit contact normal from vehicle 1 to vehicle 2, t = k x n the tangent;
r1, r2 lead from each CG to the point of impact; g = relative velocity of 2 with respect to 1 at the
point (g_n < 0: approaching); the impulse P = Pn n + Pt t acts on vehicle 2 and -P on vehicle 1.
Inverse masses and inertias allow a rigid barrier (w = iI = 0).
"""

import math

from numba.extending import register_jitable

KUDLICH_SLIBAR = 0
BRACH = 1
ROUTH = 2
FULL = 0  # the impact's kind: the slip ends (or stays) zero (Routh: sticks)
SLIDING = 1  # it slides throughout, in one direction
REVERSED = 2  # (Routh) the slip stops and reverses
# a tangential velocity at the point within SLIP_TOL of the normal one is no slip (§3): the friction's
# direction never hangs on round-off (a contact plane entered at 90 or -90 deg leaves |g_t| ~ 1e-16 |g_n|)
SLIP_TOL = 1e-9
# what Routh's path says of another law's impact (checked_impulse): its slip stops and reverses, or it stops and
# sticks but the law's sliding impulse reverses it
SLIP_REVERSES, SLIP_OVERSHOOT = 1, 2


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
    """Normal and tangential impulse (Pn, Pt) on vehicle 2, and FULL or SLIDING (Routh: or REVERSED) (§3)."""
    if law == ROUTH:
        return routh_impulse(knn, ktt, knt, gn, gt, e, mu)
    if abs(gt) <= SLIP_TOL * abs(gn):
        gt = 0.0  # no slip (SLIP_TOL)
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


@register_jitable
def routh_impulse(knn, ktt, knt, gn, gt, e, mu):
    """Routh's impulse-space solution (§3; Stronge, Impact Mechanics, 2000): (Pn, Pt, kind).

    The normal impulse p is the clock. While the point slips (sign sg), friction opposes the current slip,
    dPt/dp = -sg mu; where the slip stops the point sticks (dPt/dp = -K_nt/K_tt keeps g_t = 0) if
    |K_nt| <= mu K_tt, else it slips the other way (sign of K_nt) and then never stops. So g(p) is
    linear in p on at most two phases. Compression ends where g_n = 0; restitution goes on until the
    normal impulse's work is e^2 times minus its work in compression (Stronge's energetic coefficient).
    Each phase's work is (g_end^2 - g_start^2) / (2 dg_n/dp), so the ends are closed-form."""
    d = knn * ktt - knt * knt
    stick = abs(knt) <= mu * ktt
    if stick:  # after the slip stops (or without slip): sticking
        l2, a2 = -knt / ktt, d / ktt
    else:  # the slip reverses (or starts) toward the sign of K_nt
        l2 = -mu if knt > 0.0 else mu
        a2 = knn + knt * l2
    if abs(gt) <= SLIP_TOL * abs(gn):  # no initial slip: one phase
        pf = -(1.0 + e) * gn / a2
        return pf, l2 * pf, FULL if stick else SLIDING
    sg = 1.0 if gt > 0.0 else -1.0
    l1 = -sg * mu  # dPt/dp while the initial slip lasts
    a1, b1 = knn + knt * l1, knt + ktt * l1  # dg_n/dp, dg_t/dp
    p1 = -gt / b1 if sg * b1 < 0.0 else math.inf  # where the slip stops
    g1 = gn + a1 * p1 if p1 < math.inf else math.inf  # g_n there
    if g1 >= 0.0:  # compression ends within the first phase (then a1 > 0)
        pc = -gn / a1
        if p1 >= (1.0 + e) * pc:  # and restitution too: slip never stops, one phase (Newton = Poisson)
            pf = (1.0 + e) * pc
            return pf, l1 * pf, SLIDING
        wr = -0.5 * e * e * gn * pc - 0.5 * a1 * (p1 - pc) ** 2  # restitution work left for phase 2
        gf = math.sqrt(g1 * g1 + 2.0 * a2 * wr)
        pf = p1 + 2.0 * wr / (g1 + gf) if g1 + gf > 0.0 else p1
    else:  # the slip stops during compression
        wc = 0.5 * (gn + g1) * p1 - 0.5 * g1 * g1 / a2  # normal impulse's work in compression (< 0)
        pc = p1 - g1 / a2
        pf = pc + e * math.sqrt(-2.0 * wc / a2)
    kind = FULL if stick else (REVERSED if mu > 0.0 else SLIDING)
    return pf, l1 * p1 + l2 * (pf - p1), kind


@register_jitable
def checked_impulse(knn, ktt, knt, gn, gt, e, mu, law):
    """collision_impulse of the law, and what Routh's path for the same impact (K, initial slip, mu) says of it,
    with Routh's impulse: (Pn, Pt, kind, check, Pn_routh, Pt_routh); check SLIP_REVERSES where the slip stops and
    reverses on Routh's path, SLIP_OVERSHOOT where it stops and sticks there but the law's sliding impulse, its
    friction against the initial slip running on, reverses it (g'_t of the other sign), else 0. Kudlich-Slibar and
    Brach keep friction against the initial slip throughout: wrong in both (§3)."""
    pn, pt, kind = collision_impulse(knn, ktt, knt, gn, gt, e, mu, law)
    if law == ROUTH:
        return pn, pt, kind, SLIP_REVERSES if kind == REVERSED else 0, pn, pt
    rpn, rpt, rkind = routh_impulse(knn, ktt, knt, gn, gt, e, mu)
    if rkind == REVERSED:
        return pn, pt, kind, SLIP_REVERSES, rpn, rpt
    gt_after = gt + knt * pn + ktt * pt
    if kind == SLIDING and abs(gt) > SLIP_TOL * abs(gn) and gt_after * gt < 0.0 \
            and abs(gt_after) > SLIP_TOL * abs(gn):
        return pn, pt, kind, SLIP_OVERSHOOT, rpn, rpt
    return pn, pt, kind, 0, rpn, rpt
