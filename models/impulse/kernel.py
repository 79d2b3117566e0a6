"""The compiled time loop of the impulse model: vehicle motion, contact onset, impulses, rest.

Everything per scene runs inside one numba function (no Python loop over time steps); a batch of
scenes runs in parallel with `prange`. Step-size policy:
  * fine steps (Heun, 2nd order) of at most `dt`, and below 1 / (fastest decay rate of the regularised
    tyre forces) (planar_vehicle.stiffest_rate), whenever a tyre force can change or vehicles are close;
  * while every moving vehicle runs straight and no pair can touch within the step, the step grows up
    to `coarse_dt` (straight running has constant forces, Heun is exact for it);
  * a vehicle at rest sleeps (no force evaluation) until an impulse wakes it; the loops of a step run
    over the awake vehicles and the pairs with an awake member only (lists rebuilt when a vehicle sleeps or
    wakes, pairs in the order of the full i < k loop, so results do not depend on the skipping), and the
    bounding circles reject distant pairs before the outline test; a pair of an awake vehicle and a static
    partner (sleeping vehicle, barrier) more than 2 REACH apart is left out until a vehicle has moved REACH
    (_near_pairs): a parked or distant vehicle costs (nearly) nothing;
  * the run ends when every vehicle sleeps (stop_at_rest) or at `duration`.
Contact onset is located by bisection of the step until the outlines overlap by at most `onset_tol`.

Contact episodes (the model docstring argues the choice): a pair's touch after being apart by more than
SEPARATION is an impact (restitution e, a row of the impact table); until the pair is that far apart
again, every step in which the outlines overlap and approach gets plastic (e = 0) Coulomb-limited
contact impulses, booked into that impact's row, and a position projection keeps the overlap below
CONTACT_SLOP. Reaching max_impacts or MAX_STEPS stops and fails the run.
"""
import math

import numpy as np
from numba import njit, prange

from crashlab.geometry import (
    clip_convex,
    contact_zone_centroid,
    crushed_faces_axis,
    overlap_centroid,
    penetration,
    rect_corners_into,
)
from crashlab.models.common.driver_inputs import (
    PATCH,
    ahead,
    driver_inputs,
    effective_mode,
    next_change,
    point_friction,
    ramping,
    steady_next,
    wheel_point,
)
from crashlab.models.common.planar_vehicle import (
    P_A,
    P_B,
    P_FRONT,
    P_HALFW,
    P_IZ,
    P_MASS,
    P_REAR,
    P_TRACK,
    stiffest_rate,
    vehicle_forces_trig,
)
from crashlab.models.common.restitution_law import kernel_restitution
from crashlab.models.common.wheel_states import BRAKED, ROLLING
from crashlab.units import G

from .laws import checked_impulse, collision_impulse, impact_matrix

# configuration vector
(C_MU_ROAD, C_E, C_MU_IMP, C_LAW, C_DURATION, C_STOP_AT_REST, C_GIVEN, C_PX, C_PY, C_PLANE, C_DT,
 C_COARSE_DT, C_REC_DT, C_ONSET_TOL, C_V_REST, C_MAX_IMPACTS, C_GIVEN_I, C_GIVEN_J, C_CRUSH_TIME,
 C_BROAD_PHASE, C_SLEEPING, C_ENGAGE, C_ENGAGE_DEPTH) = range(23)
N_CFG = 23  # C_ENGAGE: [impact] point = "engagement", C_ENGAGE_DEPTH its engagement_depth (_engagement)
# impact record
# impact record: one row per impact (contact episode); the episode's follow-up contact impulses are
# summed into it (dv, energy, impulse in the impact's n-t frame); I_T_END is its last impulse
# I_REVERSED: the slip stops and reverses on Routh's path (laws.checked_impulse); the impact's own impulse
# (I_OWN_*: n-t frame, yaw-rate changes of i and j) and Routh's for it (I_ALT_*), for the warning of a law
# that does not follow the reversal (model._slip_warnings)
(I_T, I_I, I_J, I_DVX_I, I_DVY_I, I_DR_I, I_DVX_J, I_DVY_J, I_DR_J, I_ENERGY, I_PN, I_PT, I_KIND, I_PX,
 I_PY, I_PLANE, I_HEAD_I, I_HEAD_J, I_T_END, I_N_FOLLOW, I_REVERSED, I_OWN_PN, I_OWN_PT, I_OWN_DR_I, I_OWN_DR_J,
 I_ALT_PN, I_ALT_PT, I_ALT_DR_I, I_ALT_DR_J, I_CLOSING, I_ENGAGE, I_ENGAGE_RATIO) = range(32)
N_IMP = 32  # I_CLOSING: the normal closing speed at the impact, m/s (restitution = "speed", §13b)
# I_ENGAGE: how [impact] point = "engagement" placed the impact (ENGAGE_*; 0 for every other placement and for
# follow-up impulses); I_ENGAGE_RATIO: the crushed faces' smaller principal value over the larger (_engagement)
ENGAGE_USED, ENGAGE_AMBIGUOUS, ENGAGE_FALLBACK = 1, 2, 3
AMBIGUOUS_RATIO = 0.9  # principal values within 10 % of each other: the faces give no plane (docs/physics.md §4)
# diagnostics
(D_STEPS, D_IMPACTS, D_NREC, D_T_END, D_STATUS, D_CONTACT_T, D_BISECT, D_COARSE, D_MAX_DEPTH, D_KE0,
 D_E_IMPACT, D_FOLLOW, D_PROJECTED, D_VEHICLE_STEPS, D_NARROW) = range(15)
