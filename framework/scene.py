"""The Scene: the static, immutable description of one event, in SI units.

A scene file (TOML, reconstructionist's units: m, deg, km/h) is validated with pydantic and converted
once, here, into frozen dataclasses. Variants (the optimizer makes thousands) are cheap copies made
with `Scene.with_vehicle` / `Scene.replace`.
"""
from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, Strict, StrictBool, ValidationError, WrapValidator

from .errors import InputError
from .units import deg_to_rad, kmh_to_ms
from .vehicle import VehicleSpec, load_vehicle, pydantic_error, read_toml

WheelState = Literal["rolling", "locked", "locked_after_impact", "braked"]
WHEEL_STATES = ("rolling", "locked", "locked_after_impact", "braked")


# ---------------------------------------------------------------- file schema (file units)
# Bounds of a scene file (file units). Every number is finite, a number (true/false are not), and within
# these ranges; wide enough for any road event a reconstructionist models, narrow enough that the models'
# arithmetic stays finite (a heading of 1e308 deg has no sine; a car at x = 1e30 m has no outline).
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

Real = Annotated[float, Strict()]  # int or float; never a bool or a string (NaN/inf: allow_inf_nan=False)
Position = Annotated[Real, Field(ge=-POSITION_MAX, le=POSITION_MAX,
                                 description=f"m; |value| <= {POSITION_MAX:g}")]
Angle = Annotated[Real, Field(ge=-ANGLE_MAX, le=ANGLE_MAX, description=f"deg; |value| <= {ANGLE_MAX:g}")]


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)


class ZoneFile(_Strict):
    """A friction polygon of the road (docs/physics.md §2a): a wheel standing in it takes its friction."""
    friction: Real = Field(ge=0, le=FRICTION_MAX, description=f"tyre-road friction in the zone; [0, {FRICTION_MAX:g}]")
    polygon: list[tuple[Position, Position]] = Field(
        min_length=3, description="m, corners [[x, y], ...] in order (either sense); at least three, not crossing")
    name: Name | None = Field(default=None, description="label of the zone in tables and plots; default "
                              "'zone K'")


class RoadFile(_Strict):
    friction: Real = Field(default=0.8, ge=0, le=FRICTION_MAX,
                           description=f"tyre-road friction coefficient; [0, {FRICTION_MAX:g}], 0 = ice")
    zones: list[ZoneFile] = Field(default_factory=list, description="friction polygons; later zones win")


def _point_or_engagement(value, handler):
    """[impact] point: a position [x, y], or the word "engagement" (docs/physics.md §4)."""
    return value if value == "engagement" else handler(value)


class ImpactFile(_Strict):
    restitution: Real = Field(default=0.1, ge=0, le=1, description="coefficient of restitution; [0, 1]")
    friction: Real = Field(default=0.3, ge=0, le=FRICTION_MAX,
                           description=f"vehicle-vehicle friction coefficient; [0, {FRICTION_MAX:g}]")
    law: Literal["kudlich-slibar", "brach", "routh"] = Field(
        default="kudlich-slibar", description="impulse law of the planar impulse models (docs/physics.md §3): "
        "kudlich-slibar (PC-Crash, Poisson type), brach (Newton type) or routh (friction follows the slip as it "
        "stops, sticks or reverses; energetic restitution)")
    force_law: Literal["hertz", "hunt-crossley", "lankarani-nikravesh", "flores", "gonthier",
                       "exact-restitution"] = Field(
        default="flores", description="normal contact-force law of the continuous-contact models (multibody, "
        "exudyn); its damping follows the restitution")
    friction_law: Literal["coulomb", "threlfall", "ambrosio"] = Field(
        default="ambrosio", description="regularised friction law of the continuous-contact models")
    point: Annotated[tuple[Position, Position] | None, WrapValidator(_point_or_engagement)] = Field(
        default=None, description=f"m, collision position [x, y]; |x|, |y| <= {POSITION_MAX:g}; or \"engagement\" "
        "(impulse model): the point and contact plane where the outlines, moved along their velocities from first "
        "touch, overlap by engagement_depth (docs/physics.md §4)")
    plane_angle: Angle | None = Field(default=None, description="deg, tangent of the contact plane")
    engagement_depth: Real = Field(default=ENGAGEMENT_DEPTH, gt=0, le=ENGAGEMENT_DEPTH_MAX,
                                   description="m, overlap of the outlines at engagement (point = \"engagement\"); "
                                   f"(0, {ENGAGEMENT_DEPTH_MAX:g}]; default 0.5 m: Campbell's linear crush at 50 "
                                   "km/h into a rigid barrier, the calibration of crush_time (docs/physics.md §4)")


