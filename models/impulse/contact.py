"""Contact geometry of the impulse kernel: outlines, bounding circles, velocities of points, the engagement
point and plane (docs/physics.md §4), and the position projection of an overlapping pair (§5)."""
import math

from numba import njit

from crashlab.geometry import clip_convex, crushed_faces_axis, overlap_centroid, penetration, rect_corners_into
from crashlab.models.common.planar_vehicle import P_FRONT, P_HALFW, P_MASS, P_REAR

from .layout import AMBIGUOUS_RATIO, ENGAGE_AMBIGUOUS, ENGAGE_FALLBACK, ENGAGE_USED


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
def _gap(S, B, radius, i, k, nv):
    ckx, cky = _centre(S, B, k, nv)
    return math.hypot(S[i, 0] - ckx, S[i, 1] - cky) - radius[i] - radius[k]


@njit(cache=True)
def _point_velocity(S, k, nv, px, py):
    if k >= nv:
        return 0.0, 0.0
    return S[k, 3] - S[k, 5] * (py - S[k, 1]), S[k, 4] + S[k, 5] * (px - S[k, 0])


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
