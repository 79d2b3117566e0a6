"""Superellipsoid geometry, broad phase and narrow phase (docs/physics.md §10, §11, §12): the models' support
mapping and oriented-box test, and the test tools geometry_3d.py and narrow_phase_3d.py.

Brute-force references used here:
* signed gap (separated AND penetrating): the separating-axis value g(d) = -(h1(d) + h2(-d)) maximised
  over directions by exhaustive search — 20,000 Fibonacci directions (mean spacing ~0.025 rad), then the
  5 best refined by 12 levels of 9 x 9 tangent-plane grids shrinking x0.4 (final spacing ~3e-7 rad).
  h is the closed-form support function of §3.4, itself checked against dense surface samples below.
  max_d g(d) is the signed gap of two convex bodies (distance if > 0, minus the minimum translational
  penetration depth if < 0). Its sampling error is one-sided (it can only under-estimate).
* distance of separated pairs, fully sample-based: nearest pair of surface samples (80 x 80 grid per cube
  face, radially projected) via a KD-tree, then re-sampled at 0.002 (cube-parameter units, i.e. <= 4 mm
  on a 2 m semi-axis) in a window of 3 coarse spacings around the best pair. Over-estimates only.
"""
import math

import geometry_3d as se
import numpy as np
import pytest
from geometry_3d import aabb_overlap, filter_pairs, spheres_overlap
from narrow_phase_3d import _fibonacci, gap_function, signed_gap
from scipy.optimize import linprog
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from crashlab.models.common.broad_phase import obb_overlap


def random_shape(rng, emin=0.3, emax=1.0):
    return np.r_[rng.uniform(0.2, 2.0, 3), rng.uniform(emin, emax, 2)]


def random_pair(rng):
    sh1, sh2 = random_shape(rng), random_shape(rng)
    A1 = Rotation.random(random_state=rng).as_matrix()
    A2 = Rotation.random(random_state=rng).as_matrix()
    r1 = rng.uniform(-1, 1, 3)
    u = rng.normal(size=3)
    u /= np.linalg.norm(u)
    touch = se.support_value_local(*(u @ A1), sh1) + se.support_value_local(*(-u @ A2), sh2)
    r2 = r1 + u * touch * rng.uniform(0.6, 1.3)  # some separated, some penetrating (some deeply)
    return sh1, r1, A1, sh2, r2, A2


D0 = _fibonacci(20000)
_u = np.linspace(-1, 1, 9)
_U, _V = (m.ravel() for m in np.meshgrid(_u, _u))


def brute_gap(p):
    g = gap_function(D0, *p)
    best = -np.inf
    for k in np.argsort(g)[-5:]:
        d, w = D0[k], 0.03
        for _ in range(12):
            a = np.array([1.0, 0, 0]) if abs(d[0]) < 0.9 else np.array([0, 1.0, 0])
            t = np.cross(d, a)
            t /= np.linalg.norm(t)
            b = np.cross(d, t)
            cand = d + w * (_U[:, None] * t + _V[:, None] * b)
            cand /= np.linalg.norm(cand, axis=1, keepdims=True)
            gg = gap_function(cand, *p)
            j = np.argmax(gg)
            d, w = cand[j], w * 0.4
        best = max(best, gg[j])
    return best


def _patch(sh, xi, w, h):
    """Surface samples: cube-surface points (spacing h) within L-inf distance w of xi's cube point,
    projected radially."""
    u = xi / sh[:3]
    c = u / np.abs(u).max()
    out = []
    for k in range(3):
        for s in (-1.0, 1.0):
            if abs(s - c[k]) > w:
                continue
            o = [i for i in range(3) if i != k]
            g = [np.arange(max(-1, c[i] - w), min(1, c[i] + w) + h / 2, h) for i in o]
            G0, G1 = np.meshgrid(*g, indexing="ij")
            P = np.empty((G0.size, 3))
            P[:, k], P[:, o[0]], P[:, o[1]] = s, G0.ravel(), G1.ravel()
            out.append(P)
    P = np.concatenate(out) * sh[:3]
    return P / (se.G_np(P, sh) + 1)[:, None]