N_DIAG = 15  # D_VEHICLE_STEPS: awake vehicles integrated, summed over steps; D_NARROW: outline tests
# a vehicle's driver inputs at the step's start (_heun): wheel state, brake, steer and the cosines and sines of
# its steer and heading
IN_MODE, IN_BRAKE, IN_STEER, IN_COS_STEER, IN_SIN_STEER, IN_COS_HEADING, IN_SIN_HEADING = range(7)
N_IN = 7
STATUS_OK, STATUS_NOT_APPROACHING, STATUS_IMPACT_CAP, STATUS_NAN, STATUS_STEP_LIMIT = 0, 1, 2, 3, 4
MAX_STEPS = 200_000  # a guard: no scene needs more (duration <= 120 s at dt >= 1 ms)
V_EPS = 1e-6  # m/s: an overlapping pair approaching slower needs no contact impulse (round-off level)
CONTACT_SLOP = 0.002  # m: overlap tolerated in sustained contact (no bisection, no projection below it)
SEPARATION = 0.05  # m: a pair further apart than this has ended its contact episode
DEEPEN = 2.0 * CONTACT_SLOP  # m: a touching pair's overlap deepening past this within a step is bisected
MAX_SWEEPS = 50  # sequential-impulse sweeps over simultaneous contacts per step
STOP_MARGIN = 0.5  # m/s: coarse steps end this far above the speed a coarse step could brake away
REACH = 1.0  # m: a pair with a static member further apart than 2 REACH is left out until a vehicle moved REACH


@njit(cache=True)
def _outline(P, S, B, k, nv, out):
    """The outline of vehicle or barrier k, written into `out` (4, 2): the step's loops allocate none."""
    if k < nv:
        return rect_corners_into(out, S[k, 0], S[k, 1], math.cos(S[k, 2]), math.sin(S[k, 2]), P[k, P_FRONT],
                                 P[k, P_REAR], P[k, P_HALFW])
    j = k - nv
    return rect_corners_into(out, B[j, 0], B[j, 1], math.cos(B[j, 2]), math.sin(B[j, 2]), B[j, 3], B[j, 3], B[j, 4])


@njit(cache=True)
def _radius(P, B, k, nv):
    if k < nv:
        return math.sqrt(max(P[k, P_FRONT], P[k, P_REAR]) ** 2 + P[k, P_HALFW] ** 2)
    return math.sqrt(B[k - nv, 3] ** 2 + B[k - nv, 4] ** 2)


@njit(cache=True)
def _centre(S, B, k, nv):
    if k < nv:
        return S[k, 0], S[k, 1]
    return B[k - nv, 0], B[k - nv, 1]


@njit(cache=True, inline="always")  # inlined: called for every pair at every step
def _circles_apart(S, B, radius, i, k, nv):
    """Vehicle i and vehicle or barrier k cannot touch: their bounding circles do not meet."""
    if k < nv:
        ckx, cky = S[k, 0], S[k, 1]
    else:
        ckx, cky = B[k - nv, 0], B[k - nv, 1]
    dx, dy, r = S[i, 0] - ckx, S[i, 1] - cky, radius[i] + radius[k]
    if abs(dx) > r or abs(dy) > r:  # hypot(dx, dy) >= max(|dx|, |dy|) in floating point too: same answer
        return True
    return math.hypot(dx, dy) > r


@njit(cache=True)
def _awake_sets(asleep, nk, awake, pair_i, pair_k):
    """The awake vehicles (ascending) and the pairs (vehicle i, vehicle or barrier k > i) with an awake
    member, in the order of the full double loop over i < k. Returns their counts."""
    nv = asleep.shape[0]
    na, n_pairs = 0, 0
    for i in range(nv):
        if not asleep[i]:
            awake[na] = i
            na += 1
            for k in range(i + 1, nk):
                pair_i[n_pairs], pair_k[n_pairs] = i, k
                n_pairs += 1
        else:
            for k in range(i + 1, nv):
                if not asleep[k]:
                    pair_i[n_pairs], pair_k[n_pairs] = i, k
                    n_pairs += 1
    return na, n_pairs


@njit(cache=True)
def _moved(S, Snew, awake, na, ref, reach):
    """Some awake vehicle is more than `reach` from ref at the start (S) or the end (Snew) of the step."""
    for a in range(na):
        i = awake[a]
        if (math.hypot(S[i, 0] - ref[i, 0], S[i, 1] - ref[i, 1]) > reach
                or math.hypot(Snew[i, 0] - ref[i, 0], Snew[i, 1] - ref[i, 1]) > reach):
            return True
    return False


@njit(cache=True)
def _near_pairs(S, B, radius, asleep, awake, na, pair_i, pair_k, n_pairs, ref, reach, near_i, near_k,
                in_contact, episode, allowed):
    """The listed pairs without those of an awake vehicle and a static partner (a sleeping vehicle or a
    barrier) whose bounding circles are more than 2 reach apart: while no awake vehicle is more than reach
    (plus the curvature of a step) from ref = its position now, those stay apart, so the broad phase
    would skip them and reset their contact state, done here once. Returns the count."""
    nv = S.shape[0]
    for a in range(na):
        ref[awake[a], 0], ref[awake[a], 1] = S[awake[a], 0], S[awake[a], 1]
    n = 0
    for p in range(n_pairs):
        i, k = pair_i[p], pair_k[p]
        if (k >= nv or asleep[k] or asleep[i]) and _gap(S, B, radius, i, k, nv) > 2.0 * reach:
            in_contact[i, k] = False
            episode[i, k] = -1
            allowed[i, k] = 0.0
            continue
        near_i[n], near_k[n] = i, k
        n += 1
    return n


