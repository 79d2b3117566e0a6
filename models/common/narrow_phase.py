"""Narrow phase of the vehicle contacts (docs/physics.md §12): the signed gap of two bodies over horizontal
directions d(th) = (cos th, sin th, 0) only, g(th) = -(h1(d) + h2(-d)) with the closed-form support values
(a chassis superellipsoid or a barrier box), maximised: global (a 72-angle scan, then a golden-section
refinement) for a pair not in contact; warm-started from the previous angle while it is (it follows the
contact branch) as the root of the derivative
    g'(th) = (sigma2(-d) - sigma1(d)) . d'(th),   d' = (-sin th, cos th, 0)
(the derivative of a support function is the support point), bracketed by steps growing from the previous
angle and solved by Brent's method (zeroin): about 7 support-point evaluations to ~1e-12 rad instead of
the 42 support values of a golden section whose comparisons stop resolving the flat maximum at ~1e-8 rad.
When no maximum is bracketed within WARM_HALF (two extrema close together, a box corner), the warm
golden-section search of the window runs as before. Why horizontal: chassis_contact.py. The general 3D
narrow phase (common-normal Newton, SLSQP fallback) is a test tool in tests/narrow_phase_3d.py.
"""
import math

from numba import njit

from .superellipsoid import support_global, support_value_global

N_SCAN = 72        # angles of the global scan
GOLDEN_IT = 40     # golden-section iterations (~1e-9 rad)
WARM_HALF = 0.15   # rad: half-width of the warm-started window
WARM_STEP = 1e-3   # rad: first bracketing step of the warm start (x 4 per try, up to WARM_HALF)
ROOT_XTOL = 1e-12  # rad: Brent's tolerance on the angle
EPS = 2.220446049250313e-16


@njit(cache=True)
def support_value_body(kind, d0, d1, d2, sh, r, A):
    """Global support value h(d) of a chassis superellipsoid (kind 0) or of a box (kind 1, sh = half-extents)."""
    if kind == 0:
        return support_value_global(d0, d1, d2, sh, r, A)
    h = d0 * r[0] + d1 * r[1] + d2 * r[2]
    for k in range(3):
        h += abs(A[0, k] * d0 + A[1, k] * d1 + A[2, k] * d2) * sh[k]
    return h


@njit(cache=True)
def _g(th, k2, sh1, r1, A1, sh2, r2, A2):
    c, s = math.cos(th), math.sin(th)
    return -(support_value_body(0, c, s, 0.0, sh1, r1, A1) + support_value_body(k2, -c, -s, 0.0, sh2, r2, A2))


@njit(cache=True)
def _golden(lo, hi, k2, sh1, r1, A1, sh2, r2, A2):
    gr = 0.6180339887498949
    x1 = hi - gr * (hi - lo)
    x2 = lo + gr * (hi - lo)
    f1 = _g(x1, k2, sh1, r1, A1, sh2, r2, A2)
    f2 = _g(x2, k2, sh1, r1, A1, sh2, r2, A2)
    for _ in range(GOLDEN_IT):
        if f1 > f2:
            hi, x2, f2 = x2, x1, f1
            x1 = hi - gr * (hi - lo)
            f1 = _g(x1, k2, sh1, r1, A1, sh2, r2, A2)
        else:
            lo, x1, f1 = x1, x2, f2
            x2 = lo + gr * (hi - lo)
            f2 = _g(x2, k2, sh1, r1, A1, sh2, r2, A2)
    if f1 > f2:
        return x1, f1
    return x2, f2


@njit(cache=True)
def support_point_body(kind, d0, d1, d2, sh, r, A):
    """Global support point of a chassis superellipsoid (kind 0) or of a box (kind 1; on an edge or face
    normal to d: its centre line)."""
    if kind == 0:
        return support_global(d0, d1, d2, sh, r, A)
    p = [r[0], r[1], r[2]]
    for k in range(3):
        u = A[0, k] * d0 + A[1, k] * d1 + A[2, k] * d2
        sg = 1.0 if u > 0.0 else (-1.0 if u < 0.0 else 0.0)
        for i in range(3):
            p[i] += sg * sh[k] * A[i, k]
    return (p[0], p[1], p[2])


