"""[impact] point = "engagement" (docs/physics.md §4): the outlines moved along their velocities from first touch
until they overlap by engagement_depth; the point of impact at the overlap's centroid moved back by half the
pair's mean displacement, the contact plane along the crushed faces (each edge of the overlap weighted by the
area it swept; a barrier's faces only). Every expected point, plane and principal-value ratio below is worked by
hand from the rectangles (the overlap polygon written out in the test), not computed by the code under test.
The kernel's impact row says how the placement went (I_ENGAGE: used, ambiguous plane, fallback)."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from conftest import PC_CRASH

from crashlab.errors import InputError
from crashlab.fields import parse, setter
from crashlab.models.impulse import kernel as K
from crashlab.models.impulse import layout as L
from crashlab.scene_file import load_scene

HALF_W, HALF_L = 0.82, 1.8875  # the Clio's half width and CG-to-front = CG-to-rear (m)
ONSET = 1e-5  # m: the model's onset_tol (the overlap at first touch, from which the engagement starts)


def plane_deg(r):
    """The impact row's contact plane as an axis, degrees in [0, 180)."""
    return r.plane_angle % 180.0


def axis_diff(a, b):
    """Angle between two axes [deg], 0..90."""
    d = (a - b) % 180.0
    return min(d, 180.0 - d)


