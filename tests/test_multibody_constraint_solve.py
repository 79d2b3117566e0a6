"""The multibody model's numerics that exist for speed (issue 25): the block-sparse Cholesky of the Schur
matrix (models/multibody/constraint_solve.py) against a dense solve of the full saddle-point system written
here with numpy, and the warm-started horizontal gap search (common/narrow_phase.py: Brent's root of g')
against a dense scan of g(th)."""
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import crashlab
from crashlab.models.common.narrow_phase import _g, horizontal_gap
from crashlab.models.common.vehicle_3d import NB, NW, build_scene_vehicles
from crashlab.models.common.wheel_states import LOCKED, ROLLING
from crashlab.models.multibody import constraint_solve as CS
from crashlab.models.multibody.equations import MAX_JOINTS, MAX_ROWS, unpack
from crashlab.models.multibody.joints import J_I, J_J, joint_rows, vehicle_joints
from crashlab.models.multibody.model import MultibodyModel

SIDE = Path(__file__).resolve().parents[1] / "studies" / "pc_crash" / "side.toml"


@pytest.fixture(scope="module")
def vehicle_rows():
    """Constraint rows of a settled Clio placed in a scene, with random velocities (the rows' values do not
    depend on the equations being satisfied)."""
    sc = crashlab.load_scene(SIDE)
    m = MultibodyModel()
    veh = build_scene_vehicles(sc)[0]
    return m, veh, sc


def _rows(m, veh, sc, modes, rng):
    y = m.place(veh, m.settled(veh), sc.vehicles[0], np.zeros(NW), modes)
    nq = 7 * NB
    y[nq:13 * NB] += rng.normal(scale=2.0, size=6 * NB)
    JNT = vehicle_joints(veh, modes, np.zeros(NW))
    A, R, V, W = np.empty((NB, 3, 3)), np.empty((NB, 3)), np.empty((NB, 3)), np.empty((NB, 3))
    unpack(y, NB, A, R, V, W)
    D, phi, gam = np.zeros((MAX_ROWS, 12)), np.zeros(MAX_ROWS), np.zeros(MAX_ROWS)
    rowb, ispos, phit = np.zeros((MAX_ROWS, 2), np.int64), np.zeros(MAX_ROWS, np.bool_), np.zeros(MAX_ROWS)
    jst, JB = np.zeros(MAX_JOINTS + 1, np.int64), np.zeros((MAX_JOINTS, 2), np.int64)
    nj, mrow = JNT.shape[0], 0
    order = list(range(nj))[::-1]           # leaf joints first, as equations.rhs
    for q, k in enumerate(order):
        jst[q] = mrow
        JB[q] = int(JNT[k, J_I]), int(JNT[k, J_J])
        mrow = joint_rows(JNT[k], A, R, V, W, D, phi, gam, rowb, ispos, mrow, phit)
    jst[nj] = mrow
    return veh.BODY, D[:mrow], rowb[:mrow], jst, JB, nj, mrow


def _dense_D(BODY, D, rowb):
    """The constraint Jacobian as a dense (m, 6 nb) matrix and the block-diagonal mass matrix."""
    m = D.shape[0]
    Dd = np.zeros((m, 6 * NB))
    for r in range(m):
        for s in range(2):
            b = rowb[r, s]
            Dd[r, 6 * b:6 * b + 6] += D[r, 6 * s:6 * s + 6]
    Mdiag = np.concatenate([[BODY[b, 0]] * 3 + list(BODY[b, 1:4]) for b in range(NB)])
    return Dd, Mdiag


@pytest.mark.parametrize("modes", [[ROLLING] * NW, [LOCKED] * NW, [LOCKED, ROLLING, ROLLING, LOCKED]])
def test_block_cholesky_solves_the_saddle_point_system(vehicle_rows, modes):
    """lam from the block-sparse Cholesky equals the multipliers of the full KKT system [M D^T; D 0] solved
    densely by numpy, and the factor has the pattern the blocks promise (no fill-in with leaf joints first)."""
    m, veh, sc = vehicle_rows
    rng = np.random.default_rng(7)
    BODY, D, rowb, jst, JB, nj, mrow = _rows(m, veh, sc, modes, rng)
    assert mrow == 40 + sum(md == LOCKED for md in modes)    # a locked revolute joint has one more row
    Dd, Mdiag = _dense_D(BODY, D, rowb)
    n = Dd.shape[1]
    g = rng.normal(size=n) * 100.0
    c = rng.normal(size=mrow)
    K = np.zeros((n + mrow, n + mrow))
    K[:n, :n] = np.diag(Mdiag)
    K[:n, n:] = Dd.T
    K[n:, :n] = Dd
    sol = np.linalg.solve(K, np.r_[g, c])
    lam_ref = sol[n:]
    # the Schur form: (D M^-1 D^T) lam = D M^-1 g - c
    IM = np.zeros((NB, 6))
    for b in range(NB):
        IM[b, :3] = 1.0 / BODY[b, 0]
        IM[b, 3:] = 1.0 / BODY[b, 1:4]
    MD = np.zeros((MAX_ROWS, 12))
    for r in range(mrow):
        MD[r, :6] = D[r, :6] * IM[rowb[r, 0]]
        MD[r, 6:] = D[r, 6:] * IM[rowb[r, 1]]
    Dfull = np.zeros((MAX_ROWS, 12))
    Dfull[:mrow] = D
    NZ = np.zeros((MAX_JOINTS, MAX_JOINTS), np.bool_)
    CS.block_pattern(JB, nj, NZ)
    S = np.full((MAX_ROWS, MAX_ROWS), np.nan)   # entries outside the pattern must never be read
    CS.assemble(Dfull, MD, jst, JB, nj, NZ, S)
    x = np.zeros(MAX_ROWS)
    x[:mrow] = Dd @ (g / Mdiag) - c
    CS.factor(S, jst, nj, NZ)
    CS.solve(S, jst, nj, NZ, x)
    assert np.all(np.isfinite(x[:mrow]))
    np.testing.assert_allclose(x[:mrow], lam_ref, rtol=1e-9, atol=1e-9 * np.abs(lam_ref).max())
    # leaf joints first: no fill-in (the pattern is exactly "joints sharing a body")
    for a in range(nj):
        for b in range(a + 1):
            shared = bool(set(JB[a]) & set(JB[b]))
            assert NZ[a, b] == shared, (a, b)


