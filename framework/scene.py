"""The Scene: the static, immutable description of one event, in SI units, with the bounds of its values and
its geometry (outlines, the given point of impact, overlaps at the start).

Scene files are read and converted into it by crashlab.scene_file. Variants (the optimizer makes thousands)
are cheap copies made with `Scene.with_vehicle` / `Scene.replace`.
"""
from __future__ import annotations

import dataclasses
import math
from typing import Literal

from .vehicle import VehicleSpec

WheelState = Literal["rolling", "locked", "locked_after_impact", "braked"]
WHEEL_STATES = ("rolling", "locked", "locked_after_impact", "braked")


# ---------------------------------------------------------------- bounds (file units)
# Bounds of a scene (file units; crashlab.scene_file checks them). Every number is finite, a number
# (true/false are not), and within these ranges; wide enough for any road event a reconstructionist models,
# narrow enough that the models' arithmetic stays finite (a heading of 1e308 deg has no sine; a car at
# x = 1e30 m has no outline).
POSITION_MAX = 1e5  # m: |x|, |y| of vehicles, barriers and the impact point: a local site frame (100 km);
#                     survey coordinates (UTM, national grids) are shifted to a local origin first
ANGLE_MAX = 3600.0  # deg: |heading|, |plane_angle|: ten turns (angles count modulo 360)
ENGAGEMENT_DEPTH = 0.5  # m: [impact] engagement_depth default (docs/physics.md §4)
ENGAGEMENT_DEPTH_MAX = 3.0  # m: more than a car's half length of crush
SPEED_MAX = 400.0  # km/h
YAW_RATE_MAX = 720.0  # deg/s: two turns a second (a start state; post-impact spin comes from the model)
STEER_MAX = 45.0  # deg at the road wheels (lock of a car ~35-40 deg)
DURATION_MAX = 120.0  # s
FRICTION_MAX = 2.0  # road and impact friction; 0 is allowed (ice; an impact isolated from the road)
BARRIER_SIZE = (0.05, 1000.0)  # m: a post to a kilometre of wall
ZONE_CORNERS_MAX = 1000  # corners of a friction zone: checking that no two edges cross takes n^2 / 2 segment
#                          tests (1,000 corners: 1 s; the 20,000 of issue 27's fuzz: minutes); a road edge
#                          at 0.5 m over 500 m fits


# ---------------------------------------------------------------- the scene (SI)
@dataclasses.dataclass(frozen=True)
class Zone:
    """A friction polygon (SI): corners as ((x, y), ...), counter-clockwise or clockwise."""
    friction: float
    polygon: tuple[tuple[float, float], ...]
    name: str = ""


ROAD_LINE_KINDS = ("edge", "lane", "kerb", "centre")  # what a road line marks (drawn, never simulated)
ROAD_LINE_STYLES = ("solid", "dashed", "dotted")


@dataclasses.dataclass(frozen=True)
class RoadLine:
    """A line drawn on the road (SI: m): an edge, a lane marking, a kerb or a centre line, as a polyline.
    Only drawn (top views, animations): no model reads it, so it changes no result."""
    points: tuple[tuple[float, float], ...]
    kind: str = "edge"  # one of ROAD_LINE_KINDS
    style: str | None = None  # one of ROAD_LINE_STYLES; None: the kind's own (crashlab.tools.plotting)


@dataclasses.dataclass(frozen=True)
class Road:
    friction: float = 0.8
    zones: tuple[Zone, ...] = ()  # later zones win where zones overlap
    # drawn only: excluded from comparisons, so two scenes that differ in their lines are the same event
    lines: tuple[RoadLine, ...] = dataclasses.field(default=(), compare=False)


@dataclasses.dataclass(frozen=True)
class Action:
    """A driver action (SI: s, rad): None keeps the previous value; brake and steer ramp linearly."""
    t: float
    wheels: str | None = None
    brake: float | None = None
    steer: float | None = None
    ramp: float = 0.0