def sampled_distance(p, n_coarse=80, h_fine=0.002):
    sh1, r1, A1, sh2, r2, A2 = p
    L1, L2 = se.sample_surface(sh1, n_coarse), se.sample_surface(sh2, n_coarse)
    d, j = cKDTree(se.to_global(L2, r2, A2)).query(se.to_global(L1, r1, A1))
    i = int(np.argmin(d))
    w = 3 * 2 / (n_coarse - 1)
    F1 = se.to_global(_patch(sh1, L1[i], w, h_fine), r1, A1)
    F2 = se.to_global(_patch(sh2, L2[j[i]], w, h_fine), r2, A2)
    return cKDTree(F2).query(F1)[0].min()


# ----------------------------------------------------------------------------------------------------
# superellipsoid
# ----------------------------------------------------------------------------------------------------
def test_support_point_on_surface_normal_parallel_and_beats_samples():
    rng = np.random.default_rng(0)
    for _ in range(300):
        sh = random_shape(rng, 0.2, 1.0) if rng.random() < 0.8 else random_shape(rng, 1.0, 1.8)
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        s = np.array(se.support_local(*d, sh))
        assert abs(se.F_local(*s, sh)) < 1e-9
        n = np.array(se.normal_local(*s, sh))
        assert n @ d > 1 - 1e-9
        assert abs(se.support_value_local(*d, sh) - d @ s) < 1e-12
    for _ in range(20):
        sh = random_shape(rng, 0.3, 1.0)
        pts = se.sample_surface(sh, 60)
        for d in rng.normal(size=(10, 3)):
            d /= np.linalg.norm(d)
            assert se.support_value_local(*d, sh) >= (pts @ d).max() - 1e-12


def test_F_G_normal_consistency():
    rng = np.random.default_rng(1)
    for _ in range(200):
        sh = random_shape(rng, 0.2, 1.0)
        xi = rng.normal(size=3) * sh[:3]
        F, G = se.F_local(*xi, sh), se.G_local(*xi, sh)
        assert np.sign(F) == np.sign(G)
        lam = rng.uniform(0.2, 5)
        assert abs(se.G_local(*(lam * xi), sh) + 1 - lam * (G + 1)) < 1e-9 * lam
        # normal = normalised finite-difference gradient of G
        h = 1e-6
        fd = np.array([(se.G_local(*(xi + h * e), sh) - se.G_local(*(xi - h * e), sh)) / (2 * h)
                       for e in np.eye(3)])
        assert np.allclose(np.array(se.grad_G_local(*xi, sh)), fd, atol=1e-5 * np.abs(fd).max())
        assert np.allclose(se.normal_local(*xi, sh), se.normal_np(xi, sh)[0], atol=1e-12)
        assert abs(se.G_np(xi, sh)[0] - G) < 1e-12
        p = np.array(se.radial_project(*xi, sh))
        assert abs(se.G_local(*p, sh)) < 1e-12
    # G does not overflow where F does (small eps, far away)
    sh = se.shape(1, 1, 1, 0.05, 0.05)
    assert np.isinf(se.F_np(np.array([[1e9, 0, 0]]), sh)[0]) and abs(se.G_local(1e9, 0, 0, sh) / (1e9 - 1) - 1) < 1e-12


def test_normal_special_case_on_z_axis():
    sh = se.shape(1.0, 0.5, 0.8, 0.3, 0.9)  # eps2 > eps1: s^(e2/e1 - 1) * |X|^... = inf * 0 naively
    for z in (0.8, -0.8, 0.3):
        n = se.normal_local(0.0, 0.0, z, sh)
        assert n == (0.0, 0.0, math.copysign(1.0, z))
        assert se.grad_F_local(0.0, 0.0, z, sh)[:2] == (0.0, 0.0)
    assert np.all(np.isfinite(se.normal_np(np.array([[0, 0, 0.8], [1e-13, 0, 0.8]]), sh)))