Name = Annotated[str, Field(min_length=1, max_length=64, pattern=r"^[^\x00-\x1f\x7f]+$",
                            description="1-64 characters, no control characters (it labels tables and plots)")]


class ActionFile(_Strict):
    """A driver action (docs/physics.md §2a): from `t` on, the wheel state and/or brake and steer change;
    brake and steer move linearly from their previous values over `ramp`; each action holds until the next."""
    t: Real = Field(ge=0, le=DURATION_MAX, description=f"s, time of the action after the start; [0, {DURATION_MAX:g}]")
    wheels: WheelState | None = Field(default=None, description="wheel state from t on (docs/physics.md §2a); "
                                      "absent: unchanged")
    brake: Real | None = Field(default=None, ge=0, le=1,
                               description="fraction of full braking force without locking; [0, 1]")
    steer: Real | None = Field(default=None, ge=-STEER_MAX, le=STEER_MAX,
                               description=f"deg, front-wheel angle; |value| <= {STEER_MAX:g}")
    ramp: Real = Field(default=0.0, ge=0, le=DURATION_MAX,
                       description="s, time over which brake and steer move from their previous values")


class VehicleEntryFile(_Strict):
    name: Name = Field(description="the vehicle's name in this scene (tables, plots, studies); unique")
    vehicle: str = Field(min_length=1, description="a library name (crashlab vehicles) or a vehicle .toml path, "
                         "relative to the scene file")
    x: Position = Field(default=0.0, description="m, start position of the CG, x")
    y: Position = Field(default=0.0, description="m, start position of the CG, y")
    heading: Angle = Field(default=0.0, description="deg, start heading, counter-clockwise from +x")
    speed: Real = Field(default=0.0, ge=0, le=SPEED_MAX, description=f"km/h, start speed along the heading; "
                        f"[0, {SPEED_MAX:g}]")
    yaw_rate: Real = Field(default=0.0, ge=-YAW_RATE_MAX, le=YAW_RATE_MAX,
                           description=f"deg/s, start yaw rate, counter-clockwise; |value| <= {YAW_RATE_MAX:g}")
    wheels: WheelState = Field(default="rolling", description="wheel state at the start (docs/physics.md §2a): "
                               "rolling, locked, locked_after_impact (rolls until the first impact), braked "
                               "(ABS-like)")
    steer: Real = Field(default=0.0, ge=-STEER_MAX, le=STEER_MAX,
                        description=f"deg, front-wheel steer angle at the start; |value| <= {STEER_MAX:g}")
    overrides: dict = Field(default_factory=dict, description="vehicle-file keys: checked as the vehicle file")
    actions: list[ActionFile] = Field(default_factory=list, description="driver actions, in time order")


class BarrierFile(_Strict):
    x: Position = Field(description="m, centre of the barrier, x")
    y: Position = Field(description="m, centre of the barrier, y")
    heading: Angle = Field(default=0.0, description="deg, direction of the barrier's length, counter-clockwise "
                           "from +x")
    length: Real = Field(ge=BARRIER_SIZE[0], le=BARRIER_SIZE[1],
                         description=f"m, along the heading; [{BARRIER_SIZE[0]:g}, {BARRIER_SIZE[1]:g}]")
    width: Real = Field(ge=BARRIER_SIZE[0], le=BARRIER_SIZE[1],
                        description=f"m, across the heading; [{BARRIER_SIZE[0]:g}, {BARRIER_SIZE[1]:g}]")


