"""Narrow phase of the vehicle contacts (docs/physics.md §12): the signed gap of two bodies over horizontal
directions d(th) = (cos th, sin th, 0) only, g(th) = -(h1(d) + h2(-d)) with the closed-form support values
(a chassis superellipsoid or a barrier box), maximised by a golden-section search: global (a 72-angle scan,
then refinement) for a pair not in contact, warm-started from the previous angle while it is (it follows
the contact branch). Why horizontal: chassis_contact.py. The general 3D narrow phase (common-normal Newton,
SLSQP fallback) is a test tool in tests/narrow_phase_3d.py.
"""
import math

from numba import njit

from .superellipsoid import support_value_global

N_SCAN = 72        # angles of the global scan
GOLDEN_IT = 40     # golden-section iterations (~1e-9 rad)
WARM_HALF = 0.15   # rad: half-width of the warm-started window


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
def horizontal_gap(th0, warm, k2, sh1, r1, A1, sh2, r2, A2):
    """(th, g): the horizontal direction maximising the separation g(th) (signed gap, < 0 penetrating)."""
    if warm:
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