def test_transforms_and_aabb():
    rng = np.random.default_rng(2)
    for _ in range(20):
        sh = random_shape(rng)
        A = Rotation.random(random_state=rng).as_matrix()
        r = rng.normal(size=3)
        xi = rng.normal(size=(5, 3))
        assert np.allclose(se.to_local(se.to_global(xi, r, A), r, A), xi)
        Ab = Rotation.random(random_state=rng).as_matrix()
        sc = rng.normal(size=3)
        rs, As = se.shape_pose(r, Ab, sc, A)
        assert np.allclose(se.to_global(xi, rs, As), r + (sc + xi @ A.T) @ Ab.T)
        pts = se.to_global(se.sample_surface(sh, 40), r, A) - r
        e = se.aabb_half_extents(sh, A)
        assert np.all(np.abs(pts).max(axis=0) <= e + 1e-12)
        assert np.all(np.abs(pts).max(axis=0) >= e - 0.02 * sh[:3].max())  # tight
        assert np.all(se.aabb_half_extents(sh, A, exact=False) >= e - 1e-12)
        R = se.bounding_radius(sh)
        assert np.linalg.norm(pts, axis=1).max() <= R
    assert se.bounding_radius(se.shape(1, 2, 0.5, 1, 1), exact=True) == 2.0


# ----------------------------------------------------------------------------------------------------
# broad phase
# ----------------------------------------------------------------------------------------------------
def test_sphere_test_uses_sum_of_radii():
    c1, c2 = np.zeros(3), np.array([2.9, 0, 0])
    assert spheres_overlap(c1, 1.5, c2, 1.5)  # |d|^2 = 8.41 > R1^2 + R2^2 = 4.5: the buggy test misses it
    assert not spheres_overlap(c1, 1.4, c2, 1.4)
    assert aabb_overlap(c1, np.ones(3), c2, np.array([1.9, 1, 1]))
    assert not aabb_overlap(c1, np.ones(3), c2, np.array([1.8, 1, 1]))


def _box_touch_scale(cA, RA, a, cB, RB, b):
    """Exact LP: the smallest s such that the boxes scaled by s about their centres intersect
    (cA + RA u = cB + RB w, |u_i| <= s a_i, |w_j| <= s b_j). They overlap iff s <= 1."""
    # variables u (3), w (3), s
    A_eq = np.hstack([RA, -RB, np.zeros((3, 1))])
    A_ub = []
    for i in range(3):
        for sgn in (1, -1):
            row = np.zeros(7)
            row[i], row[6] = sgn, -a[i]
            A_ub.append(row)
            row = np.zeros(7)
            row[3 + i], row[6] = sgn, -b[i]
            A_ub.append(row)
    res = linprog(np.r_[np.zeros(6), 1.0], A_ub=np.array(A_ub), b_ub=np.zeros(12), A_eq=A_eq, b_eq=cB - cA,
                  bounds=[(None, None)] * 6 + [(0, None)], method="highs")
    assert res.status == 0
    return res.x[6]