@njit(cache=True)
def _dg(th, k2, sh1, r1, A1, sh2, r2, A2):
    """g'(th) = (sigma2(-d) - sigma1(d)) . (-sin th, cos th, 0)."""
    c, s = math.cos(th), math.sin(th)
    P1 = support_point_body(0, c, s, 0.0, sh1, r1, A1)
    P2 = support_point_body(k2, -c, -s, 0.0, sh2, r2, A2)
    return -(P2[0] - P1[0]) * s + (P2[1] - P1[1]) * c


@njit(cache=True)
def _zeroin(a, b, fa, fb, k2, sh1, r1, A1, sh2, r2, A2):
    """Brent's method (Brent 1973, Algorithms for Minimization without Derivatives, ch. 4: zeroin) for the
    root of _dg on [a, b], fa and fb of opposite signs."""
    c, fc = a, fa
    d = e = b - a
    for _ in range(100):
        if (fb > 0.0 and fc > 0.0) or (fb < 0.0 and fc < 0.0):
            c, fc = a, fa
            d = e = b - a
        if abs(fc) < abs(fb):
            a, b, c = b, c, b
            fa, fb, fc = fb, fc, fb
        tol = 2.0 * EPS * abs(b) + 0.5 * ROOT_XTOL
        m = 0.5 * (c - b)
        if abs(m) <= tol or fb == 0.0:
            return b
        if abs(e) >= tol and abs(fa) > abs(fb):
            s = fb / fa
            if a == c:
                p = 2.0 * m * s
                q = 1.0 - s
            else:
                q = fa / fc
                r = fb / fc
                p = s * (2.0 * m * q * (q - r) - (b - a) * (r - 1.0))
                q = (q - 1.0) * (r - 1.0) * (s - 1.0)
            if p > 0.0:
                q = -q
            else:
                p = -p
            if 2.0 * p < min(3.0 * m * q - abs(tol * q), abs(e * q)):
                e = d
                d = p / q
            else:
                d = m
                e = m
        else:
            d = m
            e = m
        a, fa = b, fb
        if abs(d) > tol:
            b += d
        else:
            b += tol if m > 0.0 else -tol
        fb = _dg(b, k2, sh1, r1, A1, sh2, r2, A2)
    return b


@njit(cache=True)
def _warm_root(th0, k2, sh1, r1, A1, sh2, r2, A2):
    """The maximum of g next to th0 as the root of g' (Brent), bracketed by steps WARM_STEP x 4^k towards
    the rising side; nan if g' does not fall through zero within WARM_HALF."""
    f0 = _dg(th0, k2, sh1, r1, A1, sh2, r2, A2)
    if f0 == 0.0:
        return th0
    sg = 1.0 if f0 > 0.0 else -1.0
    a, fa = th0, f0
    step = WARM_STEP
    while step <= WARM_HALF:
        b = th0 + sg * step
        fb = _dg(b, k2, sh1, r1, A1, sh2, r2, A2)
        if fb == 0.0:
            return b
        if (fb > 0.0) != (f0 > 0.0):
            return _zeroin(a, b, fa, fb, k2, sh1, r1, A1, sh2, r2, A2)
        a, fa = b, fb
        step *= 4.0
    return math.nan


@njit(cache=True)
def horizontal_gap(th0, warm, k2, sh1, r1, A1, sh2, r2, A2):
    """(th, g): the horizontal direction maximising the separation g(th) (signed gap, < 0 penetrating)."""
    if warm:
        th = _warm_root(th0, k2, sh1, r1, A1, sh2, r2, A2)
        if th == th:
            return th, _g(th, k2, sh1, r1, A1, sh2, r2, A2)
        lo, hi = th0 - WARM_HALF, th0 + WARM_HALF
        th, g = th0, -1e300
        for _ in range(8):
            th, g = _golden(lo, hi, k2, sh1, r1, A1, sh2, r2, A2)
            if th - lo > 0.02 and hi - th > 0.02:
                break
            lo, hi = th - WARM_HALF, th + WARM_HALF
        return th, g
    best, tb = -1e300, 0.0
    for k in range(N_SCAN):
        th = 2.0 * math.pi * k / N_SCAN
        g = _g(th, k2, sh1, r1, A1, sh2, r2, A2)
        if g > best:
            best, tb = g, th
    w = 2.0 * math.pi / N_SCAN
    return _golden(tb - w, tb + w, k2, sh1, r1, A1, sh2, r2, A2)