class ReferenceFile(_Strict):
    """A published result for one vehicle: rest pose and velocity at rest/end (file units)."""
    x: Position | None = Field(default=None, description="m, published rest (end) position of the CG, x")
    y: Position | None = Field(default=None, description="m, published rest (end) position of the CG, y")
    heading: Angle | None = Field(default=None, description="deg, published rest (end) heading")
    vx: Real | None = Field(default=None, ge=-SPEED_MAX, le=SPEED_MAX,
                            description="km/h, published velocity at the end, x (global)")
    vy: Real | None = Field(default=None, ge=-SPEED_MAX, le=SPEED_MAX,
                            description="km/h, published velocity at the end, y (global)")
    yaw_rate: Real | None = Field(default=None, ge=-YAW_RATE_MAX, le=YAW_RATE_MAX,
                                  description="deg/s, published yaw rate at the end")


class SceneFile(_Strict):
    name: str = Field(default="scene", description="title of the scene in tables and plots")
    duration: Real = Field(default=10.0, gt=0, le=DURATION_MAX,
                           description=f"s, longest simulated time; (0, {DURATION_MAX:g}]")
    stop_at_rest: StrictBool = Field(default=True, description="end the run when every vehicle is at rest")
    road: RoadFile = Field(default=RoadFile(), description="[road]: the road's friction and friction zones")
    impact: ImpactFile = Field(default=ImpactFile(), description="[impact]: the collision's coefficients, "
                               "laws and (optionally) its given position")
    vehicles: list[VehicleEntryFile] = Field(min_length=1, description="[[vehicles]]: each vehicle and its "
                                             "start state")
    barriers: list[BarrierFile] = Field(default_factory=list, description="[[barriers]]: fixed rectangular "
                                        "obstacles (walls, posts) a vehicle may hit")
    # published results to compare with: reference.<source>.<vehicle> = {x, y, heading, vx, vy, yaw_rate}
    reference: dict[str, dict[str, ReferenceFile]] = Field(
        default_factory=dict, description="published results to compare with (crashlab compare): "
        "reference.<source>.<vehicle>")
    # uncertain parameters (crashlab.uncertainty): [[uncertain]] field, distribution and its parameters;
    # checked against the scene in scene_from_dict; they do not change the simulation of the scene itself
    uncertain: list[dict] = Field(default_factory=list, description="[[uncertain]]: parameters drawn by "
                                  "simulate --monte-carlo and varied by crashlab infer (each table below)")


# ---------------------------------------------------------------- the scene (SI)
@dataclasses.dataclass(frozen=True)
class Zone:
    """A friction polygon (SI): corners as ((x, y), ...), counter-clockwise or clockwise."""
    friction: float
    polygon: tuple[tuple[float, float], ...]
    name: str = ""


@dataclasses.dataclass(frozen=True)
class Road:
    friction: float = 0.8
    zones: tuple[Zone, ...] = ()  # later zones win where zones overlap


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
    restitution: float = 0.1
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
    from .geometry import penetration
    outlines = [(v.name, vehicle_outline(v)) for v in scene.vehicles]
    hits = []
    for i, (ni, ci) in enumerate(outlines):
        for nj, cj in outlines[i + 1:]:
            if penetration(ci, cj)[0] > 0:
                hits.append((ni, nj))
        for k, b in enumerate(scene.barriers):
            if penetration(ci, barrier_outline(b))[0] > 0:
                hits.append((ni, f"barrier {k}"))
    return hits


def polygon_problem(points) -> str | None:
    """Why a polygon (corners in order) cannot be a zone, or None: it must enclose an area and no two of its
    edges may cross or touch except neighbours at their shared corner (segment test by orientations)."""
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


def _actions(v, i: int, duration: float, source) -> tuple[Action, ...]:
    """The vehicle's actions in SI, checked: in time order, within the run, each changing something, each
    ramp over before the next action starts."""
    acts = v.actions
    for k, a in enumerate(acts):
        key = f"vehicles.{i}.actions.{k}"
        if a.wheels is None and a.brake is None and a.steer is None:
            raise InputError(source, key, "an action sets wheels, brake and/or steer; this one sets none")
        if a.t > duration:
            raise InputError(source, f"{key}.t", f"t = {a.t:g} s is after the end of the run (duration "
                             f"{duration:g} s)")
        if k and a.t <= acts[k - 1].t:
            raise InputError(source, f"{key}.t", f"actions out of time order: t = {a.t:g} s is not after "
                             f"the previous action's t = {acts[k - 1].t:g} s")
    for k, a in enumerate(acts):
        key = f"vehicles.{i}.actions.{k}"
        if k + 1 < len(acts) and a.t + a.ramp > acts[k + 1].t:
            raise InputError(source, f"{key}.ramp", f"ramp = {a.ramp:g} s is longer than the {acts[k + 1].t - a.t:g}"
                             " s to the next action")
    return tuple(Action(t=a.t, wheels=a.wheels, brake=a.brake, ramp=a.ramp,
                        steer=None if a.steer is None else deg_to_rad(a.steer)) for a in acts)


