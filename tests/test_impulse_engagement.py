"""[impact] point = "engagement" (docs/physics.md §4): the outlines moved along their velocities from first touch
until they overlap by engagement_depth; the point of impact at the overlap's centroid moved back by half the
pair's mean displacement, the contact plane along the line through the two points where the outlines cross.
Worked by hand for a rectangle-into-rectangle overlap."""
from __future__ import annotations

import math

import pytest

from crashlab.errors import InputError
from crashlab.fields import parse, setter

HALF_W, HALF_L = 0.82, 1.8875  # the Clio's half width and CG-to-front = CG-to-rear (m)


def corner_into_end(make_scene, depth, law="kudlich-slibar"):
    """V1 (heading 0, 30 km/h, y = 0) into the left side of a standing V2 (heading 90) whose rear end lies at
    y = -0.18, so V1 overlaps V2's length by 1.0 m (y from -0.18 to 0.82); V2's side at x = 2.5."""
    y2 = -0.18 + HALF_L
    return make_scene(vehicles=[{"speed": 30.0}, {"x": 2.5 + HALF_W, "y": y2, "heading": 90.0}],
                      impact={"point": "engagement", "engagement_depth": depth, "law": law}, duration=3.0)


@pytest.mark.parametrize("depth", [0.2, 0.5])
def test_engagement_point_and_plane_by_hand(make_scene, impulse_model, depth):
    """At engagement V1's front is `depth` past V2's side (x = 2.5 + depth; SAT depth = min(depth, 1.0)): the
    overlap is the rectangle x 2.5..2.5 + depth, y -0.18..0.82, centroid (2.5 + depth / 2, 0.32); V1 moved
    depth, V2 stood: the point (2.5, 0.32). The outlines cross at (2.5, 0.82) (V1's left side, V2's side) and
    (2.5 + depth, -0.18) (V1's front, V2's rear end): the contact plane along that diagonal."""
    out = impulse_model.simulate(corner_into_end(make_scene, depth))
    r = out.impacts.iloc[0]
    assert r.point_x == pytest.approx(2.5, abs=1e-4) and r.point_y == pytest.approx(0.32, abs=1e-4)
    plane = math.degrees(math.atan2(-1.0, depth)) % 180.0
    assert r.plane_angle % 180.0 == pytest.approx(plane, abs=1e-2)


def test_engagement_depth_is_a_field_and_plane_angle_is_refused(make_scene):
    sc = corner_into_end(make_scene, 0.5)
    assert sc.impact.engagement and sc.impact.point is None
    f = parse("impact.engagement_depth")
    assert f.unit == "m"
    assert setter(sc, ["impact.engagement_depth"])([0.3]).impact.engagement_depth == 0.3
    with pytest.raises(InputError, match="impact.plane_angle"):
        make_scene(vehicles=[{"speed": 30.0}, {"x": 4.0, "heading": 90.0}],
                   impact={"point": "engagement", "plane_angle": 90.0})
