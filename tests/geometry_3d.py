"""Test tools: superellipsoid geometry and broad-phase stages that only the tests use (docs/physics.md §10,
§11); the models' support mapping and oriented-box test are in models/common/superellipsoid.py and
broad_phase.py.

Scalar kernels (numba, 3-tuples): F_local, G_local, grad_F_local, grad_G_local, normal_local,
radial_project, G_global, normal_global. Vectorised numpy helpers (N x 3 arrays): F_np, G_np, normal_np,
to_local, to_global, sample_surface, shape, shape_pose. Broad phase: bounding_radius, aabb_half_extents,
spheres_overlap, aabb_overlap, filter_pairs.

Numerics:
* F = (|X|^(2/e2) + |Y|^(2/e2))^(e2/e1) + |Z|^(2/e1) - 1 overflows away from the surface for small eps;
  G = (F+1)^(e1/2) - 1 is homogeneous of degree 1 (G(l xi)+1 = l (G(xi)+1)), and it is evaluated here
  on xi/m with m = max(|X|, |Y|, |Z|) and scaled back, so it never overflows.
* The normal direction is homogeneous of degree 0 and is evaluated on the same scaled point.
* |X|, |Y| < 1e-12 (scaled): only the z component of the gradient is kept (Portal's special case; the
  factor s^(e2/e1 - 1) would be inf * 0 when e2 > e1).
* A shape offset in its body (s'_c, A'_c of §10) is folded into a single (r, A) by `shape_pose`.
"""
import math

import numpy as np
from numba import njit

from crashlab.models.common.broad_phase import obb_overlap
from crashlab.models.common.superellipsoid import (  # noqa: F401  (re-exported for the tests)
    mat_t_vec,
    mat_vec,
    support_global,
    support_local,
    support_value_global,
    support_value_local,
)

XY_TINY = 1e-12


@njit(cache=True)
def F_local(x, y, z, sh):
    """Implicit function F of §10 (<0 inside, 0 on the surface, >0 outside). May overflow far away for
    small eps: use G_local there."""
    a, b, c, e1, e2 = sh[0], sh[1], sh[2], sh[3], sh[4]
    X = abs(x / a)
    Y = abs(y / b)
    Z = abs(z / c)
    s = X ** (2.0 / e2) + Y ** (2.0 / e2)
    return s ** (e2 / e1) + Z ** (2.0 / e1) - 1.0


@njit(cache=True)
def _scaled_F1(X, Y, Z, e1, e2):
    """F+1 on already-normalised |X|, |Y|, |Z| (max of them = 1 -> no overflow)."""
    s = X ** (2.0 / e2) + Y ** (2.0 / e2)
    return s ** (e2 / e1) + Z ** (2.0 / e1)


@njit(cache=True)
def G_local(x, y, z, sh):
    """Well-scaled implicit function G = (F+1)^(e1/2) - 1 (homogeneous of degree 1 in xi + 1); same zero
    set and sign as F; evaluated through the homogeneity, so no overflow for small eps."""
    a, b, c, e1, e2 = sh[0], sh[1], sh[2], sh[3], sh[4]
    X = abs(x / a)
    Y = abs(y / b)
    Z = abs(z / c)
    m = max(X, max(Y, Z))
    if m == 0.0:
        return -1.0
    f1 = _scaled_F1(X / m, Y / m, Z / m, e1, e2)
    return m * f1 ** (0.5 * e1) - 1.0


@njit(cache=True)
def grad_F_local(x, y, z, sh):
    """Gradient of F (§10) at xi, with the |X|, |Y| < 1e-12 special case. Direct formula: may overflow
    far from the surface for small eps (use normal_local / grad_G_local there)."""
    a, b, c, e1, e2 = sh[0], sh[1], sh[2], sh[3], sh[4]
    X = x / a
    Y = y / b
    Z = z / c
    gz = (2.0 / (e1 * c)) * abs(Z) ** (2.0 / e1 - 1.0) * (1.0 if Z > 0 else (-1.0 if Z < 0 else 0.0))
    if abs(X) < XY_TINY and abs(Y) < XY_TINY:
        return (0.0, 0.0, gz)
    aX = abs(X)
    aY = abs(Y)
    s = aX ** (2.0 / e2) + aY ** (2.0 / e2)
    k = (2.0 / e1) * s ** (e2 / e1 - 1.0)
    gx = k / a * aX ** (2.0 / e2 - 1.0) * (1.0 if X > 0 else (-1.0 if X < 0 else 0.0))
    gy = k / b * aY ** (2.0 / e2 - 1.0) * (1.0 if Y > 0 else (-1.0 if Y < 0 else 0.0))
    return (gx, gy, gz)