def scene_from_dict(data: dict, source: str | Path = "<scene>", base_dir: Path | None = None) -> Scene:
    """Validate a scene given as a dict in file units and convert it to SI."""
    try:
        f = SceneFile.model_validate(data)
    except ValidationError as err:
        raise pydantic_error(source, err) from None
    names = [v.name for v in f.vehicles]
    for i, n in enumerate(names):
        if names.index(n) != i:
            raise InputError(source, f"vehicles.{i}.name", f"duplicate vehicle name {n!r}")
    vehicles = tuple(
        VehicleState(
            name=v.name,
            spec=load_vehicle(v.vehicle, base_dir, v.overrides, where=f"vehicles.{i}", scene_file=source),
            x=v.x, y=v.y, heading=deg_to_rad(v.heading), speed=kmh_to_ms(v.speed),
            yaw_rate=deg_to_rad(v.yaw_rate), wheels=v.wheels, steer=deg_to_rad(v.steer),
            actions=_actions(v, i, f.duration, source))
        for i, v in enumerate(f.vehicles))
    for k, z in enumerate(f.road.zones):
        why = polygon_problem(z.polygon)
        if why:
            raise InputError(source, f"road.zones.{k}.polygon", why)
    zones = tuple(Zone(friction=z.friction, polygon=tuple(tuple(p) for p in z.polygon), name=z.name or f"zone {k}")
                  for k, z in enumerate(f.road.zones))
    imp = f.impact
    engagement = imp.point == "engagement"
    if engagement and imp.plane_angle is not None:
        raise InputError(source, "impact.plane_angle", 'not with point = "engagement" (the plane follows the overlap)')
    if engagement:
        imp = imp.model_copy(update={"point": None})
    if (imp.point is None) != (imp.plane_angle is None):
        raise InputError(source, "impact.point" if imp.point is None else "impact.plane_angle",
                         "point and plane_angle are given together or not at all")
    scene = Scene(
        name=f.name,
        vehicles=vehicles,
        road=Road(friction=f.road.friction, zones=zones),
        impact=Impact(restitution=imp.restitution, friction=imp.friction, law=imp.law,
                      force_law=imp.force_law, friction_law=imp.friction_law,
                      point=None if imp.point is None else tuple(imp.point),
                      plane_angle=None if imp.plane_angle is None else deg_to_rad(imp.plane_angle),
                      engagement=engagement, engagement_depth=imp.engagement_depth),
        barriers=tuple(Barrier(b.x, b.y, deg_to_rad(b.heading), b.length, b.width) for b in f.barriers),
        duration=f.duration,
        stop_at_rest=f.stop_at_rest,
        source=str(source),
        references={src: {n: r.model_dump(exclude_none=True) for n, r in rows.items()}
                    for src, rows in f.reference.items()},
    )
    for src, rows in f.reference.items():
        for vname in rows:
            if vname not in names:
                raise InputError(source, f"reference.{src}.{vname}", "no vehicle of that name")
    if imp.point is not None:
        try:
            given_pair(scene)
        except ValueError as err:
            raise InputError(source, "impact.point", str(err)) from None
    else:
        hits = start_overlaps(scene)
        if hits:
            a, b = hits[0]
            raise InputError(source, "vehicles", f"{a} and {b} overlap at the start; move them apart or "
                             "give [impact] point and plane_angle (collision position)")
    if f.uncertain:
        from .uncertainty import parse as parse_uncertain
        scene = dataclasses.replace(scene, uncertain=parse_uncertain(f.uncertain, scene, source))
    return scene


def load_scene(path: str | Path) -> Scene:
    """Load and validate a scene file (TOML). Bad input raises InputError (file, key, problem)."""
    path = Path(path)
    return scene_from_dict(read_toml(path, "scene"), source=path, base_dir=path.parent)

