"""Scene files: the schema of a scene file (TOML, reconstructionist's units: m, deg, km/h), validated with
pydantic and converted once, here, into the SI Scene of crashlab.scene (its [[uncertain]] tables by
crashlab.uncertainty).
"""
from __future__ import annotations

import dataclasses
import re
from pathlib import Path
from typing import Annotated, Literal

from pydantic import AfterValidator, BaseModel, ConfigDict, Field, StrictBool, ValidationError, WrapValidator

from . import uncertainty
from .errors import InputError
from .file_numbers import Real
from .file_units import from_us, system_of
from .input_files import check_kind, pydantic_error, read_toml
from .restitution import SPEED
from .scene import (
    ANGLE_MAX,
    BARRIER_SIZE,
    DURATION_MAX,
    ENGAGEMENT_DEPTH,
    ENGAGEMENT_DEPTH_MAX,
    FRICTION_MAX,
    POSITION_MAX,
    ROAD_LINE_KINDS,
    ROAD_LINE_STYLES,
    SPEED_MAX,
    STEER_MAX,
    YAW_RATE_MAX,
    ZONE_CORNERS_MAX,
    Action,
    Barrier,
    Impact,
    Road,
    RoadLine,
    Scene,
    VehicleState,
    WheelState,
    Zone,
    given_pair,
    polygon_problem,
    start_overlaps,
)
from .units import deg_to_rad, kmh_to_ms
from .vehicle import VehicleFile, load_vehicle

Position = Annotated[Real, Field(ge=-POSITION_MAX, le=POSITION_MAX,
                                 description=f"m; |value| <= {POSITION_MAX:g}")]
Angle = Annotated[Real, Field(ge=-ANGLE_MAX, le=ANGLE_MAX, description=f"deg; |value| <= {ANGLE_MAX:g}")]


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)


class ZoneFile(_Strict):
    """A friction polygon of the road (docs/physics.md §2a): a wheel standing in it takes its friction."""
    friction: Real = Field(ge=0, le=FRICTION_MAX, description=f"tyre-road friction in the zone; [0, {FRICTION_MAX:g}]")
    polygon: list[tuple[Position, Position]] = Field(
        min_length=3, description=f"m, corners [[x, y], ...] in order (either sense); 3 to {ZONE_CORNERS_MAX}, not "
        "crossing")
    name: Name | None = Field(default=None, description="label of the zone in tables and plots; default "
                              "'zone K'")


ROAD_LINE_POINTS_MAX = 10_000


class RoadLineFile(_Strict):
    """A line on the road, drawn in every top view and animation (never simulated: it changes no result)."""
    points: list[tuple[Position, Position]] = Field(
        min_length=2, max_length=ROAD_LINE_POINTS_MAX,
        description=f"m, the polyline's points [[x, y], ...] in order; 2 to {ROAD_LINE_POINTS_MAX}")
    kind: Literal[ROAD_LINE_KINDS] = Field(
        default="edge", description="what the line marks: edge (of the carriageway), lane (a lane marking), "
        "kerb, centre (the centre line); each drawn in its own way")
    style: Literal[ROAD_LINE_STYLES] | None = Field(
        default=None, description="solid, dashed or dotted; absent: the kind's own (lane dashed, the others solid)")


class RoadFile(_Strict):
    friction: Real = Field(default=0.8, ge=0, le=FRICTION_MAX,
                           description=f"tyre-road friction coefficient; [0, {FRICTION_MAX:g}], 0 = ice")
    zones: list[ZoneFile] = Field(default_factory=list, description="friction polygons; later zones win")
    lines: list[RoadLineFile] = Field(default_factory=list, description="[[road.lines]]: edges, lane markings, "
                                      "kerbs and centre lines, drawn in top views and animations (no physics)")


def _point_or_engagement(value, handler):
    """[impact] point: a position [x, y], or the word "engagement" (docs/physics.md §4)."""
    return value if value == "engagement" else handler(value)