@njit(cache=True)
def _gap(S, B, radius, i, k, nv):
    ckx, cky = _centre(S, B, k, nv)
    return math.hypot(S[i, 0] - ckx, S[i, 1] - cky) - radius[i] - radius[k]


@njit(cache=True, inline="always")  # inlined: a call costs more than the cache hit (measured)
def _wheel_frictions(P, X, i, c, sn, reach, mu, zones, zcache):
    """The road friction under the four wheels of vehicle i in state X[i], heading (c, sn) = (cos, sin)
    (driver_inputs.point_friction at each wheel). zcache[i] = (x, y, heading of the last look-up, the least
    of the four margins, each wheel's margin, each wheel's friction): since that look-up no wheel has moved
    more than d = |dx| + |dy| + reach |dheading|, so while d is below a wheel's margin its friction holds
    (_wheel_lookup)."""
    z = zcache[i]
    d = abs(X[i, 0] - z[0]) + abs(X[i, 1] - z[1]) + reach * abs(X[i, 2] - z[2])
    if d < z[3]:
        return z[8], z[9], z[10], z[11]
    return _wheel_lookup(P, X, i, c, sn, d, mu, zones[0], zones[1], zones[2], zones[3], z)


@njit(cache=True, inline="always")  # (measured: a little faster inlined)
def _wheel_lookup(P, X, i, c, s, d, mu, E, start, zmu, box, z):
    """_wheel_frictions for a vehicle with some wheel's margin spent: that wheel is looked up again, the
    others' margins shrink by d, and the pose of X[i] becomes the reference."""
    least = math.inf
    for w in range(4):
        if d >= z[4 + w]:
            xw, yw = wheel_point(X[i, 0], X[i, 1], c, s, P[i, P_A], P[i, P_B], 0.5 * P[i, P_TRACK], w)
            z[8 + w], z[4 + w] = point_friction(xw, yw, mu, E, start, zmu, box)
        else:
            z[4 + w] -= d
        least = min(least, z[4 + w])
    z[0], z[1], z[2], z[3] = X[i, 0], X[i, 1], X[i, 2], least
    return z[8], z[9], z[10], z[11]


@njit(cache=True)
def _heun(P, S, t, A, NA, hit, zones, wheel_reach, zcache, awake, na, mu, acc, h, out, k1, k2, tmp, inp, held):
    """Heun step from t of the awake vehicles awake[:na] (inputs at t and just before t + h: a step never
    straddles an action's time, and one ending there keeps its own law); a sleeping vehicle's row of
    `out` is left as it is (the caller keeps it equal to its row of S). inp[i]: vehicle i's driver inputs
    at t and the cosines and sines of its steer and heading (IN_*, set by the step policy); held[i]: how
    long they hold (driver_inputs.steady_next). The wheels' frictions: _wheel_frictions, then
    planar_vehicle.vehicle_forces_trig."""
    zoned = zones[2].shape[0] > 0
    for a in range(na):
        i = awake[a]
        mode, brake = int(inp[i, IN_MODE]), inp[i, IN_BRAKE]
        cs, ss = inp[i, IN_COS_STEER], inp[i, IN_SIN_STEER]
        c, sn = inp[i, IN_COS_HEADING], inp[i, IN_SIN_HEADING]
        f0 = f1 = f2 = f3 = mu
        if zoned:
            f0, f1, f2, f3 = _wheel_frictions(P, S, i, c, sn, wheel_reach[i], mu, zones, zcache)
        vehicle_forces_trig(P[i], S[i], c, sn, f0, f1, f2, f3, mode, brake, cs, ss, acc[i], k1[i])
        for q in range(6):
            tmp[i, q] = S[i, q] + h * k1[i, q]
        if not (ahead(t, held[i]) and t + h <= held[i]):  # the step's own law at its end (left limit)
            mode, brake, steer = driver_inputs(A[i], NA[i], t + h, True)
            mode = effective_mode(mode, hit[i])
            if steer != inp[i, IN_STEER]:
                cs, ss = (math.cos(steer), math.sin(steer)) if steer != 0.0 else (1.0, 0.0)
        c, sn = math.cos(tmp[i, 2]), math.sin(tmp[i, 2])
        if zoned:
            f0, f1, f2, f3 = _wheel_frictions(P, tmp, i, c, sn, wheel_reach[i], mu, zones, zcache)
        vehicle_forces_trig(P[i], tmp[i], c, sn, f0, f1, f2, f3, mode, brake, cs, ss, acc[i], k2[i])
        for q in range(6):
            out[i, q] = S[i, q] + 0.5 * h * (k1[i, q] + k2[i, q])


@njit(cache=True)
def _near_zone(S, i, reach, box):
    """Whether vehicle i's CG lies within `reach` of a zone's bounding box (its friction may change within
    the step)."""
    for z in range(box.shape[0]):
        if box[z, 0] - reach < S[i, 0] < box[z, 1] + reach and box[z, 2] - reach < S[i, 1] < box[z, 3] + reach:
            return True
    return False


@njit(cache=True)
def _point_velocity(S, k, nv, px, py):
    if k >= nv:
        return 0.0, 0.0
    return S[k, 3] - S[k, 5] * (py - S[k, 1]), S[k, 4] + S[k, 5] * (px - S[k, 0])


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
        alt[I_REVERSED] = 1.0 if rev else 0.0
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
def _advanced(P, S, B, k, nv, tau, out):
    """The outline of vehicle or barrier k moved tau along its CG velocity (a barrier stays)."""
    if k >= nv:
        return _outline(P, S, B, k, nv, out)
    return rect_corners_into(out, S[k, 0] + tau * S[k, 3], S[k, 1] + tau * S[k, 4], math.cos(S[k, 2]),
                             math.sin(S[k, 2]), P[k, P_FRONT], P[k, P_REAR], P[k, P_HALFW])