@dataclasses.dataclass(frozen=True)
class Impact:
    restitution: float = 0.1  # the constant; with restitution_law "speed" the law's (crashlab.restitution)
    restitution_law: str = "constant"  # or "speed": e of the closing speed at each impact (docs/physics.md §13b)
    friction: float = 0.3
    law: str = "kudlich-slibar"
    force_law: str = "flores"
    friction_law: str = "ambrosio"
    point: tuple[float, float] | None = None  # m, global, at first contact
    plane_angle: float | None = None  # rad, tangent of the contact plane, CCW from +x
    engagement: bool = False  # point = "engagement": point and plane at engagement_depth (impulse model, §4)
    engagement_depth: float = ENGAGEMENT_DEPTH  # m


@dataclasses.dataclass(frozen=True)
class VehicleState:
    """One vehicle of a scene: its data and its start state (SI: m, rad, m/s, rad/s)."""

    name: str
    spec: VehicleSpec
    x: float = 0.0
    y: float = 0.0
    heading: float = 0.0
    speed: float = 0.0
    yaw_rate: float = 0.0
    wheels: str = "rolling"
    steer: float = 0.0
    actions: tuple[Action, ...] = ()  # in time order (checked when read); wheels and steer hold before


@dataclasses.dataclass(frozen=True)
class Barrier:
    x: float
    y: float
    heading: float
    length: float
    width: float


@dataclasses.dataclass(frozen=True)
class Scene:
    name: str
    vehicles: tuple[VehicleState, ...]
    road: Road = Road()
    impact: Impact = Impact()
    barriers: tuple[Barrier, ...] = ()
    duration: float = 10.0
    stop_at_rest: bool = True
    source: str = "<scene>"
    references: dict = dataclasses.field(default_factory=dict, compare=False, hash=False)
    # the scene file's [[uncertain]] parameters (crashlab.uncertainty.Uncertain, file units): what Monte Carlo,
    # the posterior and the searches may vary; the scene's own values are the nominal ones
    uncertain: tuple = dataclasses.field(default=(), compare=False, hash=False)

    def vehicle(self, name: str) -> VehicleState:
        for v in self.vehicles:
            if v.name == name:
                return v
        raise KeyError(name)

    @property
    def vehicle_names(self) -> list[str]:
        return [v.name for v in self.vehicles]

    def replace(self, **changes) -> Scene:
        return dataclasses.replace(self, **changes)

    def with_vehicle(self, name: str, **changes) -> Scene:
        """A copy with fields of one vehicle's start state changed (SI units)."""
        vs = tuple(dataclasses.replace(v, **changes) if v.name == name else v for v in self.vehicles)
        if vs == self.vehicles and name not in self.vehicle_names:
            raise KeyError(name)
        return dataclasses.replace(self, vehicles=vs)


def driver_input_key(scene: Scene) -> str | None:
    """The first scene key holding driver actions or friction zones (`vehicles.N.actions`, `road.zones`),
    or None for a scene without them."""
    for i, v in enumerate(scene.vehicles):
        if v.actions:
            return f"vehicles.{i}.actions"
    return "road.zones" if scene.road.zones else None


def vehicle_outline(v: VehicleState, x=None, y=None, heading=None):
    from .geometry import rect_corners
    s = v.spec
    return rect_corners(v.x if x is None else x, v.y if y is None else y,
                        v.heading if heading is None else heading, s.cg_to_front, s.cg_to_rear, s.width / 2)


def barrier_outline(b: Barrier):
    from .geometry import rect_corners
    return rect_corners(b.x, b.y, b.heading, b.length / 2, b.length / 2, b.width / 2)


