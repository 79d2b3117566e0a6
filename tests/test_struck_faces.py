"""Struck faces of the 3D chassis contact at the first touch (docs/physics.md §13a "Struck faces"): from the
approach of the two bodies' plan boxes, not from where on their rounded outlines they first touch.

The rounded superellipse outlines of two cars head-on at a small lateral overlap first touch far back on their
corners, where the contact point lies nearer their flanks: the faces were chosen there, so the fronts of two cars
overlapping by 0.26 m glanced off as a sideswipe (a Clio's delta-V 4.2 km/h) and at 0.28 m engaged (36.5 km/h).
What a reconstructionist calls the struck face is where the other car came in: here both fronts.

References written here: the faces each scene's approach makes obvious (the geometry of the plan boxes and their
relative motion); for the runs, the planar impulse-momentum of a frictionless impact along the fronts' normal at
the middle of the engaged width (Brach & Brach 2011, ch. 5: P = (1 + e) v / (1/m1 + 1/m2 + r1^2/I1 + r2^2/I2))."""
import math
import sys
from pathlib import Path

import numpy as np
import pytest

from crashlab.models.common import chassis_contact as C
from crashlab.models.common.contact_force import FRICTION_V0, FRICTION_V1, FRICTION_VS

sys.path.insert(0, str(Path(__file__).parent))
from conftest import build_scene  # noqa: E402

SH = np.array([2.38, 0.916, 0.25, 0.5, 0.5, 0.0, 0.0])   # a, b, c, eps1, eps2 (2/eps = 4), offsets
STR = np.array([48e3, 590e3, 1.832, 24e3, 300e3, 1.832, 30e3, 370e3, 4.7])
FRONT, REAR, LEFT, RIGHT = 0, 1, 2, 3


def _state(poses):
    """Chassis states of (x, y, heading [rad], vx, vy) per vehicle: Euler parameters of the heading, nq = 7."""
    Y = np.zeros((len(poses), 13))
    for k, (x, y, h, vx, vy) in enumerate(poses):
        Y[k, :7] = [x, y, 0.5, math.cos(h / 2), 0.0, 0.0, math.sin(h / 2)]
        Y[k, 7:9] = [vx, vy]
    return Y


def _faces(poses):
    """Fresh contact arrays, evaluated once: the struck faces (i, j) latched and whether the pair is touching."""
    PP = C.pair_table(2, 0, 1e6, 1.5, np.array([STR, STR]), [1500.0, 1500.0])
    CT = C.contact_arrays(np.array([SH, SH]), PP, np.zeros((0, 5)), 2)
    CSH, BOXR, BOXA, BOXE, PP, PST, PSG, FX, BPC, OUT, FM = CT
    C.contacts(_state(poses), 7, CSH, BOXR, BOXA, BOXE, PP, PST, PSG[0], FX, BPC, OUT, FM, 1.5, 0.0, 0.3, 0.0,
               FRICTION_V0, FRICTION_V1, FRICTION_VS, 1e-3, float(C.LAW_STRUCTURE), 0.1)
    return (int(PST[0, C.S_FACE_I]), int(PST[0, C.S_FACE_J])), PSG[0, 0, C.G_DEL] > 0.0


def _at_first_touch(poses_of):
    """poses_of(s): the scene with V2 moved s along its approach; the poses 1 mm past the first touch."""
    lo, hi = 0.0, 8.0                      # s = 0 touching, s = 8 apart
    assert _faces(poses_of(lo))[1] and not _faces(poses_of(hi))[1]
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if _faces(poses_of(mid))[1] else (lo, mid)
    return poses_of(lo - 1e-3)


@pytest.mark.parametrize("overlap", [0.05, 0.26, 0.6])
def test_head_on_at_a_small_overlap_strikes_the_fronts(overlap):
    """Two cars head-on, closing at 20 m/s, their widths overlapping by `overlap`: both fronts (the first touch on
    the rounded corners is nearer the flanks: the rule by the point gave both left flanks up to about 0.3 m)."""
    y2 = 2 * SH[1] - overlap
    faces, _ = _faces(_at_first_touch(lambda s: [(0, 0, 0, 10, 0), (2.0 + s, y2, math.pi, -10, 0)]))
    assert faces == (FRONT, FRONT)


def test_rear_end_at_a_small_overlap_strikes_front_and_rear():
    """V1 at 15 m/s into a standing car ahead, 0.1 m of overlap across: V1's front, V2's rear."""
    y2 = 2 * SH[1] - 0.1
    faces, _ = _faces(_at_first_touch(lambda s: [(0, 0, 0, 15, 0), (2.0 + s, y2, 0.0, 0, 0)]))
    assert faces == (FRONT, REAR)


