"""Broad phase for superellipsoid contact (docs/physics.md §11): bounding spheres -> AABB -> OBB 15-axis SAT.

* spheres_overlap: |c1 - c2|^2 <= (R1 + R2)^2 — NOT R1^2 + R2^2 (the non-conservative bug of
  artur-ag/fcl SuperOvoid.cpp, §11).
* aabb_overlap: |c1_k - c2_k| <= e1_k + e2_k for k = 1..3.
* obb_overlap: Gottschalk's 15-axis separating-axis test (PQP obb_disjoint) in A's frame with
  |R|_ij + eps (eps = 1e-6) against near-parallel edge pairs. A superellipsoid (0 < eps <= 2) lies
  inside its a x b x c box, so the box test is conservative.
* filter_pairs: runs the three stages over candidate pairs and reports how many each stage removed.
"""
import numpy as np
from numba import njit

from .superellipsoid import aabb_half_extents, bounding_radius


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