def kernel_row(model, scene):
    """The first impact's kernel row (every column, L.I_*) of the scene run by the impulse model; the impact
    record starts as garbage (7.0), as an np.empty one may: the kernel writes every column of a row it keeps."""
    P, S0, B, cfg, A, NA, zones = model.pack(scene)
    nv = P.shape[0]
    rest, final, contact = np.empty((nv, 3)), np.empty((nv, 3)), np.empty((nv, 4))
    imp, diag = np.full((model.max_impacts, L.N_IMP), 7.0), np.zeros(L.N_DIAG)
    K.simulate_one(P, S0, B, cfg, A, NA, zones, rest, final, contact, imp, np.zeros((0, nv, 7)), diag)
    assert diag[L.D_IMPACTS] >= 1
    return imp[0]


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
    depth, V2 stood: the point (2.5, 0.32). Crushed faces: the rectangle's two edges across the motion (V1's
    front, V2's side, 1.0 m each, swept depth); its edges along the motion swept nothing: the plane along V2's
    side, 90 deg (before: the diagonal through the two outline crossings, atan2(-1, depth))."""
    out = impulse_model.simulate(corner_into_end(make_scene, depth))
    r = out.impacts.iloc[0]
    assert r.point_x == pytest.approx(2.5, abs=1e-4) and r.point_y == pytest.approx(0.32, abs=1e-4)
    assert axis_diff(plane_deg(r), 90.0) < 1e-6


def frontal(make_scene, y2, depth, speed=50.0):
    """Two aligned Clios, V1 (heading 0, `speed` km/h) into a standing V2 (heading 180) at x = 5 with lateral
    offset y2: the fronts meet at x = 5 - HALF_L = 3.1125."""
    return make_scene(vehicles=[{"speed": speed, "wheels": "rolling"},
                                {"x": 5.0, "y": y2, "heading": 180.0, "wheels": "rolling"}],
                      impact={"point": "engagement", "engagement_depth": depth, "restitution": 0.1, "friction": 0.3},
                      duration=2.0)


@pytest.mark.parametrize("y2,depth", [(0.0, 0.2), (0.0, 0.5), (0.0, 0.8), (0.5, 0.5), (0.5, 0.8), (1.09, 0.5)])
def test_aligned_frontal_plane_across_the_driving_direction(make_scene, impulse_model, y2, depth):
    """Full and offset overlap: at engagement the overlap is the rectangle x 3.1125..3.1125 + depth (V1 moved
    depth), y from y2 - HALF_W to HALF_W (width 1.64 - y2 >= depth, else the SAT depth never reaches depth);
    its edges across the motion are the two fronts: the plane perpendicular to the driving direction (90 deg),
    principal-value ratio 0, the point (3.1125, middle of the lateral overlap). y2 = 1.09 leaves a 0.55 x 0.5 m
    overlap: its second moments are within 20 % of each other (no clear long axis), the crushed faces are not."""
    sc = frontal(make_scene, y2, depth)
    out = impulse_model.simulate(sc)
    r = out.impacts.iloc[0]
    assert axis_diff(plane_deg(r), 90.0) < 1.0
    assert r.point_x == pytest.approx(5.0 - HALF_L, abs=ONSET)
    assert r.point_y == pytest.approx(0.5 * (y2 - HALF_W + HALF_W), abs=1e-6)
    row = kernel_row(impulse_model, sc)
    assert row[L.I_ENGAGE] == L.ENGAGE_USED and row[L.I_ENGAGE_RATIO] == pytest.approx(0.0, abs=1e-9)
    if y2 == 0.0:  # a central impact: no tangential slip, the impulse is full
        assert r.kind == "full"


def test_head_on_case_at_0_8_m_engagement_is_central():
    """The defect this fixes (PC-Crash case 1, studies/pc_crash/head_on.toml, 50 km/h into a standing Clio):
    at 0.8 m engagement the plane through the two outline crossings was the overlap's diagonal, 116 deg, and
    the central impact became a sliding one (delta-V 25.74 km/h, rest poses 2.7 / 4.8 m from PC-Crash's).
    Along the crushed faces: 90 deg, full impact, delta-V (1 + e) m2 / (m1 + m2) x 50 = 27.50 km/h, PC-Crash's."""
    import crashlab
    s = load_scene(PC_CRASH / "head_on.toml")
    sc = s.replace(impact=dataclasses.replace(s.impact, engagement=True, engagement_depth=0.8))
    out = crashlab.simulate(sc, model="impulse")
    r = out.impacts.iloc[0]
    assert axis_diff(plane_deg(r), 90.0) < 1.0
    assert r.kind == "full"
    for v in ("V1", "V2"):
        row = out.impacts[out.impacts.vehicle == v].iloc[0]
        assert math.hypot(row.dvx, row.dvy) == pytest.approx(1.1 * 0.5 * 50.0, rel=1e-6)  # km/h (display units)


@pytest.mark.parametrize("v2", [0.0, 30.0])
def test_t_bone_plane_along_the_struck_side(make_scene, impulse_model, v2):
    """V1 (heading 0, 50 km/h) into the middle of the left side of V2 (heading 90, standing or at v2 km/h
    along +y), V2's side at x = 2.5. At engagement V1's front is d = 0.5 m past it (V1 moved Dx = d, V2 moved
    Dy = d v2 / 50): the overlap is the rectangle x 2.5..3.0, y -0.82..0.82 (V1's width inside V2's side).
    Swept areas: V1's front and V2's side 1.64 Dx each, V1's two sides d Dy each: the plane along V2's side
    (90 deg), the principal-value ratio (2 d Dy) / (2 x 1.64 Dx) = d (v2 / 50) / 1.64; the point: the centroid
    (2.75, 0) moved back by half the mean displacement (d / 2, Dy / 2): (2.5, -Dy / 2)."""
    d = 0.5
    sc = make_scene(vehicles=[{"speed": 50.0, "wheels": "rolling"},
                              {"x": 2.5 + HALF_W, "y": -v2 / 3.6 * (2.5 - HALF_L) / (50 / 3.6),
                               "heading": 90.0, "speed": v2, "wheels": "rolling"}],
                    impact={"point": "engagement", "engagement_depth": d}, duration=2.0)
    row = kernel_row(impulse_model, sc)
    # V2's start y puts V1's centre line at V2's centre at first touch; the hand numbers hold for any y inside
    dy = d * v2 / 50.0
    assert axis_diff(math.degrees(row[L.I_PLANE]) % 180.0, 90.0) < 1e-6
    assert row[L.I_ENGAGE] == L.ENGAGE_USED
    assert row[L.I_ENGAGE_RATIO] == pytest.approx(d * (v2 / 50.0) / (2 * HALF_W), abs=1e-4)
    assert row[L.I_PX] == pytest.approx(2.5, abs=1e-4) and row[L.I_PY] == pytest.approx(-0.5 * dy, abs=1e-4)


def oblique(make_scene, theta, depth, barrier=False):
    """V1 (Clio, heading theta deg, 40 km/h) with its front-right corner C0 at (2.0, 0.0) at the start, into a
    face along +y at x = s = 2.4: the left side of a standing Clio V2 (heading 90), or a barrier's face.
    Returns the scene and the first-touch corner (s, yc)."""
    th = math.radians(theta)
    cx0, cy0 = 2.0, 0.0
    x1 = cx0 - HALF_L * math.cos(th) - HALF_W * math.sin(th)  # V1's CG from its front-right corner
    y1 = cy0 - HALF_L * math.sin(th) + HALF_W * math.cos(th)
    s = 2.4
    yc = cy0 + (s - cx0) * math.tan(th)
    yb = yc + 0.4  # V2's (the barrier's) centre along its face
    vehicles = [{"x": x1, "y": y1, "heading": theta, "speed": 40.0, "wheels": "rolling"}]
    kw = {}
    if barrier:
        kw["barriers"] = [{"x": s + 1.0, "y": yb, "heading": 0.0, "length": 2.0, "width": 6.0}]
    else:
        vehicles.append({"x": s + HALF_W, "y": yb, "heading": 90.0, "wheels": "rolling"})
    sc = make_scene(vehicles=vehicles, impact={"point": "engagement", "engagement_depth": depth}, duration=2.0, **kw)
    return sc, (s, yc)


def test_oblique_front_into_side_plane_between_the_crushed_faces(make_scene, impulse_model):
    """V1 at theta = 30 deg into V2's side. At engagement (SAT depth p = 0.3 along V2's side normal) V1's
    corner C is p past the side: the overlap is the triangle C = (s + p, yc + p tan theta),
    P1 = C + (p / sin theta)(-sin theta, cos theta) on V1's front, P2 = C + (p / cos theta)(-cos theta, -sin theta)
    on V1's right side, P1 and P2 on V2's side (x = s). V2 stands, V1 moved D = (p, p tan theta): swept areas
    |edge x D|: the front piece C-P1 (across D) and the piece P1-P2 of V2's side each sweep
    p^2 / (sin theta cos theta), the piece P2-C along V1's side nothing. Two faces of equal weight at 120 deg
    (V1's front) and 90 deg (V2's side): the plane midway, 105 deg; ratio (1 - cos 30) / (1 + cos 30) =
    tan^2 15 deg. The point: the triangle's centroid moved back by D / 2."""
    theta, p = 30.0, 0.3
    th = math.radians(theta)
    sc, (s, yc) = oblique(make_scene, theta, p)
    # the overlap polygon by hand and its crushed-face axis (doubled-angle mean of the swept areas)
    C = np.array([s + p, yc + p * math.tan(th)])
    P1 = C + (p / math.sin(th)) * np.array([-math.sin(th), math.cos(th)])
    P2 = C + (p / math.cos(th)) * np.array([-math.cos(th), -math.sin(th)])
    assert P1[0] == pytest.approx(s) and P2[0] == pytest.approx(s)
    D = np.array([p, p * math.tan(th)])  # V1's displacement from first touch
    c2 = s2 = w_sum = 0.0
    for a, b in ((C, P1), (P1, P2), (P2, C)):
        e = b - a
        w = abs(e[0] * D[1] - e[1] * D[0])
        ang = math.atan2(e[1], e[0])
        c2, s2, w_sum = c2 + w * math.cos(2 * ang), s2 + w * math.sin(2 * ang), w_sum + w
    plane = math.degrees(0.5 * math.atan2(s2, c2)) % 180.0
    ratio = (w_sum - math.hypot(c2, s2)) / (w_sum + math.hypot(c2, s2))
    assert plane == pytest.approx(90.0 + theta / 2.0)  # the closed form: midway between 90 and 90 + theta
    assert ratio == pytest.approx(math.tan(math.radians(theta / 2.0)) ** 2)
    point = (C + P1 + P2) / 3.0 - 0.5 * D
    row = kernel_row(impulse_model, sc)
    assert row[L.I_ENGAGE] == L.ENGAGE_USED
    assert axis_diff(math.degrees(row[L.I_PLANE]) % 180.0, plane) < 1e-4
    assert row[L.I_ENGAGE_RATIO] == pytest.approx(ratio, abs=1e-6)
    assert row[L.I_PX] == pytest.approx(point[0], abs=1e-4) and row[L.I_PY] == pytest.approx(point[1], abs=1e-4)


def test_oblique_into_a_barrier_plane_along_the_barrier(make_scene, impulse_model):
    """The same corner into a rigid barrier's face: the barrier does not crush, only its face counts (the car's
    crushed front ends up along it): the plane is the face, 90 deg, ratio 0; the point as above (the
    barrier stands: half of V1's displacement back)."""
    theta, p = 30.0, 0.3
    th = math.radians(theta)
    sc, (s, yc) = oblique(make_scene, theta, p, barrier=True)
    C = np.array([s + p, yc + p * math.tan(th)])
    P1 = C + (p / math.sin(th)) * np.array([-math.sin(th), math.cos(th)])
    P2 = C + (p / math.cos(th)) * np.array([-math.cos(th), -math.sin(th)])
    point = (C + P1 + P2) / 3.0 - 0.5 * np.array([p, p * math.tan(th)])
    row = kernel_row(impulse_model, sc)
    assert row[L.I_ENGAGE] == L.ENGAGE_USED and row[L.I_ENGAGE_RATIO] == pytest.approx(0.0, abs=1e-9)
    assert axis_diff(math.degrees(row[L.I_PLANE]) % 180.0, 90.0) < 1e-6
    assert row[L.I_PX] == pytest.approx(point[0], abs=1e-4) and row[L.I_PY] == pytest.approx(point[1], abs=1e-4)


def test_ambiguous_plane_is_flagged_and_keeps_the_first_touch_plane(make_scene, impulse_model):
    """Grazing at theta = 88 deg: the overlap stays a triangle between V1's front, V1's side and V2's side,
    self-similar as it deepens, and the two crushed faces (V1's front at 178 deg, V2's side at 90) sweep equal
    areas: principal-value ratio tan^2(44 deg) = 0.93 > 0.9, no plane stands out. The row is flagged
    ENGAGE_AMBIGUOUS and the contact plane is the one at first touch (the default placement's), not one of the
    two axes picked silently."""
    theta = 88.0
    sc, _ = oblique(make_scene, theta, 0.04)
    row = kernel_row(impulse_model, sc)
    assert row[L.I_ENGAGE] == L.ENGAGE_AMBIGUOUS
    assert row[L.I_ENGAGE_RATIO] == pytest.approx(math.tan(math.radians(theta / 2)) ** 2, abs=1e-6)
    found = sc.replace(impact=dataclasses.replace(sc.impact, engagement=False))
    assert row[L.I_PLANE] == pytest.approx(kernel_row(impulse_model, found)[L.I_PLANE], abs=1e-9)


def test_engagement_never_reached_is_flagged(make_scene, impulse_model):
    """A 0.2 m lateral overlap (V2 offset 1.44 m) never overlaps by 0.5 m in the separating-axis sense: the
    row says ENGAGE_FALLBACK and the point and plane are the contact-zone ones (as without engagement);
    without engagement (the contact-zone point, a given point) the column is 0."""
    sc = frontal(make_scene, 1.44, 0.5)
    row = kernel_row(impulse_model, sc)
    assert row[L.I_ENGAGE] == L.ENGAGE_FALLBACK
    found = kernel_row(impulse_model, sc.replace(impact=dataclasses.replace(sc.impact, engagement=False)))
    assert found[L.I_ENGAGE] == 0
    for c in (L.I_PX, L.I_PY, L.I_PLANE, L.I_DVX_I, L.I_DVY_I):
        assert row[c] == found[c]
    given = make_scene(vehicles=[{"speed": 50.0}, {"x": 2 * HALF_L, "heading": 180.0}],
                       impact={"point": [HALF_L, 0.0], "plane_angle": 90.0}, duration=1.0)  # fronts touching
    assert kernel_row(impulse_model, given)[L.I_ENGAGE] == 0  # the collision position's impact at t = 0


def test_engagement_depth_is_a_field_and_plane_angle_is_refused(make_scene):
    sc = corner_into_end(make_scene, 0.5)
    assert sc.impact.engagement and sc.impact.point is None
    f = parse("impact.engagement_depth")
    assert f.unit == "m"
    assert setter(sc, ["impact.engagement_depth"])([0.3]).impact.engagement_depth == 0.3
    with pytest.raises(InputError, match="impact.plane_angle"):
        make_scene(vehicles=[{"speed": 30.0}, {"x": 4.0, "heading": 90.0}],
                   impact={"point": "engagement", "plane_angle": 90.0})