@njit(cache=True)
def _engagement(P, S, B, i, k, nv, depth, nx, ny, oa, ob):
    """The point of impact and contact normal at engagement (docs/physics.md §4): the outlines of i and k
    moved along their CG velocities (no turning) until their overlap (`penetration` depth) reaches `depth`
    (bisection); the point at the overlap's centroid, moved back by half the pair's mean displacement
    (between the two crush zones, as contact_zone_centroid); the contact plane along the crushed faces
    (geometry.crushed_faces_axis: the overlap's edges weighted by the area each swept; a barrier's faces
    only, it does not crush), the normal from i
    to k (against k's displacement relative to i). Returns (px, py, ex, ey, flag, ratio): flag ENGAGE_USED;
    ENGAGE_AMBIGUOUS where the faces' principal values lie within 10 % (ratio > AMBIGUOUS_RATIO): the
    point is kept, the plane is the onset normal (nx, ny) (the struck edge at first touch); ENGAGE_FALLBACK
    with a NaN point where the overlap never reaches `depth` within 128 depth / closing speed, nothing was
    swept, or the pair does not approach at that point along that normal: the caller keeps the contact-zone
    point and the onset normal."""
    vix, viy = S[i, 3], S[i, 4]
    vkx, vky = (S[k, 3], S[k, 4]) if k < nv else (0.0, 0.0)
    closing = math.hypot(vkx - vix, vky - viy)
    if closing <= 0.0 or depth <= 0.0:
        return math.nan, math.nan, nx, ny, ENGAGE_FALLBACK, math.nan
    hi, reached = depth / closing, False
    for _ in range(8):  # bracket: 1, 2, 4, ... 128 x depth / closing speed
        if penetration(_advanced(P, S, B, i, nv, hi, oa), _advanced(P, S, B, k, nv, hi, ob))[0] >= depth:
            reached = True
            break
        hi *= 2.0
    if not reached:
        return math.nan, math.nan, nx, ny, ENGAGE_FALLBACK, math.nan
    lo = 0.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if penetration(_advanced(P, S, B, i, nv, mid, oa), _advanced(P, S, B, k, nv, mid, ob))[0] >= depth:
            hi = mid
        else:
            lo = mid
    ca, cb = _advanced(P, S, B, i, nv, hi, oa), _advanced(P, S, B, k, nv, hi, ob)
    cx, cy, _ = overlap_centroid(ca, cb)
    poly, npoly = clip_convex(ca, cb)
    dx, dy = hi * (vkx - vix), hi * (vky - viy)  # k's displacement relative to i
    tx, ty, ratio = crushed_faces_axis(poly, npoly, dx, dy, cb if k >= nv else cb[:0])  # a barrier: rigid
    if math.isnan(cx) or math.isnan(tx):
        return math.nan, math.nan, nx, ny, ENGAGE_FALLBACK, ratio
    flag = ENGAGE_USED
    ex, ey = ty, -tx  # the normal of the faces' plane, from i to k: k moved against it
    if ex * dx + ey * dy > 0.0:
        ex, ey = -ex, -ey
    if ratio > AMBIGUOUS_RATIO:
        flag, ex, ey = ENGAGE_AMBIGUOUS, nx, ny
    px, py = cx - 0.5 * hi * (vix + vkx), cy - 0.5 * hi * (viy + vky)
    v1x, v1y = _point_velocity(S, i, nv, px, py)
    v2x, v2y = _point_velocity(S, k, nv, px, py)
    if (v2x - v1x) * ex + (v2y - v1y) * ey >= 0.0:
        return math.nan, math.nan, nx, ny, ENGAGE_FALLBACK, ratio
    return px, py, ex, ey, flag, ratio


@njit(cache=True)
def _record_impact(imp, n, t, i, j, nv, S_before, S, pn, pt, kind, energy, px, py, nx, ny):
    imp[n, I_T], imp[n, I_I], imp[n, I_J] = t, i, j
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
    imp[n, I_T_END], imp[n, I_N_FOLLOW] = t, 0.0


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


@njit(cache=True)
def _project_apart(P, S, i, k, nv, nx, ny, shift):
    """Move the pair apart by `shift` along n (from i to k), split by inverse mass so that their centre
    of mass stays; positions only, velocities (momentum, energy) untouched (position projection,
    as the split impulse of Box2D / Chipmunk)."""
    w1 = 1.0 / P[i, P_MASS]
    w2 = 1.0 / P[k, P_MASS] if k < nv else 0.0
    f1, f2 = w1 / (w1 + w2), w2 / (w1 + w2)
    S[i, 0] -= shift * f1 * nx
    S[i, 1] -= shift * f1 * ny
    if k < nv:
        S[k, 0] += shift * f2 * nx
        S[k, 1] += shift * f2 * ny


