"""Rotations of the 3D models: Euler parameters (Nikravesh 1988; docs/physics.md §6) and compiled vector
helpers on 3-tuples.

p = [e0, e1, e2, e3], A(p) the rotation matrix (body -> global), p_dot = 1/2 L(p)^T w' with w' the
body-fixed angular velocity. Vectors are tuples so that numba keeps them in registers (no allocation).
`rotation_entries` is the one home of A(p) (numba, a 9-tuple); `rotation_matrix_into`, `rotation_into`
(a body of a stack), `matrix` (numpy) and the multibody pose use it; `from_matrix` goes back (Shepperd);
`rot_z` is the rotation about the vertical.
"""
import math

import numpy as np
from numba import njit


@njit(cache=True, inline="always")
def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


@njit(cache=True, inline="always")
def dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@njit(cache=True, inline="always")
def add(a, b):
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


@njit(cache=True, inline="always")
def sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


@njit(cache=True, inline="always")
def scale(s, a):
    return (s * a[0], s * a[1], s * a[2])


@njit(cache=True, inline="always")
def mv(A, b, x):
    """A[b] @ x (body -> global)."""
    return (A[b, 0, 0] * x[0] + A[b, 0, 1] * x[1] + A[b, 0, 2] * x[2],
            A[b, 1, 0] * x[0] + A[b, 1, 1] * x[1] + A[b, 1, 2] * x[2],
            A[b, 2, 0] * x[0] + A[b, 2, 1] * x[1] + A[b, 2, 2] * x[2])


@njit(cache=True, inline="always")
def mtv(A, b, x):
    """A[b]^T @ x (global -> body)."""
    return (A[b, 0, 0] * x[0] + A[b, 1, 0] * x[1] + A[b, 2, 0] * x[2],
            A[b, 0, 1] * x[0] + A[b, 1, 1] * x[1] + A[b, 2, 1] * x[2],
            A[b, 0, 2] * x[0] + A[b, 1, 2] * x[1] + A[b, 2, 2] * x[2])


@njit(cache=True, inline="always")
def rotation_entries(e0, e1, e2, e3):
    """The nine entries of A(p) of §6, row by row, as a tuple (p need not be exactly unit: it is normalised
    here). The one home of the formula; tuples stay in registers."""
    n = 1.0 / (e0 * e0 + e1 * e1 + e2 * e2 + e3 * e3)
    return ((e0 * e0 + e1 * e1 - e2 * e2 - e3 * e3) * n, 2.0 * (e1 * e2 - e0 * e3) * n,
            2.0 * (e1 * e3 + e0 * e2) * n, 2.0 * (e1 * e2 + e0 * e3) * n, (e0 * e0 - e1 * e1 + e2 * e2 - e3 * e3) * n,
            2.0 * (e2 * e3 - e0 * e1) * n, 2.0 * (e1 * e3 - e0 * e2) * n, 2.0 * (e2 * e3 + e0 * e1) * n,
            (e0 * e0 - e1 * e1 - e2 * e2 + e3 * e3) * n)


@njit(cache=True, inline="always")
def rotation_matrix_into(e0, e1, e2, e3, A):
    """A(p) written into the 3x3 array A."""
    r = rotation_entries(e0, e1, e2, e3)
    for k in range(9):
        A[k // 3, k % 3] = r[k]


@njit(cache=True)
def rotation_into(e0, e1, e2, e3, A, b):
    """A(p) written into A[b] of a stack of matrices (nb, 3, 3)."""
    r = rotation_entries(e0, e1, e2, e3)
    for k in range(9):
        A[b, k // 3, k % 3] = r[k]


def matrix(p):
    """A(p) as a new numpy array."""
    A = np.empty((3, 3))
    rotation_matrix_into(float(p[0]), float(p[1]), float(p[2]), float(p[3]), A)
    return A


def rot_z(a):
    """Rotation by the angle a [rad] about the global z axis."""
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


@njit(cache=True, inline="always")
def p_dot(e0, e1, e2, e3, w):
    """p_dot = 1/2 L^T w'  (w' body-fixed angular velocity)."""
    return (-0.5 * (e1 * w[0] + e2 * w[1] + e3 * w[2]),
            0.5 * (e0 * w[0] + e2 * w[2] - e3 * w[1]),
            0.5 * (e0 * w[1] + e3 * w[0] - e1 * w[2]),
            0.5 * (e0 * w[2] + e1 * w[1] - e2 * w[0]))


def from_matrix(A):
    """Euler parameters of a rotation matrix, Shepperd's branch (largest of e0^2..e3^2; §6)."""
    tr = A[0, 0] + A[1, 1] + A[2, 2]
    cand = [tr, A[0, 0], A[1, 1], A[2, 2]]
    k = max(range(4), key=lambda i: cand[i])
    if k == 0:
        e0 = 0.5 * math.sqrt(1.0 + tr)
        e = [(A[2, 1] - A[1, 2]) / (4 * e0), (A[0, 2] - A[2, 0]) / (4 * e0), (A[1, 0] - A[0, 1]) / (4 * e0)]
        p = [e0] + e
    elif k == 1:
        e1 = 0.5 * math.sqrt(1.0 + 2 * A[0, 0] - tr)
        p = [(A[2, 1] - A[1, 2]) / (4 * e1), e1, (A[1, 0] + A[0, 1]) / (4 * e1), (A[0, 2] + A[2, 0]) / (4 * e1)]
    elif k == 2:
        e2 = 0.5 * math.sqrt(1.0 + 2 * A[1, 1] - tr)
        p = [(A[0, 2] - A[2, 0]) / (4 * e2), (A[1, 0] + A[0, 1]) / (4 * e2), e2, (A[2, 1] + A[1, 2]) / (4 * e2)]
    else:
        e3 = 0.5 * math.sqrt(1.0 + 2 * A[2, 2] - tr)
        p = [(A[1, 0] - A[0, 1]) / (4 * e3), (A[0, 2] + A[2, 0]) / (4 * e3), (A[2, 1] + A[1, 2]) / (4 * e3), e3]
    if p[0] < 0:
        p = [-c for c in p]
    return p
