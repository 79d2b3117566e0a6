"""Superellipsoid geometry (docs/physics.md §10): the chassis contact body of the 3D models, through its
closed-form support mapping (what the vehicle contacts need).

A shape is the float64 array ``sh = [a, b, c, eps1, eps2]`` (semi-axes in m, shape exponents; eps1 the
profile along z, eps2 the xy cross-section). Convex for 0 < eps <= 2. Local (shape) coordinates xi; a pose
is (r, A): centre and rotation matrix (columns = local axes in the global frame), so x = r + A xi.

Scalar kernels, numba ``@njit(cache=True)`` on 3-tuples (no allocation): support_local,
support_value_local, support_global, support_value_global, mat_vec, mat_t_vec. The implicit function,
normals and numpy helpers that only the tests use are in tests/geometry_3d.py.
"""
from numba import njit


# ----------------------------------------------------------------------------------------------------
# scalar kernels (local coordinates)
# ----------------------------------------------------------------------------------------------------
@njit(cache=True)
def support_local(dx, dy, dz, sh):
    """Support mapping sigma(d) of §10 (Hölder duality): the surface point maximising d . xi. d need not
    be unit. Valid for 0 < eps < 2."""
    a, b, c, e1, e2 = sh[0], sh[1], sh[2], sh[3], sh[4]
    ux, uy, uz = a * dx, b * dy, c * dz
    m = max(abs(ux), max(abs(uy), abs(uz)))
    if m == 0.0:
        return (0.0, 0.0, c)
    ux /= m
    uy /= m
    uz /= m
    ps = 2.0 / (2.0 - e2)
    qs = 2.0 / (2.0 - e1)
    s = (abs(ux) ** ps + abs(uy) ** ps) ** (1.0 / ps)
    t = (s ** qs + abs(uz) ** qs) ** (1.0 / qs)
    rho = (s / t) ** (qs - 1.0)
    zeta = (abs(uz) / t) ** (qs - 1.0)
    if s > 0.0:
        X = rho * (abs(ux) / s) ** (ps - 1.0)
        Y = rho * (abs(uy) / s) ** (ps - 1.0)
    else:
        X = 0.0
        Y = 0.0
    if ux < 0.0:
        X = -X
    elif ux == 0.0:
        X = 0.0
    if uy < 0.0:
        Y = -Y
    elif uy == 0.0:
        Y = 0.0
    if uz < 0.0:
        zeta = -zeta
    elif uz == 0.0:
        zeta = 0.0
    return (a * X, b * Y, c * zeta)


@njit(cache=True)
def support_value_local(dx, dy, dz, sh):
    """h(d) = max over the shape of d . xi (= t of §10 for the unnormalised u)."""
    a, b, c, e1, e2 = sh[0], sh[1], sh[2], sh[3], sh[4]
    ux, uy, uz = abs(a * dx), abs(b * dy), abs(c * dz)
    m = max(ux, max(uy, uz))
    if m == 0.0:
        return 0.0
    ps = 2.0 / (2.0 - e2)
    qs = 2.0 / (2.0 - e1)
    s = ((ux / m) ** ps + (uy / m) ** ps) ** (1.0 / ps)
    return m * (s ** qs + (uz / m) ** qs) ** (1.0 / qs)


# ----------------------------------------------------------------------------------------------------
# global-frame kernels (pose r (3,), A (3,3): x = r + A xi)
# ----------------------------------------------------------------------------------------------------
@njit(cache=True, inline="always")
def mat_vec(A, x0, x1, x2):
    """A x for a 3x3 A and x given by components."""
    return (A[0, 0] * x0 + A[0, 1] * x1 + A[0, 2] * x2,
            A[1, 0] * x0 + A[1, 1] * x1 + A[1, 2] * x2,
            A[2, 0] * x0 + A[2, 1] * x1 + A[2, 2] * x2)


@njit(cache=True, inline="always")
def mat_t_vec(A, x0, x1, x2):
    """A^T x for a 3x3 A and x given by components."""
    return (A[0, 0] * x0 + A[1, 0] * x1 + A[2, 0] * x2,
            A[0, 1] * x0 + A[1, 1] * x1 + A[2, 1] * x2,
            A[0, 2] * x0 + A[1, 2] * x1 + A[2, 2] * x2)


@njit(cache=True)
def support_global(d0, d1, d2, sh, r, A):
    """Global support point r + A sigma(A^T d)."""
    l = mat_t_vec(A, d0, d1, d2)
    s = support_local(l[0], l[1], l[2], sh)
    g = mat_vec(A, s[0], s[1], s[2])
    return (r[0] + g[0], r[1] + g[1], r[2] + g[2])


@njit(cache=True)
def support_value_global(d0, d1, d2, sh, r, A):
    """Global support value d . r + h(A^T d)."""
    l = mat_t_vec(A, d0, d1, d2)
    return d0 * r[0] + d1 * r[1] + d2 * r[2] + support_value_local(l[0], l[1], l[2], sh)