@njit(cache=True)
def simulate_one(P, S0, B, cfg, A, NA, zones, rest, final, contact, imp, traj, diag):
    """Simulate one scene. P (nv, N_PARAMS), S0 (nv, 6) start states, B (nb, 5) barriers
    (x, y, heading, half length, half width), A, NA the driver's action tables, zones the friction zones
    (common/driver_inputs.pack_action_tables, pack_zones). Outputs are written into the arrays passed in."""
    nv, nb = P.shape[0], B.shape[0]
    nk = nv + nb
    mu, e, mu_imp, law = cfg[C_MU_ROAD], cfg[C_E], cfg[C_MU_IMP], int(cfg[C_LAW])
    duration, dt, coarse_dt, rec_dt = cfg[C_DURATION], cfg[C_DT], cfg[C_COARSE_DT], cfg[C_REC_DT]
    tol, v_rest, max_imp = cfg[C_ONSET_TOL], cfg[C_V_REST], min(int(cfg[C_MAX_IMPACTS]), imp.shape[0])
    broad, sleeping = cfg[C_BROAD_PHASE] > 0.5, cfg[C_SLEEPING] > 0.5  # study switches (comparison scaling)
    S = S0.copy()
    no_alt = np.empty(0)
    Snew = np.empty_like(S)
    S_before = np.empty_like(S)
    k1 = np.empty_like(S)
    k2 = np.empty_like(S)
    tmp = np.empty_like(S)
    acc = np.zeros((nv, 2))
    asleep = np.zeros(nv, np.bool_)
    hit = np.zeros(nv, np.bool_)
    radius = np.empty(nk)
    for k in range(nk):
        radius[k] = _radius(P, B, k, nv)
    in_contact = np.zeros((nv, nk), np.bool_)
    episode = np.full((nv, nk), -1, np.int64)  # impact row of the pair's open contact episode
    allowed = np.zeros((nv, nk))  # overlap the projection leaves (a collision position's start overlap)
    cl_i = np.empty(nv * nk, np.int64)  # the contacts of a step: pair, depth, normal, overlap centroid
    cl_k = np.empty(nv * nk, np.int64)
    cl_d = np.empty(nv * nk)
    cl_n = np.empty((nv * nk, 2))
    cl_p = np.empty((nv * nk, 2))
    cl_v = np.empty((nv * nk, 8, 2))  # and the overlap polygon's vertices
    cl_m = np.zeros(nv * nk, np.int64)
    oa, ob = np.empty((4, 2)), np.empty((4, 2))  # the outlines of the pair under test (_outline)
    pen = np.empty((nv * nk, 3))  # each listed pair's overlap test at the step's end: depth, normal
    awake = np.empty(nv, np.int64)  # the awake vehicles and the pairs with an awake member (_awake_sets)
    pair_i = np.empty(nv * nk, np.int64)
    pair_k = np.empty(nv * nk, np.int64)
    near_i = np.empty(nv * nk, np.int64)  # the listed pairs that can touch soon (_near_pairs)
    near_k = np.empty(nv * nk, np.int64)
    ref = np.zeros((nv, 2))
    n_near, near_stale = 0, True
    for i in range(nv):  # outlines that overlap at the start are in contact (a collision position)
        for k in range(i + 1, nk):
            if broad and _circles_apart(S, B, radius, i, k, nv):
                continue
            d0 = penetration(_outline(P, S, B, i, nv, oa), _outline(P, S, B, k, nv, ob))[0]
            if d0 > 0.0:
                in_contact[i, k] = True
                allowed[i, k] = d0
    mu_max = mu  # the largest road friction anywhere (zones): bounds the step and the stopping speed
    for z in range(zones[2].shape[0]):
        mu_max = max(mu_max, zones[2][z])
    zoned = zones[2].shape[0] > 0
    wheel_reach = np.empty(nv)  # the CG-centred circle holding every wheel (_wheel_frictions)
    zcache = np.zeros((nv, 12))  # each vehicle's last wheel frictions and their margins (_wheel_frictions): none
    zcache[:, 3:8] = -1.0
    inp = np.zeros((nv, N_IN))  # each vehicle's driver inputs at the step's start (_heun): steer 0 so far
    inp[:, IN_COS_STEER] = 1.0
    held = np.full(nv, -math.inf)  # until when the inputs of the law read last hold (steady_next): none yet
    law_mode = np.zeros(nv, np.int64)  # the law read last: driver_inputs, next_change, ramping
    law_brake = np.zeros(nv)
    law_change = np.zeros(nv)
    law_ramp = np.zeros(nv, np.bool_)
    rate_mode = np.full(nv, -1, np.int64)  # the wheel state of the vehicle's step bound rate_h (stiffest_rate)
    rate_h = np.full(nv, math.inf)
    for i in range(nv):
        wheel_reach[i] = math.sqrt(max(P[i, P_A], P[i, P_B]) ** 2 + (0.5 * P[i, P_TRACK]) ** 2)
    for i in range(nv):
        if math.hypot(S[i, 3], S[i, 4]) < v_rest and abs(S[i, 5]) < v_rest:
            S[i, 3:6] = 0.0
            asleep[i] = sleeping
    diag[:] = 0.0
    diag[D_CONTACT_T] = math.nan
    contact[:] = math.nan
    ke0 = 0.0
    for i in range(nv):
        ke0 += _kinetic(P, S, i, nv)
    diag[D_KE0] = ke0
    n_imp, n_rec, t = 0, 0, 0.0
    next_rec = 0.0
    status = STATUS_OK

    # impact at t = 0 at a given point of impact and contact plane (PC-Crash style)
    if cfg[C_GIVEN] > 0.5 and nk >= 2:
        i0, j = int(cfg[C_GIVEN_I]), int(cfg[C_GIVEN_J])  # the pair touching at the point
        px, py, th = cfg[C_PX], cfg[C_PY], cfg[C_PLANE]
        nx, ny = math.sin(th), -math.cos(th)
        cjx, cjy = _centre(S, B, j, nv)
        if nx * (cjx - S[i0, 0]) + ny * (cjy - S[i0, 1]) < 0.0:
            nx, ny = -nx, -ny
        for i in range(nv):
            contact[i, 0], contact[i, 1], contact[i, 2] = S[i, 0], S[i, 1], S[i, 2]
            contact[i, 3] = math.hypot(S[i, 3], S[i, 4])
        diag[D_CONTACT_T] = 0.0
        S_before[:] = S
        pn, pt, kind, energy, gn = _apply_impulse(P, S, i0, j, nv, px, py, nx, ny, e, mu_imp, law, imp[0])
        if kind < 0:
            status = STATUS_NOT_APPROACHING
        else:
            _record_impact(imp, 0, 0.0, i0, j, nv, S_before, S, pn, pt, kind, energy, px, py, nx, ny)
            n_imp = 1
            # the given impulse keeps its own row (the collision position's impulse as given); contact
            # after it, where the pair's overlap deepens, opens an episode of its own
            diag[D_E_IMPACT] += energy
            _struck(i0, j, nv, hit, asleep)
            in_contact[i0, j] = True

    na, n_pairs = _awake_sets(asleep, nk, awake, pair_i, pair_k)
    Snew[:] = S  # a sleeping vehicle's row of Snew stays equal to its row of S (_heun leaves it)
    steps = 0
    while t < duration - 1e-12:
        if rec_dt > 0.0 and t >= next_rec - 1e-12 and n_rec < traj.shape[0] - 1:
            traj[n_rec, :, 0] = t
            traj[n_rec, :, 1:7] = S
            n_rec += 1
            next_rec += rec_dt
        # ---- step size: the fine step within the tyre forces' stability limit, coarse while every
        # moving vehicle runs straight and nothing can touch
        # (a step ends where a driver's input changes its law: an action's start or its ramp's end; it is
        # fine within a ramp and near a friction zone)
        h = dt
        t_change = math.inf
        quiet = True
        for a in range(na):
            i = awake[a]
            if not ahead(t, held[i]):  # the inputs' law changed (or changes continuously): read it again
                law_mode[i], law_brake[i], steer = driver_inputs(A[i], NA[i], t)
                law_change[i] = next_change(A[i], NA[i], t)
                law_ramp[i] = ramping(A[i], NA[i], t)
                held[i] = steady_next(A[i], NA[i], t)
                if steer != inp[i, IN_STEER]:
                    inp[i, IN_STEER] = steer
                    inp[i, IN_COS_STEER], inp[i, IN_SIN_STEER] = ((math.cos(steer), math.sin(steer)) if steer != 0.0
                                                                  else (1.0, 0.0))
            t_change = min(t_change, law_change[i])
            if law_ramp[i]:
                quiet = False
            mode, brake, steer = effective_mode(law_mode[i], hit[i]), law_brake[i], inp[i, IN_STEER]
            inp[i, IN_MODE], inp[i, IN_BRAKE] = mode, brake
            if mode == ROLLING and brake > 0.0:
                mode = BRAKED  # a braking rolling wheel is as stiff as a braked one
            if mode != rate_mode[i]:  # (the bound changes with the wheel state only: mu_max is fixed)
                rate = stiffest_rate(P[i], mu_max, mode)  # 0 for locked wheels on ice: no tyre force
                rate_mode[i], rate_h[i] = mode, 1.0 / rate if rate > 0.0 else math.inf
            h = min(h, rate_h[i])
            c, sn = math.cos(S[i, 2]), math.sin(S[i, 2])
            inp[i, IN_COS_HEADING], inp[i, IN_SIN_HEADING] = c, sn
            lat = -sn * S[i, 3] + c * S[i, 4]
            speed = math.hypot(S[i, 3], S[i, 4])
            if abs(S[i, 5]) > 1e-9 or abs(lat) > 1e-9 or steer != 0.0:
                quiet = False
            elif zoned and _near_zone(S, i, radius[i] + speed * coarse_dt + PATCH, zones[3]):
                quiet = False
            # a vehicle that can come to a stop within a coarse step (deceleration <= mu g) is near
            # the discontinuity of Coulomb friction: a coarse Heun step there oscillates about v = 0
            if speed < 2.0 * mu_max * G * coarse_dt + STOP_MARGIN:
                quiet = False
        if quiet and coarse_dt > dt:
            h_gap = coarse_dt
            for p in range(n_pairs):  # (a sleeping vehicle and a barrier: not listed, closing 0)
                i, k = pair_i[p], pair_k[p]
                ckx, cky = _centre(S, B, k, nv)
                gap = math.hypot(S[i, 0] - ckx, S[i, 1] - cky) - radius[i] - radius[k]
                closing = math.hypot(S[i, 3], S[i, 4])
                if k < nv:
                    closing += math.hypot(S[k, 3], S[k, 4])
                if closing > 0.0:
                    h_gap = min(h_gap, 0.5 * gap / closing)
            if h_gap > h:
                h = h_gap
                diag[D_COARSE] += 1
        h = min(h, duration - t, t_change - t)
        _heun(P, S, t, A, NA, hit, zones, wheel_reach, zcache, awake, na, mu, acc, h, Snew, k1, k2, tmp, inp, held)
        steps += 1
        diag[D_VEHICLE_STEPS] += na
        if steps > MAX_STEPS:
            status = STATUS_STEP_LIMIT
            break
        # ---- the pairs tested this step: with the broad phase, pairs with a static partner far away
        # are left out (_near_pairs, rebuilt once an awake vehicle has moved REACH); a step longer
        # than REACH tests every listed pair
        li, lk, nl = pair_i, pair_k, n_pairs
        if broad and (na < nv or nb > 0):
            if near_stale or _moved(S, Snew, awake, na, ref, REACH):
                near_stale = _moved(S, Snew, awake, na, S[:, 0:2], REACH)  # the step itself longer
                if not near_stale:
                    n_near = _near_pairs(S, B, radius, asleep, awake, na, pair_i, pair_k, n_pairs, ref, REACH,
                                         near_i, near_k, in_contact, episode, allowed)
            if not near_stale:
                li, lk, nl = near_i, near_k, n_near
        # ---- onset of a new contact: bisect the step until the overlap is at most tol; a touching pair
        # whose overlap deepens past DEEPEN within the step (another part of it approaching, e.g. a
        # rotating car's far corner) is bisected likewise, to an overlap between CONTACT_SLOP and DEEPEN
        bisected = False  # (else the contacts below reuse each pair's test of the step's end: pen)
        for p in range(nl):
            i, k = li[p], lk[p]
            if broad and _circles_apart(Snew, B, radius, i, k, nv):
                continue
            diag[D_NARROW] += 1
            depth, nx, ny, _ = penetration(_outline(P, Snew, B, i, nv, oa), _outline(P, Snew, B, k, nv, ob))
            pen[p, 0], pen[p, 1], pen[p, 2] = depth, nx, ny
            if in_contact[i, k]:
                if allowed[i, k] > 0.0 or depth <= DEEPEN:
                    continue
                lo_d, hi_d = CONTACT_SLOP, DEEPEN
            else:
                if depth <= tol or (episode[i, k] >= 0 and depth <= CONTACT_SLOP):
                    continue
                lo_d, hi_d = 0.0, tol
            lo, hi = 0.0, h
            bisected = True
            for _ in range(60):
                hm = 0.5 * (lo + hi)
                _heun(P, S, t, A, NA, hit, zones, wheel_reach, zcache, awake, na, mu, acc, hm, Snew, k1, k2, tmp, inp,
                      held)
                diag[D_BISECT] += 1
                depth = penetration(_outline(P, Snew, B, i, nv, oa), _outline(P, Snew, B, k, nv, ob))[0]
                if depth > hi_d:
                    hi = hm
                elif depth <= lo_d:
                    lo = hm
                else:
                    break
            h = hm
        t += h
        for a in range(na):
            i = awake[a]
            for q in range(6):
                S[i, q] = Snew[i, q]
        # ---- contacts: an impact (the first touch of an episode) gets its own row; a pair in an open
        # episode that overlaps and approaches gets a plastic contact impulse booked into the episode's
        # row. Several contacts at once (a car squeezed between a car and a wall) are
        # resolved together by sweeps of sequential impulses (projected Gauss-Seidel) over the step's
        # contacts: after the first sweep a pair is approaching again only through its neighbours'
        # impulses of this instant, so its further impulses are plastic and booked into its row. Then a
        # projection keeps each overlap below CONTACT_SLOP.
        nc = 0
        for p in range(nl):
            i, k = li[p], lk[p]
            if broad and _circles_apart(S, B, radius, i, k, nv):
                in_contact[i, k] = False
                episode[i, k] = -1
                allowed[i, k] = 0.0
                continue
            if bisected:  # the step's end moved since the onset test
                diag[D_NARROW] += 1
                depth, nx, ny, _ = penetration(_outline(P, S, B, i, nv, oa), _outline(P, S, B, k, nv, ob))
            else:
                depth, nx, ny = pen[p, 0], pen[p, 1], pen[p, 2]
            if depth <= 0.0:
                in_contact[i, k] = False
                allowed[i, k] = 0.0
                if -depth > SEPARATION:
                    episode[i, k] = -1
                continue
            in_contact[i, k] = True
            if depth <= allowed[i, k] + CONTACT_SLOP and allowed[i, k] > 0.0:
                # a collision position's start overlap, not deepening: the given impulse resolved it
                allowed[i, k] = min(allowed[i, k], depth)
                continue
            diag[D_MAX_DEPTH] = max(diag[D_MAX_DEPTH], depth)
            ci, ck = _outline(P, S, B, i, nv, oa), _outline(P, S, B, k, nv, ob)
            px, py, area = overlap_centroid(ci, ck)
            if math.isnan(px):
                continue
            poly, npoly = clip_convex(ci, ck)
            cl_m[nc] = min(npoly, cl_v.shape[1])
            cl_v[nc, :cl_m[nc]] = poly[:cl_m[nc]]
            cl_i[nc], cl_k[nc], cl_d[nc] = i, k, depth
            cl_n[nc, 0], cl_n[nc, 1], cl_p[nc, 0], cl_p[nc, 1] = nx, ny, px, py
            nc += 1
        stop = False
        woke = False
        for _ in range(MAX_SWEEPS if nc > 1 else 1):
            active = False
            for c in range(nc):
                i, k = cl_i[c], cl_k[c]
                nx, ny, px, py = cl_n[c, 0], cl_n[c, 1], cl_p[c, 0], cl_p[c, 1]
                v1x, v1y = _point_velocity(S, i, nv, px, py)
                v2x, v2y = _point_velocity(S, k, nv, px, py)
                approach = -((v2x - v1x) * nx + (v2y - v1y) * ny)
                row = episode[i, k]
                if row >= 0 and imp[row, I_T] != t:
                    # sustained contact: the overlap's vertex that approaches fastest (rigid bodies: the
                    # normal velocity is linear over the overlap, so its extremes are at vertices)
                    for q in range(cl_m[c]):
                        qx, qy = cl_v[c, q, 0], cl_v[c, q, 1]
                        v1x, v1y = _point_velocity(S, i, nv, qx, qy)
                        v2x, v2y = _point_velocity(S, k, nv, qx, qy)
                        aq = -((v2x - v1x) * nx + (v2y - v1y) * ny)
                        if aq > approach:
                            approach, px, py = aq, qx, qy
                if approach <= V_EPS:
                    continue
                is_impact = row < 0
                if is_impact:
                    if n_imp >= max_imp:
                        status = STATUS_IMPACT_CAP
                        stop = True
                        break
                    # the point: the middle of the contact zone the approach will crush, or (point =
                    # "engagement") the overlap's centroid at engagement with its contact plane
                    zx, e_flag, e_ratio = math.nan, 0, math.nan
                    if cfg[C_ENGAGE] > 0.5:
                        zx, zy, nx, ny, e_flag, e_ratio = _engagement(P, S, B, i, k, nv, cfg[C_ENGAGE_DEPTH], nx,
                                                                      ny, oa, ob)
                    if math.isnan(zx):
                        zx, zy, _ = contact_zone_centroid(_outline(P, S, B, i, nv, oa),
                                                          _outline(P, S, B, k, nv, ob),
                                                          nx, ny, cfg[C_CRUSH_TIME] * approach)
                    if not math.isnan(zx):
                        px, py = zx, zy
                e_k = e if is_impact else 0.0  # follow-ups are plastic (no bounce chatter)
                S_before[:] = S
                alt = imp[n_imp] if is_impact else no_alt  # (the impact's row: its slip-reversal check)
                pn, pt, kind, energy, gn = _apply_impulse(P, S, i, k, nv, px, py, nx, ny, e_k, mu_imp, law, alt)
                if kind < 0:
                    continue
                active = True
                if is_impact:
                    if n_imp == 0:
                        diag[D_CONTACT_T] = t
                        for q in range(nv):
                            contact[q, 0], contact[q, 1] = S_before[q, 0], S_before[q, 1]
                            contact[q, 2] = S_before[q, 2]
                            contact[q, 3] = math.hypot(S_before[q, 3], S_before[q, 4])
                    _record_impact(imp, n_imp, t, i, k, nv, S_before, S, pn, pt, kind, energy, px, py, nx, ny)
                    imp[n_imp, I_ENGAGE], imp[n_imp, I_ENGAGE_RATIO] = e_flag, e_ratio
                    episode[i, k] = n_imp
                    n_imp += 1
                else:
                    _merge_impact(imp, row, t, i, k, nv, S_before, S, pn, pt, energy, nx, ny)
                    diag[D_FOLLOW] += 1
                diag[D_E_IMPACT] += energy
                woke = woke or asleep[i] or (k < nv and asleep[k])
                _struck(i, k, nv, hit, asleep)
            if stop or not active:
                break
        if stop:
            break
        if woke:
            na, n_pairs = _awake_sets(asleep, nk, awake, pair_i, pair_k)
            near_stale = True
        # non-penetration at the position level: the velocity-level contact impulse stops the approach at
        # the end of a step but not the overlap gained within it (~ a h^2 / 2)
        for c in range(nc):
            i, k, depth = cl_i[c], cl_k[c], cl_d[c]
            target = max(allowed[i, k], CONTACT_SLOP)
            if depth > target:
                _project_apart(P, S, i, k, nv, cl_n[c, 0], cl_n[c, 1], depth - target)
                diag[D_PROJECTED] += depth - target
                Snew[i] = S[i]  # (a sleeping vehicle's row of Snew equals its row of S)
                if k < nv:
                    Snew[k] = S[k]
                    near_stale = near_stale or asleep[k]  # a static partner moved
                near_stale = near_stale or asleep[i]
            allowed[i, k] = min(allowed[i, k], depth)
        # ---- rest: a vehicle that has (almost) stopped goes to sleep; an impulse wakes it
        # (a sleeping vehicle's state is only moved by the projection, finite: NaN can arise in awake ones)
        all_asleep, slept = True, False
        for a in range(na):
            i = awake[a]
            if math.hypot(S[i, 3], S[i, 4]) < v_rest and abs(S[i, 5]) < v_rest:
                S[i, 3:6] = 0.0
                asleep[i] = sleeping
                if sleeping:
                    Snew[i] = S[i]
                    slept = True
            if not asleep[i]:
                all_asleep = False
            if math.isnan(S[i, 0]) or math.isnan(S[i, 3]):
                status = STATUS_NAN
        if slept:
            na, n_pairs = _awake_sets(asleep, nk, awake, pair_i, pair_k)
            near_stale = True
        if status == STATUS_NAN or (all_asleep and cfg[C_STOP_AT_REST] > 0.5):
            break
    if rec_dt > 0.0 and n_rec < traj.shape[0]:
        traj[n_rec, :, 0] = t
        traj[n_rec, :, 1:7] = S
        n_rec += 1
    rest[:, :] = S[:, 0:3]
    final[:, :] = S[:, 3:6]
    diag[D_STEPS], diag[D_IMPACTS], diag[D_NREC], diag[D_T_END] = steps, n_imp, n_rec, t
    diag[D_STATUS] = status


@njit(cache=True, parallel=True)
def simulate_many(P, S0, B, cfg, A, NA, ZC, ZS, ZMU, ZBOX, rest, final, contact, imp, diag):
    """A batch of scenes of the same composition (vehicles, barriers, action rows, zone corners), in
    parallel, without trajectories."""
    no_traj = np.empty((0, P.shape[1], 7))
    for s in prange(P.shape[0]):
        simulate_one(P[s], S0[s], B[s], cfg[s], A[s], NA[s], (ZC[s], ZS[s], ZMU[s], ZBOX[s]), rest[s], final[s],
                     contact[s], imp[s], no_traj, diag[s])
