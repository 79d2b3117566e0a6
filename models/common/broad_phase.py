"""Broad phase of the vehicle contacts (docs/physics.md §11): the oriented-box test. The cheaper gates (plan
bounding circles, height ranges) are in chassis_contact.contacts; the bounding-sphere and AABB stages and
`filter_pairs` are test tools (tests/geometry_3d.py).

* obb_overlap: Gottschalk's 15-axis separating-axis test (PQP obb_disjoint) in A's frame with
  |R|_ij + eps (eps = 1e-6) against near-parallel edge pairs. A superellipsoid (0 < eps <= 2) lies
  inside its a x b x c box, so the box test is conservative.
"""
import numpy as np
from numba import njit


@njit(cache=True)
def obb_overlap(cA, RA, a, cB, RB, b, eps=1e-6):
    """15-axis SAT (§11). RA, RB: columns are the box axes (world); a, b: half-extents.
    Returns True if the boxes overlap (no separating axis found), False if disjoint."""
    R = np.empty((3, 3))
    AR = np.empty((3, 3))
    t = np.empty(3)
    for i in range(3):
        t[i] = RA[0, i] * (cB[0] - cA[0]) + RA[1, i] * (cB[1] - cA[1]) + RA[2, i] * (cB[2] - cA[2])
        for j in range(3):
            R[i, j] = RA[0, i] * RB[0, j] + RA[1, i] * RB[1, j] + RA[2, i] * RB[2, j]
            AR[i, j] = abs(R[i, j]) + eps
    # A's face axes
    for i in range(3):
        if abs(t[i]) > a[i] + b[0] * AR[i, 0] + b[1] * AR[i, 1] + b[2] * AR[i, 2]:
            return False
    # B's face axes
    for j in range(3):
        if abs(t[0] * R[0, j] + t[1] * R[1, j] + t[2] * R[2, j]) > \
                a[0] * AR[0, j] + a[1] * AR[1, j] + a[2] * AR[2, j] + b[j]:
            return False
    # edge-edge axes A_i x B_j
    for i in range(3):
        i1 = (i + 1) % 3
        i2 = (i + 2) % 3
        for j in range(3):
            j1 = (j + 1) % 3
            j2 = (j + 2) % 3
            lhs = abs(t[i2] * R[i1, j] - t[i1] * R[i2, j])
            rhs = a[i1] * AR[i2, j] + a[i2] * AR[i1, j] + b[j1] * AR[i, j2] + b[j2] * AR[i, j1]
            if lhs > rhs:
                return False
    return True