def _distance_to_outline(px, py, corners) -> float:
    """Distance from a point to a convex outline (corners counter-clockwise); 0 inside."""
    best, inside = float("inf"), True
    for k in range(4):
        ax, ay = corners[k]
        bx, by = corners[(k + 1) % 4]
        ex, ey = bx - ax, by - ay
        if ex * (py - ay) - ey * (px - ax) < 0.0:
            inside = False
        t = min(max(((px - ax) * ex + (py - ay) * ey) / (ex * ex + ey * ey), 0.0), 1.0)
        best = min(best, ((px - ax - t * ex) ** 2 + (py - ay - t * ey) ** 2) ** 0.5)
    return 0.0 if inside else best


GIVEN_POINT_TOLERANCE = 0.5  # m: the given point of impact lies within this of both outlines it joins


def given_pair(scene: Scene) -> tuple[int, int]:
    """The pair that meets at the given point of impact: (vehicle index, index of the other vehicle, or
    number of vehicles + barrier index), the one whose two outlines lie nearest the point.
    Raises ValueError when no pair lies within GIVEN_POINT_TOLERANCE of it."""
    px, py = scene.impact.point
    nv = len(scene.vehicles)
    outlines = [vehicle_outline(v) for v in scene.vehicles] + [barrier_outline(b) for b in scene.barriers]
    dist = [_distance_to_outline(px, py, c) for c in outlines]
    pairs = [(max(dist[i], dist[k]), i, k) for i in range(nv) for k in range(i + 1, len(outlines))]
    if not pairs or min(pairs)[0] > GIVEN_POINT_TOLERANCE:
        raise ValueError(f"no two outlines meet within {GIVEN_POINT_TOLERANCE} m of the point")
    _, i, k = min(pairs)
    return i, k


def start_overlaps(scene: Scene) -> list[tuple[str, str]]:
    """Pairs (vehicle, vehicle or barrier#k) whose outlines overlap in the start state."""
    import numpy as np
    x, y, heading = ([[getattr(v, q) for v in scene.vehicles]] for q in ("x", "y", "heading"))
    return [(a, b) for a, b, hit in start_overlap_rows(scene, np.array(x), np.array(y), np.array(heading)) if hit[0]]


def start_overlap_rows(scene: Scene, x, y, heading) -> list:
    """For N start states of the scene's vehicles (x, y [m], heading [rad], each (N, nv) in scene order): every
    pair (vehicle, vehicle or barrier#k) with (N,) True where their outlines overlap."""
    from .geometry import rect_overlap_rows
    tol = 1e-9  # m: outlines that touch (bumper to bumper, round-off either way) do not overlap
    rects = [(v.name, (x[:, i], y[:, i], heading[:, i], v.spec.cg_to_front, v.spec.cg_to_rear, v.spec.width / 2))
             for i, v in enumerate(scene.vehicles)]
    hits = []
    for i, (ni, ri) in enumerate(rects):
        for nj, rj in rects[i + 1:]:
            hits.append((ni, nj, rect_overlap_rows(ri, rj) > tol))
        for k, b in enumerate(scene.barriers):
            rb = (b.x, b.y, b.heading, b.length / 2, b.length / 2, b.width / 2)  # barrier_outline's rectangle
            hits.append((ni, f"barrier {k}", rect_overlap_rows(ri, rb) > tol))
    return hits


APPROACH_GAP = 0.1  # m of closing travel between the outlines at the start of an approach (approach_scene)
APPROACH_MAX = 60.0  # s: the longest approach searched (vehicles that do not part by then are at rest)