@njit(cache=True)
def grad_G_local(x, y, z, sh):
    """Gradient of G (homogeneous of degree 0, evaluated on the scaled point: never overflows)."""
    a, b, c, e1, e2 = sh[0], sh[1], sh[2], sh[3], sh[4]
    m = max(abs(x / a), max(abs(y / b), abs(z / c)))
    if m == 0.0:
        return (0.0, 0.0, 0.0)
    xs, ys, zs = x / m, y / m, z / m
    g = grad_F_local(xs, ys, zs, sh)
    f1 = _scaled_F1(abs(xs / a), abs(ys / b), abs(zs / c), e1, e2)
    k = 0.5 * e1 * f1 ** (0.5 * e1 - 1.0)
    return (k * g[0], k * g[1], k * g[2])


@njit(cache=True)
def normal_local(x, y, z, sh):
    """Unit outward normal grad F / |grad F| in local coordinates (direction of the level set through xi)."""
    g = grad_G_local(x, y, z, sh)
    n = math.sqrt(g[0] * g[0] + g[1] * g[1] + g[2] * g[2])
    if n == 0.0:
        return (0.0, 0.0, 1.0)
    return (g[0] / n, g[1] / n, g[2] / n)


@njit(cache=True)
def radial_project(x, y, z, sh):
    """xi / (G(xi) + 1): the surface point on the ray from the centre through xi."""
    g1 = G_local(x, y, z, sh) + 1.0
    if g1 <= 0.0:
        return (0.0, 0.0, sh[2])
    return (x / g1, y / g1, z / g1)


@njit(cache=True)
def G_global(x0, x1, x2, sh, r, A):
    l = mat_t_vec(A, x0 - r[0], x1 - r[1], x2 - r[2])
    return G_local(l[0], l[1], l[2], sh)


@njit(cache=True)
def normal_global(x0, x1, x2, sh, r, A):
    l = mat_t_vec(A, x0 - r[0], x1 - r[1], x2 - r[2])
    n = normal_local(l[0], l[1], l[2], sh)
    return mat_vec(A, n[0], n[1], n[2])


# ----------------------------------------------------------------------------------------------------
def shape(a, b, c, eps1, eps2):
    """Pack a shape array [a, b, c, eps1, eps2] (checks convexity 0 < eps <= 2)."""
    if not (a > 0 and b > 0 and c > 0):
        raise ValueError("semi-axes must be positive")
    if not (0 < eps1 <= 2 and 0 < eps2 <= 2):
        raise ValueError("shape exponents must satisfy 0 < eps <= 2 (convexity)")
    return np.array([a, b, c, eps1, eps2], dtype=np.float64)


def shape_pose(r_body, A_body, s_c=None, A_c=None):
    """Pose of a shape offset in its body (§10): x = r_i + A_i (s'_c + A'_c xi) = r + A xi."""
    r_body = np.asarray(r_body, float)
    A_body = np.asarray(A_body, float)
    s_c = np.zeros(3) if s_c is None else np.asarray(s_c, float)
    A_c = np.eye(3) if A_c is None else np.asarray(A_c, float)
    return r_body + A_body @ s_c, A_body @ A_c


def to_local(x, r, A):
    """Global point(s) x (..., 3) -> local xi = A^T (x - r)."""
    return (np.asarray(x, float) - r) @ np.asarray(A, float)


def to_global(xi, r, A):
    """Local point(s) xi (..., 3) -> global x = r + A xi."""
    return np.asarray(xi, float) @ np.asarray(A, float).T + r


def _split(xi, sh):
    xi = np.atleast_2d(np.asarray(xi, float))
    a, b, c, e1, e2 = sh
    return np.abs(xi[:, 0] / a), np.abs(xi[:, 1] / b), np.abs(xi[:, 2] / c), e1, e2