def _number_or_speed(value, handler):
    """[impact] restitution: a number in [0, 1], or the word "speed" (docs/physics.md §13b)."""
    if isinstance(value, str) and value != SPEED:
        raise ValueError(f'a number in [0, 1] or "{SPEED}", got {value!r}')
    return value if value == SPEED else handler(value)


def _or_word(word: str):
    """json_schema_extra of a key that also takes a word (the WrapValidators above): its JSON Schema one of the
    type's schema or that word, so that an editor checking against `crashlab schema` accepts what the loader does."""
    def extra(schema: dict) -> None:
        typed = {k: schema.pop(k) for k in list(schema) if k not in ("default", "description", "title")}
        schema["anyOf"] = typed.get("anyOf", [typed]) + [{"const": word}]
    return extra


class ImpactFile(_Strict):
    restitution: Annotated[Real, WrapValidator(_number_or_speed)] = Field(
        default=0.1, ge=0, le=1, json_schema_extra=_or_word(SPEED),
        description="coefficient of restitution; or \"speed\": a law of the closing speed "
        "at each impact (Cipriani et al. 2002, held at its ends 3.6-28.8 km/h with a warning; docs/physics.md §13b)")
    friction: Real = Field(default=0.3, ge=0, le=FRICTION_MAX,
                           description=f"vehicle-vehicle friction coefficient; [0, {FRICTION_MAX:g}]")
    law: Literal["kudlich-slibar", "brach", "routh"] = Field(
        default="kudlich-slibar", description="impulse law of the planar impulse models (docs/physics.md §3): "
        "kudlich-slibar (PC-Crash, Poisson type), brach (Newton type) or routh (friction follows the slip as it "
        "stops, sticks or reverses; energetic restitution)")
    force_law: Literal["hertz", "hunt-crossley", "lankarani-nikravesh", "flores", "gonthier",
                       "exact-restitution"] = Field(
        default="flores", description="normal contact-force law of the generic chassis contact of multibody "
        "and exudyn (their contact_law = \"generic\"; the default structure law does not use it); its damping "
        "follows the restitution")
    friction_law: Literal["coulomb", "threlfall", "ambrosio"] = Field(
        default="ambrosio", description="regularised friction law of the continuous-contact models")
    point: Annotated[tuple[Position, Position] | None, WrapValidator(_point_or_engagement)] = Field(
        default=None, json_schema_extra=_or_word("engagement"),
        description=f"m, collision position [x, y] (the impulse model's; a model that finds its own contacts runs "
        f"from its approach, docs/physics.md §4); |x|, |y| <= {POSITION_MAX:g}; or \"engagement\" "
        "(impulse model): the point and contact plane where the outlines, moved along their velocities from first "
        "touch, overlap by engagement_depth (docs/physics.md §4)")
    plane_angle: Angle | None = Field(default=None, description="deg, tangent of the contact plane")
    engagement_depth: Real = Field(default=ENGAGEMENT_DEPTH, gt=0, le=ENGAGEMENT_DEPTH_MAX,
                                   description="m, overlap of the outlines at engagement (point = \"engagement\"); "
                                   f"(0, {ENGAGEMENT_DEPTH_MAX:g}]; default 0.5 m: Campbell's linear crush at 50 "
                                   "km/h into a rigid barrier, the calibration of crush_time (docs/physics.md §4)")


def _trimmed(name: str) -> str:
    """A name without spaces at its ends: "V1 " would be a second name that looks like "V1"."""
    if name != name.strip():
        raise ValueError(f"no spaces at the start or end, got {name!r}")
    return name


