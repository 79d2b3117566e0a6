"""Feasibility repair of reconstruction candidates (a pymoo Repair over a ReconstructionProblem).

The thesis re-drew infeasible candidates and proposed a back-off operator as future work; this is it:
  1. vehicles that overlap at the start: the vehicle whose position is free is moved back along its
     heading until the outlines are apart (1 cm clearance);
  2. a candidate that misses: with straight-line motion at the start speeds, the pose of least
     separation is found; when moving the free vehicle sideways by at most `max_shift` (in all) brings
     the outlines into contact there, it is moved, and steps 1-2 are repeated (a shift along one
     separating axis may leave another). Step 1 always comes last.
Variables stay within their bounds; what cannot be repaired is left to the constraints.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit
from pymoo.core.repair import Repair

from crashlab.geometry import rect_corners

from .problem import outline_depth

CLEARANCE = 0.01  # m


@njit(cache=True)
def _least_separation(poses, dims, i, j, t_max, dt):
    """Straight-line motion at constant speed: (max depth over time, its axis, its time)."""
    best, bx, by, bt = -1e300, 0.0, 0.0, 0.0
    moved = poses.copy()
    n = int(t_max / dt) + 1
    for k in range(n):
        t = k * dt
        for q in (i, j):
            moved[q, 0] = poses[q, 0] + poses[q, 3] * math.cos(poses[q, 2]) * t
            moved[q, 1] = poses[q, 1] + poses[q, 3] * math.sin(poses[q, 2]) * t
        d, nx, ny, _ = outline_depth(moved, dims, i, j)
        if d > best:
            best, bx, by, bt = d, nx, ny, t
        if d > 0.0:
            break
    return best, bx, by, bt


@njit(cache=True)
def repair_poses(poses, dims, movable, max_shift, t_max):
    """Repair start poses in place. poses (n, nv, 4): x, y, heading [rad], speed [m/s];
    dims (nv, 3): front, rear, half width; movable (nv,) bool: position is a free variable.
    Returns per candidate 0 (untouched), 1 (repaired) ."""
    n, nv = poses.shape[0], poses.shape[1]
    changed = np.zeros(n, np.int64)
    for c in range(n):
        P = poses[c]
        for i in range(nv):
            for j in range(i + 1, nv):
                mover = i if movable[i] else (j if movable[j] else -1)
                if mover < 0:
                    continue
                shifted = 0.0  # the sideways moves of step 2 add up to at most max_shift
                for _ in range(6):  # a shift along one axis may leave another separating: repeat
                    # 1. back off along the heading until apart
                    if _back_off(P, dims, i, j, mover):
                        changed[c] = 1
                    # 2. a near miss is brought onto a collision course; when the least separation is
                    #    at the start (the outlines only move apart) a shift would only make them overlap
                    best, nx, ny, t = _least_separation(P, dims, i, j, t_max, 0.01)
                    if best > 0.0 or -best > max_shift - shifted or t <= 0.0:
                        break
                    s = -best + 0.05
                    shifted += s
                    sign = 1.0 if mover == i else -1.0  # move i towards j (along n) or j towards i
                    P[mover, 0] += sign * s * nx
                    P[mover, 1] += sign * s * ny
                    changed[c] = 1
                # the last shift must not leave the outlines overlapping at the start
                if _back_off(P, dims, i, j, mover):
                    changed[c] = 1
    return changed


@njit(cache=True)
def _back_off(P, dims, i, j, mover):
    """Move `mover` back along its heading until the outlines of i and j are apart (1 cm clearance);
    True if moved. The overlapping back-off distances form an interval starting at 0 (a line through the
    convex Minkowski difference), so bisection between 0 and a distance that clears the outlines along
    the heading finds its end, however the outlines are turned."""
    if outline_depth(P, dims, i, j)[0] <= 0.0:
        return False
    other = j if mover == i else i
    hx, hy = math.cos(P[mover, 2]), math.sin(P[mover, 2])
    cm = rect_corners(P[mover, 0], P[mover, 1], P[mover, 2], dims[mover, 0], dims[mover, 1], dims[mover, 2])
    co = rect_corners(P[other, 0], P[other, 1], P[other, 2], dims[other, 0], dims[other, 1], dims[other, 2])
    hi_m, lo_o = -1e300, 1e300
    for k in range(4):
        hi_m = max(hi_m, cm[k, 0] * hx + cm[k, 1] * hy)
        lo_o = min(lo_o, co[k, 0] * hx + co[k, 1] * hy)
    x0, y0 = P[mover, 0], P[mover, 1]
    lo, hi = 0.0, max(hi_m - lo_o, 0.0) + CLEARANCE  # overlapping at lo, apart at hi
    for _it in range(50):
        mid = 0.5 * (lo + hi)
        P[mover, 0], P[mover, 1] = x0 - mid * hx, y0 - mid * hy
        if outline_depth(P, dims, i, j)[0] > 0.0:
            lo = mid
        else:
            hi = mid
    s = min(hi + CLEARANCE, max(hi_m - lo_o, 0.0) + CLEARANCE)
    P[mover, 0], P[mover, 1] = x0 - s * hx, y0 - s * hy
    return True


class CollisionRepair(Repair):
    """pymoo Repair over a ReconstructionProblem (it provides start poses and their inverse)."""

    def __init__(self, max_shift: float = 1.0, horizon: float = 4.0):
        super().__init__()
        self.max_shift, self.horizon = max_shift, horizon
        self.repaired = 0
        self.seen = 0

    def _do(self, problem, X, **kwargs):
        return self.apply(problem, X)

    def apply(self, problem, X) -> np.ndarray:
        """Repaired copy of the candidates X (n, n_var) of a ReconstructionProblem."""
        X = np.array(X, dtype=float, copy=True)
        poses = problem.start_poses(X)
        changed = repair_poses(poses, problem.outline_dims, problem.movable, self.max_shift, self.horizon)
        self.repaired += int(changed.sum())
        self.seen += len(X)
        return problem.with_positions(X, poses)