def F_np(xi, sh):
    """F of §10 for an (N, 3) array of local points."""
    X, Y, Z, e1, e2 = _split(xi, sh)
    with np.errstate(over="ignore"):
        return (X ** (2 / e2) + Y ** (2 / e2)) ** (e2 / e1) + Z ** (2 / e1) - 1.0


def G_np(xi, sh):
    """Well-scaled G for an (N, 3) array of local points (no overflow)."""
    X, Y, Z, e1, e2 = _split(xi, sh)
    m = np.maximum(np.maximum(X, Y), Z)
    ms = np.where(m > 0, m, 1.0)
    X, Y, Z = X / ms, Y / ms, Z / ms
    f1 = (X ** (2 / e2) + Y ** (2 / e2)) ** (e2 / e1) + Z ** (2 / e1)
    return np.where(m > 0, m * f1 ** (0.5 * e1) - 1.0, -1.0)


def normal_np(xi, sh):
    """Unit outward local normals for an (N, 3) array of local points (special case |X|,|Y| < 1e-12)."""
    xi = np.atleast_2d(np.asarray(xi, float))
    a, b, c, e1, e2 = sh
    m = np.max(np.abs(xi / np.array([a, b, c])), axis=1)
    m = np.where(m > 0, m, 1.0)
    X, Y, Z = xi[:, 0] / a / m, xi[:, 1] / b / m, xi[:, 2] / c / m
    aX, aY = np.abs(X), np.abs(Y)
    tiny = (aX < XY_TINY) & (aY < XY_TINY)
    s = np.where(tiny, 1.0, aX ** (2 / e2) + aY ** (2 / e2))
    k = (2 / e1) * s ** (e2 / e1 - 1.0)
    gx = np.where(tiny, 0.0, k / a * aX ** (2 / e2 - 1.0) * np.sign(X))
    gy = np.where(tiny, 0.0, k / b * aY ** (2 / e2 - 1.0) * np.sign(Y))
    gz = (2 / (e1 * c)) * np.abs(Z) ** (2 / e1 - 1.0) * np.sign(Z)
    g = np.stack([gx, gy, gz], axis=1)
    return g / np.linalg.norm(g, axis=1, keepdims=True)


def sample_surface(sh, n=40):
    """Surface points: an n x n grid on each face of the unit cube, scaled by (a, b, c) and projected
    radially onto the surface (xi / (G + 1)). Spacing on the surface <= ~2 max(a,b,c)/n for boxy shapes."""
    u = np.linspace(-1.0, 1.0, n)
    U, V = np.meshgrid(u, u, indexing="ij")
    U, V = U.ravel(), V.ravel()
    one = np.ones_like(U)
    faces = [np.stack(p, axis=1) for p in ((one, U, V), (-one, U, V), (U, one, V), (U, -one, V),
                                           (U, V, one), (U, V, -one))]
    pts = np.unique(np.concatenate(faces), axis=0) * sh[:3]
    return pts / (G_np(pts, sh) + 1.0)[:, None]


# ----------------------------------------------------------------------------------------------------
# broad-phase helpers (§11)
# ----------------------------------------------------------------------------------------------------
def bounding_radius(sh, exact=False):
    """Bounding-sphere radius about the shape centre. Default: the box corner sqrt(a^2+b^2+c^2), always
    conservative for 0 < eps <= 2. exact=True: the largest |xi| on the surface (max(a,b,c) for an
    ellipsoid; numerically, by a dense sample refined with the radial projection, +1e-9 margin)."""
    a, b, c, e1, e2 = sh
    if not exact:
        return float(math.sqrt(a * a + b * b + c * c))
    if e1 == 1.0 and e2 == 1.0:
        return float(max(a, b, c))
    pts = sample_surface(sh, 60)
    return float(np.max(np.linalg.norm(pts, axis=1))) * (1 + 1e-3)


def aabb_half_extents(sh, A, exact=True):
    """World AABB half-extents of the shape with rotation A. exact=True: e_k = h(A^T e_k) (support value
    along each world axis, tight); exact=False: the oriented-box bound |A| (a, b, c) (§11)."""
    A = np.asarray(A, float)
    if not exact:
        return np.abs(A) @ sh[:3]
    return np.array([support_value_local(A[k, 0], A[k, 1], A[k, 2], sh) for k in range(3)])