Name = Annotated[str, Field(min_length=1, max_length=64, pattern=r"^[^\x00-\x1f\x7f]+$",
                            description="1-64 characters, no control characters, no spaces at its ends (it labels "
                            "tables and plots)"), AfterValidator(_trimmed)]


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
    units: Literal["si", "us"] = Field(default="si", description="the file's units: \"si\" (m, km/h, kg as every "
                                       "key's unit says) or \"us\" (ft, mph, lb: docs/reference.md's US column)")
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
    """Validate a scene given as a dict in file units and convert it to SI. An error's key names a vehicle by
    its name (vehicles.V1.overrides.mass), not its index, where the file gives the name."""
    try:
        return _scene_from_dict(data, source, base_dir)
    except InputError as err:
        key = _named_key(err.key, data)
        if key == err.key:
            raise
        raise InputError(err.file, key, err.problem) from None


def _named_key(key: str, data) -> str:
    """vehicles.<i>.rest with vehicles.<name>.rest where the i-th vehicle table has a name."""
    m = re.match(r"^vehicles\.(\d+)(\..*)?$", key)
    vehicles = data.get("vehicles") if isinstance(data, dict) else None
    if not m or not isinstance(vehicles, list) or int(m.group(1)) >= len(vehicles):
        return key
    name = vehicles[int(m.group(1))].get("name") if isinstance(vehicles[int(m.group(1))], dict) else None
    usable = isinstance(name, str) and 0 < len(name) <= 64 and name.isprintable() and m.group(2) != ".name"
    return f"vehicles.{name}{m.group(2) or ''}" if usable else key


def _overrides_given(data: dict, i: int):
    """The i-th vehicle's overrides as the file gives them (before a US file's conversion), or None."""
    vehicles = data.get("vehicles")
    entry = vehicles[i] if isinstance(vehicles, list) and i < len(vehicles) else None
    return entry.get("overrides") if isinstance(entry, dict) else None


def _scene_from_dict(data: dict, source, base_dir) -> Scene:
    given, system = data, system_of(data, source)  # (a refused bound is said in the file's units and values)
    if system == "us":  # ft, mph, lb read into the file units the checks speak (crashlab.file_units)
        data = from_us(data, SceneFile, {"overrides": VehicleFile, "uncertain": uncertainty.UncertainFile})
    try:
        f = SceneFile.model_validate(data)
    except ValidationError as err:
        raise pydantic_error(source, err, schema=SceneFile, system=system, given=given) from None
    names = [v.name for v in f.vehicles]
    for i, n in enumerate(names):
        if names.index(n) != i:
            raise InputError(source, f"vehicles.{i}.name", f"duplicate vehicle name {n!r}")
    vehicles = tuple(
        VehicleState(
            name=v.name,
            spec=load_vehicle(v.vehicle, base_dir, v.overrides, where=f"vehicles.{i}", scene_file=source,
                              system=system, given=_overrides_given(given, i)),
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
    if not engagement and "engagement_depth" in imp.model_fields_set:
        raise InputError(source, "impact.engagement_depth", 'acts only with point = "engagement" (docs/physics.md §4)')
    if engagement:
        imp = imp.model_copy(update={"point": None})
    if (imp.point is None) != (imp.plane_angle is None):
        raise InputError(source, "impact.point" if imp.point is None else "impact.plane_angle",
                         "point and plane_angle are given together or not at all")
    scene = Scene(
        name=f.name,
        vehicles=vehicles,
        road=Road(friction=f.road.friction, zones=zones,
                  lines=tuple(RoadLine(points=tuple(tuple(p) for p in ln.points), kind=ln.kind, style=ln.style)
                              for ln in f.road.lines)),
        impact=Impact(**({"restitution_law": SPEED} if imp.restitution == SPEED else
                         {"restitution": imp.restitution}),
                      friction=imp.friction, law=imp.law,
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
        scene = dataclasses.replace(scene, uncertain=uncertainty.parse(f.uncertain, scene, source))
    return scene


def load_scene(path: str | Path) -> Scene:
    """Load and validate a scene file (TOML). Bad input raises InputError (file, key, problem)."""
    path = Path(path)
    data = read_toml(path, "scene")
    check_kind(path, data, "scene")
    return scene_from_dict(data, source=path, base_dir=path.parent)