def test_block_pattern_adds_fill_in():
    """Chassis-knuckle joints first (the table's order): eliminating one couples its knuckle-wheel joint to
    every other chassis-knuckle joint; the symbolic pattern must include that fill-in."""
    JB = np.array([[0, 1], [0, 2], [1, 3], [2, 4]], np.int64)   # two chains off body 0
    NZ = np.zeros((4, 4), np.bool_)
    CS.block_pattern(JB, 4, NZ)
    assert NZ[2, 0] and NZ[3, 1] and NZ[1, 0]          # shared bodies
    assert NZ[2, 1] and NZ[3, 2]                       # fill-in from eliminating joints 0 and 1
    assert not NZ[3, 0]                                # joint 3 never meets joint 0
    assert CS.dense_tail(4, NZ) == 1                   # joints 1-3 are all coupled after the fill-in


def _pair(rng):
    """Two Clio-like chassis superellipsoids, tilted a little, overlapping in plan."""
    sh = np.array([1.8875, 0.82, 0.25, 0.5, 0.5])
    A1 = Rotation.from_euler("zyx", [rng.uniform(-np.pi, np.pi), rng.normal(0, 0.05), rng.normal(0, 0.05)]).as_matrix()
    A2 = Rotation.from_euler("zyx", [rng.uniform(-np.pi, np.pi), rng.normal(0, 0.05), rng.normal(0, 0.05)]).as_matrix()
    r1 = np.array([0.0, 0.0, 0.5])
    ang = rng.uniform(-np.pi, np.pi)
    r2 = r1 + rng.uniform(1.2, 2.6) * np.array([math.cos(ang), math.sin(ang), 0.0]) + [0, 0, rng.normal(0, 0.02)]
    return sh, r1, A1, sh.copy(), r2, A2


def test_warm_gap_search_finds_the_maximum_of_a_dense_scan():
    """The warm start (Brent on g') started 0.05 rad off lands on the maximum of g(th): against a dense scan
    (20,000 angles, then a 2,000-point scan of the best cell) written here, g is not smaller than the scan's
    best and the angle agrees to 1e-5 rad; the cold search (scan + golden section) agrees too."""
    rng = np.random.default_rng(3)
    checked = 0
    for _ in range(40):
        sh1, r1, A1, sh2, r2, A2 = _pair(rng)
        ths = np.linspace(0, 2 * np.pi, 20000, endpoint=False)
        gs = np.array([_g(t, 0, sh1, r1, A1, sh2, r2, A2) for t in ths])
        k = int(np.argmax(gs))
        fine = np.linspace(ths[k] - 4e-4, ths[k] + 4e-4, 2001)
        gf = np.array([_g(t, 0, sh1, r1, A1, sh2, r2, A2) for t in fine])
        th_ref, g_ref = fine[np.argmax(gf)], gf.max()
        # a unique, well-separated maximum (the warm start follows one branch; skip near-symmetric ties)
        second = np.max(gs[np.abs((ths - th_ref + np.pi) % (2 * np.pi) - np.pi) > 0.3])
        if g_ref - second < 1e-3:
            continue
        for off in (0.05, -0.05, 0.0):
            th, g = horizontal_gap(th_ref + off, True, 0, sh1, r1, A1, sh2, r2, A2)
            assert g >= g_ref - 1e-12
            assert abs((th - th_ref + np.pi) % (2 * np.pi) - np.pi) < 1e-5
        th, g = horizontal_gap(0.0, False, 0, sh1, r1, A1, sh2, r2, A2)
        assert g >= g_ref - 1e-12
        checked += 1
    assert checked >= 20