@pytest.mark.parametrize("angle", [0.0, 30.0, 60.0])
def test_front_into_a_flank(angle):
    """V2 (heading +y, standing) struck on its left flank (facing -x) by V1's front, V1 coming at `angle` from the
    flank's normal: V1's front and V2's left, also at 60 deg where V1's corner touches first."""
    a = math.radians(angle)
    faces, _ = _faces(_at_first_touch(lambda s: [(1.5 - s * math.cos(a), 0.5 - s * math.sin(a), a, 12 * math.cos(a),
                                                  12 * math.sin(a)), (3.0, 0.5, math.pi / 2, 0, 0)]))
    assert faces == (FRONT, LEFT)


def test_lane_change_sideswipe_strikes_the_flanks():
    """V2 alongside V1 (same direction, 2 m/s faster) drifting into it at 1 m/s: V1's left and V2's right flank."""
    faces, _ = _faces(_at_first_touch(lambda s: [(0, 0, 0, 20, 0), (0.8, 2 * SH[1] - 0.02 + s, 0.0, 22, -1)]))
    assert faces == (LEFT, RIGHT)


def test_without_approach_the_point_decides():
    """Two cars touching at rest have no approach: each face is the one nearest the touch point in proportion
    (the rule for a barrier and a tilted body): head-on 0.1 m across, both left flanks on the rounded corners."""
    y2 = 2 * SH[1] - 0.1
    faces, _ = _faces(_at_first_touch(lambda s: [(0, 0, 0, 0, 0), (2.0 + s, y2, math.pi, 0, 0)]))
    assert faces == (LEFT, LEFT)


def _first_row(out, name):
    return min((r for r in out.impact_rows if r["vehicle"] == name), key=lambda r: r["t"])


@pytest.mark.parametrize("model", ["multibody", "exudyn"])
@pytest.mark.parametrize("overlap", [0.26, 0.28])
def test_small_overlap_head_on_has_no_cliff(overlap, model):
    """A saloon and a Clio head-on at 50/50 km/h with 0.26 and 0.28 m of overlap across (restitution 0.1, impact
    friction 0.3): both engage on their fronts, the Clio's delta-V within 15 % of the frictionless impact along the
    fronts' normal at the middle of the engaged width (Clio 48.2 / 48.6 km/h; was 3.3 km/h at 0.26 m, a sideswipe,
    and 22.8 at 0.28 m), in both 3D models."""
    from crashlab.registry import get_model

    y2 = 0.5 * (1.832 + 1.64) - overlap
    sc = build_scene([{"vehicle": "saloon", "speed": 50.0},
                      {"vehicle": "clio", "x": 5.0, "y": y2, "heading": 180.0, "speed": 50.0}],
                     impact={"restitution": 0.1, "friction": 0.3}, road={"friction": 0.8}, duration=3.0)
    s, c = (v.spec for v in sc.vehicles)
    r1, r2 = 0.5 * (s.width - overlap), 0.5 * (c.width - overlap)
    P = 1.1 * (100 / 3.6) / (1 / s.mass + 1 / c.mass + r1 ** 2 / s.yaw_inertia + r2 ** 2 / c.yaw_inertia)
    out = get_model(model).simulate(sc)
    assert out.outcome_ok, out.warnings
    row1, row2 = _first_row(out, "V1"), _first_row(out, "V2")
    assert (row1["side"], row2["side"]) == ("front", "front")
    assert 3.6 * math.hypot(row2["dvx"], row2["dvy"]) == pytest.approx(3.6 * P / c.mass, rel=0.15)


@pytest.mark.parametrize("model", ["multibody", "exudyn"])
def test_a_post_inside_the_front_stops_the_car(model):
    """A Clio at 100 km/h into a rigid 0.3 m post 0.4 m off its centreline (inside its 0.82 m half width): the post's
    struck face is the one the car came in through, so the car crushes its front on it and stops (with the crush
    zone's warning: no wheels or engine stop it sooner). The faces were the nearest ones in proportion to the
    point, on the rounded corner the car's flank and the post's side: the car slid past and ended 53 m beyond it
    with a delta-V of 5 km/h and no warning (a fuzzer)."""
    from crashlab.registry import get_model

    sc = build_scene([{"vehicle": "clio", "speed": 100.0}], impact={"restitution": 0.1, "friction": 0.3},
                     road={"friction": 0.8}, duration=2.0,
                     barriers=[{"x": 2.3, "y": 0.4, "heading": 0.0, "length": 0.3, "width": 0.3}])
    out = get_model(model).simulate(sc)
    row = _first_row(out, "V1")
    assert row["side"] == "front"
    assert out.rest_si[0, 0] < 2.3 and 3.6 * math.hypot(row["dvx"], row["dvy"]) > 100.0
    assert any("crush zone" in w for w in out.warnings), out.warnings
