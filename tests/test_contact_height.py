"""Height of the 3D models' contact point (docs/physics.md §13a "point"): two bodies meet only where their heights
overlap, so the force acts in the middle of the band [max(z1a, z2a), min(z1b, z2b)] of their z-ranges (a barrier's
too). Until 2026-11-27 the point was the midpoint of the two bodies' horizontal support points, i.e. the mean of
their centres' heights: a Clio against the Citaro bus was pushed at 0.68 m, 0.08 m above the top of its own
contact body (0.10-0.60 m), was struck on its roof and pitched into the road.

References written here: the band's middle from the bodies' z-ranges (an upright superellipsoid of half height c
about its centre z: z -+ c; a barrier box from the road to 2 x 0.75 m); the point's height read back from the
moment about the CG of a purely horizontal force, M_y = (z_M - z_CG) F_x; for the run, the 1D momentum of a
central collinear impact, dv_1 = m_2 (1 + e) v_rel / (m_1 + m_2)."""
import math
import sys
from pathlib import Path

import numpy as np
import pytest

from crashlab.models.common import chassis_contact as C
from crashlab.models.common.contact_force import FRICTION_V0, FRICTION_V1, FRICTION_VS

sys.path.insert(0, str(Path(__file__).parent))
from conftest import build_scene  # noqa: E402

A, B = 48e3, 590e3                                       # N/m, N/m^2: every face
STR = np.array([A, B, 1.8, A, B, 1.8, A, B, 4.5])


def _shape(c):
    """A chassis superellipsoid of half length 2.2 m, half width 0.9 m, half height c (2/eps = 4), no offsets."""
    return np.array([2.2, 0.9, c, 0.5, 0.5, 0.0, 0.0])


def _point_height(sh1, z1, sh2=None, z2=0.0, barrier=False, depth=0.1):
    """Vehicle 1 heading +x with its centre at height z1, pushed `depth` into vehicle 2 (heading -x, centre at
    height z2) or into a barrier's face across x; both at rest (no friction force: no sliding), one evaluation of
    the structure law. Returns the contact point's height read from each body's moment about its CG (the force is
    horizontal), and the force along x on vehicle 1."""
    nv = 1 if barrier else 2
    Y = np.zeros((nv, 13))
    Y[0, :7] = [0.0, 0.0, z1, 1.0, 0.0, 0.0, 0.0]
    if barrier:
        bar = np.array([[sh1[0] - depth + 0.5, 0.0, 90.0 * math.pi / 180.0, 5.0, 0.5]])   # face at x = a - depth
        PP = C.pair_table(1, 1, 1e6, 1.5, np.array([STR]), [1500.0])
        CT = C.contact_arrays(np.array([sh1]), PP, bar, 1)
    else:
        Y[1, :7] = [sh1[0] + sh2[0] - depth, 0.0, z2, 0.0, 0.0, 0.0, 1.0]
        PP = C.pair_table(2, 0, 1e6, 1.5, np.array([STR, STR]), [1500.0, 1500.0])
        CT = C.contact_arrays(np.array([sh1, sh2]), PP, np.zeros((0, 5)), 2)
    CSH, BOXR, BOXA, BOXE, PP, PST, PSG, FX, BPC, OUT, FM = CT
    C.contacts(Y, 7, CSH, BOXR, BOXA, BOXE, PP, PST, PSG[0], FX, BPC, OUT, FM, 1.5, 0.0, 0.3, 0.0, FRICTION_V0,
               FRICTION_V1, FRICTION_VS, 1e-3, float(C.LAW_STRUCTURE), 0.1)
    fx = FX[0, 0]
    assert fx < 0.0 and FX[0, 2] == 0.0                   # pushed back, horizontally
    heights = [z1 + FX[0, 4] / fx]
    if not barrier:
        assert FX[1, 0] == pytest.approx(-fx, rel=1e-12)
        heights.append(z2 + FX[1, 4] / FX[1, 0])
    return heights, fx


def test_point_in_the_middle_of_the_shared_height_band():
    """A low body (0.25-0.75 m) against a tall one (0.40-1.60 m): the band is 0.40-0.75 m, the point at 0.575 m
    (the old rule, the mean of the centres, put it at 0.75 m, the low body's top)."""
    heights, _ = _point_height(_shape(0.25), 0.5, _shape(0.6), 1.0)
    assert heights == pytest.approx([0.575, 0.575], abs=1e-9)


def test_point_of_a_low_body_under_a_tall_one_in_its_own_range():
    """A car (0.10-0.60 m) against a bus-like body reaching down to 0.32 m (0.32-1.69 m): the band is 0.32-0.60 m,
    the point at 0.46 m, inside the car's body (the old rule: (0.35 + 1.005) / 2 = 0.68 m, above it)."""
    heights, _ = _point_height(_shape(0.25), 0.35, _shape(0.685), 1.005)
    assert heights == pytest.approx([0.46, 0.46], abs=1e-9)


@pytest.mark.parametrize("z", [0.35, 0.5])
def test_equal_heights_unchanged(z):
    """Equal bodies at equal heights: the band is each body's own range, its middle their common centre height,
    which the old rule (the mean of the support points' heights) gave too: no moment about either CG."""
    heights, fx = _point_height(_shape(0.25), z, _shape(0.25), z)
    assert heights == pytest.approx([z, z], abs=1e-9)


def test_barrier_point_in_the_vehicle_range_and_in_the_shared_band():
    """Against a barrier (a box from the road to 1.5 m): an upright car's band is its own range, the point at its
    centre as before (0.35 m); a body raised to 1.15-1.65 m meets the barrier only up to 1.5 m: 1.325 m."""
    heights, _ = _point_height(_shape(0.25), 0.35, barrier=True)
    assert heights == pytest.approx([0.35], abs=1e-9)
    heights, _ = _point_height(_shape(0.25), 1.4, barrier=True)
    assert heights == pytest.approx([1.325], abs=1e-9)


def test_clio_against_the_bus_head_on_keeps_the_momentum_reference():
    """The library Clio (980 kg) at 50 km/h head-on into the Citaro bus (18,000 kg) at 30 km/h, e = 0.1, no impact
    friction (so the contact has no vertical force): the Clio's delta-V of the impact within 2 % of the 1D
    momentum reference m2 (1 + e) v_rel / (m1 + m2) = 83.5 km/h, struck on its front. With the point at the mean
    of the centres' heights (0.68 m) the Clio was struck on its roof and pitched into the road: -3.8 %
    (80.3 km/h), its body 3 cm below the road."""
    from crashlab.models.multibody import MultibodyModel

    sc = build_scene([{"vehicle": "clio", "speed": 50.0},
                      {"vehicle": "citaro_bus", "x": 1.8875 + 6.35 + 0.3, "heading": 180.0, "speed": 30.0}],
                     impact={"restitution": 0.1, "friction": 0.0}, road={"friction": 0.8}, duration=0.3)
    m1, m2 = (v.spec.mass for v in sc.vehicles)
    out = MultibodyModel().simulate(sc)
    assert out.outcome_ok, out.warnings
    row = min((r for r in out.impact_rows if r["vehicle"] == "V1"), key=lambda r: r["t"])
    ref = -m2 * 1.1 * (80.0 / 3.6) / (m1 + m2)
    assert row["dvx"] == pytest.approx(ref, rel=0.02)
    assert row["side"] == "front"