def approach_time(scene: Scene, gap: float = APPROACH_GAP) -> float:
    """How long before a collision position ([impact] point, outlines overlapping) its approach starts
    (docs/physics.md §4 "Approach"): the shortest time T that, every vehicle moved back along its start velocity
    by T, parts the outlines (bisection), plus `gap` / the largest closing speed of the pairs that overlap (a
    barrier stands still), where that touches no other pair; 0 where no outlines overlap at the start. Raises
    ValueError when moving back by APPROACH_MAX does not part them (vehicles at rest)."""
    hits = start_overlaps(scene)
    if not hits:
        return 0.0
    lo, hi = 0.0, 0.01
    while start_overlaps(_moved_back(scene, hi)):
        if hi >= APPROACH_MAX:
            raise ValueError("the vehicles do not part when moved back along their velocities")
        lo, hi = hi, min(2.0 * hi, APPROACH_MAX)
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if start_overlaps(_moved_back(scene, mid)) else (lo, mid)
    vel = {v.name: (v.speed * math.cos(v.heading), v.speed * math.sin(v.heading)) for v in scene.vehicles}
    closing = max(math.hypot(vel[a][0] - vel.get(b, (0.0, 0.0))[0], vel[a][1] - vel.get(b, (0.0, 0.0))[1])
                  for a, b in hits)
    t = hi + (gap / closing if closing > 0 else 0.0)
    return hi if gap > 0.0 and start_overlaps(_moved_back(scene, t)) else t


def approach_scene(scene: Scene, gap: float = APPROACH_GAP, t: float | None = None) -> Scene:
    """A scene with a collision position as a model that finds its own contacts needs it (docs/physics.md §4
    "Approach"): the point and plane dropped and every vehicle moved back along its start velocity by
    approach_time, the duration and the driver actions that much later (a collision position's times count from
    it; t: that time where the caller has it already); driving on undisturbed, the vehicles would reach the
    collision position together. Unchanged without a given point."""
    if scene.impact.point is None:
        return scene
    return _moved_back(scene, approach_time(scene, gap) if t is None else t)


def _moved_back(scene: Scene, t: float) -> Scene:
    """The scene without its given point, every vehicle moved back along its start velocity by t [s], its
    driver actions and the duration t later (their times count from the collision position)."""
    return scene.replace(impact=dataclasses.replace(scene.impact, point=None, plane_angle=None),
                         duration=scene.duration + t,
                         vehicles=tuple(dataclasses.replace(v, x=v.x - t * v.speed * math.cos(v.heading),
                                                            y=v.y - t * v.speed * math.sin(v.heading),
                                                            actions=tuple(dataclasses.replace(a, t=a.t + t)
                                                                          for a in v.actions))
                                        for v in scene.vehicles))


def polygon_problem(points) -> str | None:
    """Why a polygon (corners in order) cannot be a zone, or None: at most ZONE_CORNERS_MAX corners, it must
    enclose an area and no two of its edges may cross or touch except neighbours at their shared corner
    (segment test by orientations)."""
    if len(points) > ZONE_CORNERS_MAX:
        return f"{len(points)} corners: at most {ZONE_CORNERS_MAX}"
    pts = [tuple(map(float, p)) for p in points]
    n = len(pts)
    area2 = sum(pts[k][0] * pts[(k + 1) % n][1] - pts[(k + 1) % n][0] * pts[k][1] for k in range(n))
    if abs(area2) < 1e-9:
        return "encloses no area"

    def orient(a, b, c):
        d = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
        return (d > 1e-12) - (d < -1e-12)

    def on_segment(a, b, c):  # c collinear with a-b: does it lie on the segment?
        return min(a[0], b[0]) - 1e-12 <= c[0] <= max(a[0], b[0]) + 1e-12 and \
            min(a[1], b[1]) - 1e-12 <= c[1] <= max(a[1], b[1]) + 1e-12

    for i in range(n):
        a, b = pts[i], pts[(i + 1) % n]
        for j in range(i + 1, n):
            if j == i + 1 or (i == 0 and j == n - 1):  # neighbours share a corner
                continue
            c, d = pts[j], pts[(j + 1) % n]
            o1, o2, o3, o4 = orient(a, b, c), orient(a, b, d), orient(c, d, a), orient(c, d, b)
            if (o1 != o2 and o3 != o4) or (o1 == 0 and on_segment(a, b, c)) or (o2 == 0 and on_segment(a, b, d)) \
                    or (o3 == 0 and on_segment(c, d, a)) or (o4 == 0 and on_segment(c, d, b)):
                return f"edges {i} and {j} cross (the polygon intersects itself)"
    return None