def test_obb_sat_matches_exact_lp_on_1000_pairs():
    rng = np.random.default_rng(3)
    mismatches = grazing = overlaps = 0
    for k in range(1000):
        a, b = rng.uniform(0.1, 2.0, 3), rng.uniform(0.1, 2.0, 3)
        RA = Rotation.random(random_state=rng).as_matrix()
        if k % 5 == 0:  # nearly parallel edges: the eps case
            RB = RA @ Rotation.from_rotvec(rng.normal(size=3) * 1e-7).as_matrix()
        else:
            RB = Rotation.random(random_state=rng).as_matrix()
        cA = rng.normal(size=3)
        cB = cA + rng.normal(size=3) * rng.uniform(0.5, 3.0)
        s = _box_touch_scale(cA, RA, a, cB, RB, b)
        sat = obb_overlap(cA, RA, a, cB, RB, b)
        if abs(s - 1) < 1e-5:
            grazing += 1
            continue
        overlaps += s < 1
        mismatches += sat != (s < 1)
    print(f"OBB SAT vs LP: {mismatches} mismatches, {grazing} grazing skipped, {overlaps} overlapping")
    assert mismatches == 0
    assert 200 < overlaps < 800


def test_filter_pairs_counts():
    rng = np.random.default_rng(4)
    n = 30
    centres = rng.uniform(-6, 6, (n, 3))
    rots = Rotation.random(n, random_state=rng).as_matrix()
    shapes = np.array([random_shape(rng) for _ in range(n)])
    out, counts = filter_pairs(centres, rots, shapes)
    assert counts["candidates"] == n * (n - 1) // 2
    assert counts["sphere"] + counts["aabb"] + counts["obb"] + counts["remaining"] == counts["candidates"]
    assert counts["sphere"] > 0 and counts["remaining"] == len(out)
    # conservative: no pair in contact (narrow phase) is removed
    for i in range(n):
        for j in range(i + 1, n):
            g = signed_gap(shapes[i], centres[i], rots[i], shapes[j], centres[j], rots[j])[0]
            if g <= 0:
                assert (i, j) in out


# ----------------------------------------------------------------------------------------------------
# narrow phase
# ----------------------------------------------------------------------------------------------------
def _check_narrow(n_pairs, seed):
    rng = np.random.default_rng(seed)
    errs, pen, methods = [], 0, {}
    for _ in range(n_pairs):
        p = random_pair(rng)
        info = {}
        gap, n, P1, P2, conv = signed_gap(*p, info=info)
        methods[info["method"]] = methods.get(info["method"], 0) + 1
        assert conv
        assert np.all(np.isfinite(np.r_[gap, n, P1, P2]))
        sh1, r1, A1, sh2, r2, A2 = p
        assert abs(se.G_global(*P1, sh1, r1, A1)) < 1e-9 and abs(se.G_global(*P2, sh2, r2, A2)) < 1e-9
        assert abs(np.linalg.norm(P2 - P1) - abs(gap)) < 1e-12 and abs(np.linalg.norm(n) - 1) < 1e-12
        errs.append(gap - brute_gap(p))
        pen += gap < 0
    errs = np.array(errs)
    print(f"narrow phase vs direction brute force on {n_pairs} pairs ({pen} penetrating): "
          f"max |err| {np.abs(errs).max():.2e} m, methods {methods}")
    assert np.abs(errs).max() < 1e-3
    assert 0.2 * n_pairs < pen < 0.8 * n_pairs


def test_narrow_phase_vs_brute_force_100():
    _check_narrow(100, 5)


@pytest.mark.slow
def test_narrow_phase_vs_brute_force_1000():
    _check_narrow(1000, 6)


def _check_sampled(n_sep, seed):
    rng = np.random.default_rng(seed)
    errs = []
    while len(errs) < n_sep:
        p = random_pair(rng)
        gap = signed_gap(*p)[0]
        if gap > 0:
            errs.append(sampled_distance(p) - gap)
    errs = np.array(errs)
    print(f"distance vs sampled surfaces on {n_sep} separated pairs: err in [{errs.min():.2e}, {errs.max():.2e}] m")
    assert errs.min() > -1e-9  # samples can only over-estimate the distance
    assert errs.max() < 1e-3


def test_distance_vs_surface_samples():
    _check_sampled(6, 7)


@pytest.mark.slow
def test_distance_vs_surface_samples_100():
    _check_sampled(100, 8)