# ----------------------------------------------------------------------------------------------------
# broad-phase stages (§11): spheres_overlap |c1 - c2|^2 <= (R1 + R2)^2 (NOT R1^2 + R2^2), aabb_overlap
# |c1_k - c2_k| <= e1_k + e2_k; filter_pairs runs them and obb_overlap and counts what each removed
# ----------------------------------------------------------------------------------------------------
@njit(cache=True)
def spheres_overlap(c1, R1, c2, R2):
    """True if the spheres (c1, R1), (c2, R2) touch or overlap: |c1 - c2|^2 <= (R1 + R2)^2."""
    d0 = c1[0] - c2[0]
    d1 = c1[1] - c2[1]
    d2 = c1[2] - c2[2]
    s = R1 + R2
    return d0 * d0 + d1 * d1 + d2 * d2 <= s * s


@njit(cache=True)
def aabb_overlap(c1, e1, c2, e2):
    """True if the AABBs [c1 - e1, c1 + e1] and [c2 - e2, c2 + e2] overlap (touching counts)."""
    for k in range(3):
        if abs(c1[k] - c2[k]) > e1[k] + e2[k]:
            return False
    return True


def filter_pairs(centres, rotations, shapes, pairs=None, use_aabb=True):
    """Broad phase over N superellipsoids (global centres (N,3), rotations (N,3,3), shapes (N,5)).

    pairs: iterable of (i, j) candidates (default: all i < j). Returns (surviving pairs list,
    counts dict with 'candidates', 'sphere', 'aabb', 'obb' = pairs removed by each stage, 'remaining').
    """
    centres = np.asarray(centres, float)
    rotations = np.asarray(rotations, float)
    shapes = np.asarray(shapes, float)
    n = len(centres)
    if pairs is None:
        pairs = [(i, j) for i in range(n) for j in range(i + 1, n)]
    pairs = list(pairs)
    R = np.array([bounding_radius(s) for s in shapes])
    E = np.array([aabb_half_extents(s, A) for s, A in zip(shapes, rotations)]) if use_aabb else None
    counts = {"candidates": len(pairs), "sphere": 0, "aabb": 0, "obb": 0, "remaining": 0}
    out = []
    for i, j in pairs:
        if not spheres_overlap(centres[i], R[i], centres[j], R[j]):
            counts["sphere"] += 1
            continue
        if use_aabb and not aabb_overlap(centres[i], E[i], centres[j], E[j]):
            counts["aabb"] += 1
            continue
        if not obb_overlap(centres[i], rotations[i], shapes[i, :3], centres[j], rotations[j], shapes[j, :3]):
            counts["obb"] += 1
            continue
        out.append((i, j))
    counts["remaining"] = len(out)
    return out, counts


def nose_barrier_crush(energy, B, a, b, p=4.0, width=None):
    """Deepest crush C of a superellipse nose (plan |x/a|^p + |y/b|^p = 1, half width b) face-on against a rigid
    barrier that absorbs `energy` [J] with CRASH3's stiffness B [N/m^2] over the crush profile (docs/physics.md §13a
    "Engaged width"): each line y across the nose crushes C - s(y), s(y) = a (1 - (1 - |y/b|^p)^(1/p)) its setback,
    so energy = B/2 * integral over y of (C - s(y))+^2 (times width / 2b where the structure is narrower); dense
    trapezoidal rule in y, bisection in C. The flat face (s = 0) gives sqrt(2 energy / (2 b B))."""
    y = np.linspace(-b, b, 200_001)
    s = a * (1.0 - (1.0 - np.abs(y / b) ** p) ** (1.0 / p))
    scale = 1.0 if width is None else min(1.0, width / (2.0 * b))
    lo, hi = 0.0, a
    for _ in range(60):
        c = 0.5 * (lo + hi)
        e = 0.5 * B * scale * np.trapezoid(np.maximum(c - s, 0.0) ** 2, y)
        lo, hi = (c, hi) if e < energy else (lo, c)
    return 0.5 * (lo + hi)