def test_slsqp_fallback_and_warm_start():
    rng = np.random.default_rng(9)
    for _ in range(10):
        p = random_pair(rng)
        info = {}
        gap, n, P1, P2, conv = signed_gap(*p, method="slsqp", info=info)
        assert conv and info["method"] == "slsqp"
        assert abs(gap - brute_gap(p)) < 1e-3
        # warm start after a small motion of body 2
        sh1, r1, A1, sh2, r2, A2 = p
        r2b = r2 + 1e-3 * rng.normal(size=3)
        A2b = A2 @ Rotation.from_rotvec(1e-3 * rng.normal(size=3)).as_matrix()
        info2 = {}
        g2 = signed_gap(sh1, r1, A1, sh2, r2b, A2b, warm=info["warm"], info=info2)
        g3 = signed_gap(sh1, r1, A1, sh2, r2b, A2b)
        assert info2["method"] == "newton-warm" and abs(g2[0] - g3[0]) < 1e-9


def test_spheres_and_aligned_boxes_exact():
    s1, s2 = se.shape(0.5, 0.5, 0.5, 1, 1), se.shape(0.3, 0.3, 0.3, 1, 1)
    I = np.eye(3)
    for dist in (1.0, 0.8, 0.6, 0.2):
        c2 = np.array([dist, 0.2 * dist, -0.1]) / np.linalg.norm([dist, 0.2 * dist, -0.1]) * dist
        gap, n, P1, P2, conv = signed_gap(s1, np.zeros(3), I, s2, c2, I)
        assert conv and abs(gap - (dist - 0.8)) < 1e-10 and np.allclose(n, c2 / dist)
    b1, b2 = se.shape(1, 1, 0.5, 0.3, 0.3), se.shape(0.5, 0.5, 0.5, 0.3, 0.3)
    for dz in (1.2, 0.9):  # face-to-face (flat faces: zero curvature at the face centre)
        gap, n, *_ = signed_gap(b1, np.zeros(3), I, b2, np.array([0.1, -0.05, dz]), I)
        assert abs(gap - (dz - 1.0)) < 1e-6 and n[2] > 0.999


def test_rect_corners_into_is_rect_corners_written_in_place():
    """rect_corners_into(out, x, y, cos h, sin h, ...) writes exactly rect_corners(x, y, h, ...) into `out`
    (every entry) and returns `out` itself; both are the rectangle front/rear along the heading and
    half_width to each side, counter-clockwise (checked against the rotation written out here)."""
    from crashlab.geometry import rect_corners, rect_corners_into
    rng = np.random.default_rng(9)
    for x, y, h, front, rear, half in zip(rng.uniform(-50, 50, 300), rng.uniform(-50, 50, 300),
                                          rng.uniform(-4, 4, 300), rng.uniform(0.5, 3, 300),
                                          rng.uniform(0.5, 3, 300), rng.uniform(0.3, 1.2, 300)):
        out = np.full((4, 2), np.nan)
        got = rect_corners_into(out, x, y, math.cos(h), math.sin(h), front, rear, half)
        assert got is out
        assert np.array_equal(out, rect_corners(x, y, h, front, rear, half))
        local = np.array([(front, -half), (front, half), (-rear, half), (-rear, -half)])
        rot = np.array([[math.cos(h), -math.sin(h)], [math.sin(h), math.cos(h)]])
        np.testing.assert_allclose(out, (x, y) + local @ rot.T, rtol=0, atol=1e-12)
        e = np.roll(out, -1, axis=0) - out
        area = 0.5 * np.sum(out[:, 0] * np.roll(out[:, 1], -1) - np.roll(out[:, 0], -1) * out[:, 1])
        assert area == pytest.approx((front + rear) * 2 * half, rel=1e-12)  # positive: counter-clockwise
        assert np.hypot(*e.T) == pytest.approx([2 * half, front + rear, 2 * half, front + rear], rel=1e-12)
