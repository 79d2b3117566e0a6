"""A named quantity of a scene: one dotted path, its value, its range, and scenes with it changed.

The one home for "which number of a scene" (uncertain parameters, Monte Carlo, the posterior and the
search's free variables all name fields this way). Values are in FILE units (m, deg, km/h, s, kg, as a
scene file writes them); the Scene holds SI, and the conversion is made here with crashlab.units.

    road.friction                               -        tyre-road friction
    road.zones.K.friction  (also zones.K.friction)  -    friction of zone K (counted from 0)
    impact.restitution, impact.friction         -
    impact.engagement_depth                     m        (point = "engagement")
    vehicles.V.x, vehicles.V.y                  m
    vehicles.V.heading                          deg      -> rad
    vehicles.V.speed                            km/h     -> m/s
    vehicles.V.yaw_rate                         deg/s    -> rad/s
    vehicles.V.steer                            deg      -> rad (front-wheel angle at the start)
    vehicles.V.actions.K.t | ramp               s
    vehicles.V.actions.K.brake                  -        (fraction of full braking)
    vehicles.V.actions.K.steer                  deg      -> rad
    vehicles.V.mass                             kg       the vehicle's total mass
    vehicles.V.yaw_inertia                      kg m^2

V is a vehicle's name (it may contain dots: the path is read from its end). A vehicle's mass is changed
exactly as a scene's `overrides.mass` changes it (crashlab.vehicle.load_vehicle): the total mass is
replaced, the inertias and the per-model sections are kept as written, and the same consistency checks
(radius of gyration 0.1-1 x the box diagonal, crashlab.vehicle.consistency_problems) apply.

`setter(scene, paths)` resolves the paths once and returns a function row -> Scene that makes one
dataclass copy per changed vehicle, road and impact (the Monte Carlo and the searches build thousands).
"""
from __future__ import annotations

import dataclasses
import math
import re
from typing import Callable, Sequence

import numpy as np

from .scene import (
    ANGLE_MAX,
    DURATION_MAX,
    ENGAGEMENT_DEPTH_MAX,
    FRICTION_MAX,
    POSITION_MAX,
    SPEED_MAX,
    STEER_MAX,
    YAW_RATE_MAX,
    Scene,
    start_overlap_rows,
    start_overlaps,
)
from .units import deg_to_rad, kmh_to_ms, ms_to_kmh, rad_to_deg
from .vehicle import GYRATION_SHARE, MASS_RANGE, consistency_problems

VEHICLE_STATE = ("x", "y", "heading", "speed", "yaw_rate", "steer")
VEHICLE_SPEC = ("mass", "yaw_inertia")
ACTION_QUANTITIES = ("t", "brake", "steer", "ramp")
IMPACT_QUANTITIES = ("restitution", "friction", "engagement_depth")

# file unit of each quantity, and the conversion file -> SI (identity where absent)
UNITS = {"x": "m", "y": "m", "heading": "deg", "speed": "km/h", "yaw_rate": "deg/s", "steer": "deg",
         "t": "s", "ramp": "s", "brake": "-", "mass": "kg", "yaw_inertia": "kg m^2", "friction": "-",
         "restitution": "-", "engagement_depth": "m"}
_TO_SI = {"heading": deg_to_rad, "speed": kmh_to_ms, "yaw_rate": deg_to_rad, "steer": deg_to_rad}
_FROM_SI = {"heading": rad_to_deg, "speed": ms_to_kmh, "yaw_rate": rad_to_deg, "steer": rad_to_deg}
# ranges of a scene file (crashlab.scene), file units; mass, yaw_inertia and action times also depend on the
# scene (field_range)
STATIC_RANGES = {"x": (-POSITION_MAX, POSITION_MAX), "y": (-POSITION_MAX, POSITION_MAX),
                 "heading": (-ANGLE_MAX, ANGLE_MAX), "speed": (0.0, SPEED_MAX),
                 "yaw_rate": (-YAW_RATE_MAX, YAW_RATE_MAX), "steer": (-STEER_MAX, STEER_MAX),
                 "t": (0.0, DURATION_MAX), "ramp": (0.0, DURATION_MAX), "brake": (0.0, 1.0),
                 "friction": (0.0, FRICTION_MAX), "restitution": (0.0, 1.0), "mass": MASS_RANGE,
                 "engagement_depth": (1e-3, ENGAGEMENT_DEPTH_MAX),
                 "yaw_inertia": (1e-9, 1e9)}

VALID_FORMS = ("road.friction, road.zones.K.friction (or zones.K.friction), impact.restitution, impact.friction, "
               "impact.engagement_depth, "
               f"vehicles.V.{{{'|'.join(VEHICLE_STATE + VEHICLE_SPEC)}}}, "
               f"vehicles.V.actions.K.{{{'|'.join(ACTION_QUANTITIES)}}} (V a vehicle name, K counted from 0)")

_ZONE = re.compile(r"^(?:road\.)?zones\.(\d+)\.friction$")
_ACTION = re.compile(r"^vehicles\.(.+)\.actions\.(\d+)\.(t|brake|steer|ramp)$")
_VEHICLE = re.compile(rf"^vehicles\.(.+)\.({'|'.join(VEHICLE_STATE + VEHICLE_SPEC)})$")


@dataclasses.dataclass(frozen=True)
class Field:
    """A parsed path. kind: road | zone | impact | vehicle (start state) | spec (mass, yaw_inertia) |
    action; index: the zone's or action's number; path: the canonical spelling."""
    kind: str
    quantity: str
    vehicle: str | None = None
    index: int | None = None

    @property
    def path(self) -> str:
        if self.kind == "road":
            return "road.friction"
        if self.kind == "zone":
            return f"road.zones.{self.index}.friction"
        if self.kind == "impact":
            return f"impact.{self.quantity}"
        if self.kind == "action":
            return f"vehicles.{self.vehicle}.actions.{self.index}.{self.quantity}"
        return f"vehicles.{self.vehicle}.{self.quantity}"

    @property
    def unit(self) -> str:
        return UNITS[self.quantity]

    def to_si(self, value: float) -> float:
        f = _TO_SI.get(self.quantity)
        return float(value) if f is None else f(float(value))

    def from_si(self, value: float) -> float:
        f = _FROM_SI.get(self.quantity)
        return float(value) if f is None else f(float(value))

    def to_si_array(self, values) -> np.ndarray:
        """to_si of every value of an array (the population's column of this field)."""
        f = _TO_SI.get(self.quantity)
        values = np.asarray(values, dtype=float)
        return values if f is None else f(values)


def parse(path: str) -> Field:
    """The Field a path names (syntax only; `resolve` also checks that the scene has it).
    ValueError naming the valid forms for anything else."""
    if not isinstance(path, str):
        raise ValueError(f"a field is a dotted path (string), got {path!r}; valid: {VALID_FORMS}")
    if path == "road.friction":
        return Field("road", "friction")
    if path.startswith("impact.") and path[7:] in IMPACT_QUANTITIES:
        return Field("impact", path[7:])
    m = _ZONE.match(path)
    if m:
        return Field("zone", "friction", index=int(m.group(1)))
    m = _ACTION.match(path)
    if m:
        return Field("action", m.group(3), vehicle=m.group(1), index=int(m.group(2)))
    m = _VEHICLE.match(path)
    if m:
        q = m.group(2)
        return Field("spec" if q in VEHICLE_SPEC else "vehicle", q, vehicle=m.group(1))
    raise ValueError(f"unknown field {path!r}; valid: {VALID_FORMS}")


def study_path(vehicle: str | None, field: str) -> str:
    """The path of a reconstruction study's free variable (its `vehicle` and `field`: speed, actions.K.t,
    restitution, road.friction, zones.K.friction, ...)."""
    if vehicle is not None:
        return f"vehicles.{vehicle}.{field}"
    if field in IMPACT_QUANTITIES:
        return f"impact.{field}"
    return parse(field).path


def resolve(scene: Scene, path: str | Field) -> Field:
    """The Field of a path, checked against the scene: the vehicle, zone or action exists and (for an
    action's brake or steer) the action sets that value. ValueError saying what the scene has."""
    f = parse(path) if isinstance(path, str) else path
    if f.vehicle is not None and f.vehicle not in scene.vehicle_names:
        raise ValueError(f"no vehicle {f.vehicle!r} in the scene ({', '.join(scene.vehicle_names)})")
    if f.kind == "zone" and f.index >= len(scene.road.zones):
        raise ValueError(f"the scene has {len(scene.road.zones)} friction zone(s), counted from 0")
    if f.kind == "impact" and f.quantity == "engagement_depth" and not scene.impact.engagement:
        raise ValueError('impact.engagement_depth acts only with [impact] point = "engagement" (docs/physics.md §4)')
    if f.kind == "action":
        acts = scene.vehicle(f.vehicle).actions
        if f.index >= len(acts):
            raise ValueError(f"vehicle {f.vehicle!r} has {len(acts)} action(s), counted from 0")
        if getattr(acts[f.index], f.quantity) is None:
            raise ValueError(f"action {f.index} of {f.vehicle!r} sets no {f.quantity}")
    return f


def _owner(scene: Scene, f: Field):
    if f.kind == "road":
        return scene.road
    if f.kind == "zone":
        return scene.road.zones[f.index]
    if f.kind == "impact":
        return scene.impact
    v = scene.vehicle(f.vehicle)
    return v.spec if f.kind == "spec" else v.actions[f.index] if f.kind == "action" else v


def get(scene: Scene, path: str | Field) -> float:
    """The value of a field in file units."""
    f = resolve(scene, path)
    return f.from_si(getattr(_owner(scene, f), f.quantity))


def _gyration_bounds(spec, quantity: str) -> tuple[float, float]:
    """The mass (or yaw inertia) range within which every radius of gyration of the vehicle stays within
    GYRATION_SHARE of its box diagonal, the other quantities as they are (crashlab.vehicle)."""
    lo_k, hi_k = GYRATION_SHARE
    axes = (("yaw_inertia", spec.length, spec.width), ("roll_inertia", spec.width, spec.height),
            ("pitch_inertia", spec.length, spec.height))
    lo, hi = 0.0, math.inf
    for key, a, b in axes:
        d2 = a * a + b * b
        inertia = getattr(spec, key)
        if quantity == "mass":  # lo_k^2 d2 <= I/m <= hi_k^2 d2
            lo, hi = max(lo, inertia / (hi_k ** 2 * d2)), min(hi, inertia / (lo_k ** 2 * d2))
        elif key == quantity:
            lo, hi = max(lo, spec.mass * lo_k ** 2 * d2), min(hi, spec.mass * hi_k ** 2 * d2)
    return lo, hi


def field_range(scene: Scene, path: str | Field) -> tuple[float, float]:
    """The values (file units, closed interval) the field may take in this scene: the scene file's bounds,
    for a mass or yaw inertia also the radius-of-gyration bounds, for an action's time and ramp the run's
    duration and the neighbouring actions (time order, a ramp over before the next action starts)."""
    f = resolve(scene, path)
    lo, hi = STATIC_RANGES[f.quantity]
    if f.kind == "spec":
        glo, ghi = _gyration_bounds(scene.vehicle(f.vehicle).spec, f.quantity)
        lo, hi = max(lo, glo), min(hi, ghi)
    elif f.kind == "action" and f.quantity in ("t", "ramp"):
        acts = scene.vehicle(f.vehicle).actions
        a, k = acts[f.index], f.index
        nxt = acts[k + 1].t if k + 1 < len(acts) else scene.duration
        if f.quantity == "t":
            lo = max(lo, acts[k - 1].t + acts[k - 1].ramp if k else 0.0)
            hi = min(hi, nxt - a.ramp if k + 1 < len(acts) else scene.duration)
        else:
            hi = min(hi, nxt - a.t) if k + 1 < len(acts) else hi
    return lo, hi


_PLAIN: dict = {}  # class -> True when a shallow copy equals dataclasses.replace (no __post_init__, no slots)


def _copy(obj, **changes):
    """dataclasses.replace for the scene's frozen dataclasses without re-running __init__ (a third of the
    cost): the same shallow copy with the changed attributes; replace itself for a class that validates in
    __post_init__ or has slots. The setter passes only field names it resolved."""
    cls = type(obj)
    plain = _PLAIN.get(cls)
    if plain is None:
        plain = _PLAIN[cls] = not hasattr(cls, "__post_init__") and not hasattr(cls, "__slots__")
    if not plain:
        return dataclasses.replace(obj, **changes)
    new = object.__new__(cls)
    d = new.__dict__
    d.update(obj.__dict__)
    d.update(changes)
    return new


def _actions_problem(acts, duration: float) -> str | None:
    """Why changed actions are no valid sequence (the checks crashlab.scene makes of a file's, in its
    order: time order first, then the ramps), or None."""
    for k, a in enumerate(acts):
        if a.t > duration:
            return f"action {k} starts at {a.t:g} s, after the end of the run ({duration:g} s)"
        if k and a.t <= acts[k - 1].t:
            return f"action {k} at {a.t:g} s is not after action {k - 1} at {acts[k - 1].t:g} s"
    for k, a in enumerate(acts[:-1]):
        if a.t + a.ramp > acts[k + 1].t:
            return f"action {k}'s ramp ({a.ramp:g} s) reaches past action {k + 1}"
    return None


def resolve_all(scene: Scene, paths: Sequence[str | Field]) -> list[Field]:
    """The Fields of `paths` (resolve), each at most once: ValueError naming a field given twice (which value
    would win is nothing a caller should rely on)."""
    fs, seen = [], set()
    for p in paths:
        f = resolve(scene, p)
        if f.path in seen:
            raise ValueError(f"field {f.path!r} given twice")
        seen.add(f.path)
        fs.append(f)
    return fs


def setter(scene: Scene, paths: Sequence[str | Field], check: bool = True) -> Callable[[Sequence[float]], Scene]:
    """A function row -> Scene: the scene with the fields set to the row's values (file units, in the
    order of `paths`). The paths are resolved once (ValueError for an unknown path or one the scene does not
    have); each call makes one copy per changed vehicle, road and impact and of the scene.
    With `check`, a value outside field_range, actions put out of order, a mass the vehicle checks refuse, or
    start poses that put two outlines on top of each other where the scene file refuses it (no [impact] point)
    raises ValueError naming the field."""
    fs = resolve_all(scene, paths)
    ranges = [field_range(scene, f) for f in fs]
    road_i = [(i, f) for i, f in enumerate(fs) if f.kind in ("road", "zone")]
    impact_i = [(i, f.quantity) for i, f in enumerate(fs) if f.kind == "impact"]
    by_vehicle: dict[str, list] = {}
    for i, f in enumerate(fs):
        if f.vehicle is not None:
            by_vehicle.setdefault(f.vehicle, []).append((i, f))
    vindex = {n: k for k, n in enumerate(scene.vehicle_names)}
    to_si = [(_TO_SI.get(f.quantity) or float) for f in fs]
    moves_start = _moves_start(scene, fs)

    def build(row) -> Scene:
        if len(row) != len(fs):
            raise ValueError(f"{len(row)} values for {len(fs)} fields")
        vals = [float(x) for x in row]
        if check:
            for f, v, (lo, hi) in zip(fs, vals, ranges):
                if not lo <= v <= hi:  # NaN fails too
                    raise ValueError(f"{f.path} = {v:g} is outside [{lo:g}, {hi:g}] {f.unit}")
        si = [c(v) for c, v in zip(to_si, vals)]
        changes = {}
        if road_i:
            road, zones = {}, None
            for i, f in road_i:
                if f.kind == "road":
                    road["friction"] = si[i]
                else:
                    zones = list(scene.road.zones) if zones is None else zones
                    zones[f.index] = _copy(zones[f.index], friction=si[i])
            if zones is not None:
                road["zones"] = tuple(zones)
            changes["road"] = _copy(scene.road, **road)
        if impact_i:
            imp = {q: si[i] for i, q in impact_i}
            if "restitution" in imp:  # a number given replaces restitution = "speed" (docs/physics.md §13b)
                imp["restitution_law"] = "constant"
            changes["impact"] = _copy(scene.impact, **imp)
        if by_vehicle:
            vehicles = list(scene.vehicles)
            for name, items in by_vehicle.items():
                v = vehicles[vindex[name]]
                state, spec, acts = {}, {}, None
                for i, f in items:
                    if f.kind == "vehicle":
                        state[f.quantity] = si[i]
                    elif f.kind == "spec":
                        spec[f.quantity] = si[i]
                    else:
                        acts = list(v.actions) if acts is None else acts
                        acts[f.index] = _copy(acts[f.index], **{f.quantity: si[i]})
                if spec:
                    state["spec"] = with_spec(v.spec, **spec) if check else _copy(v.spec, **spec)
                if acts is not None:
                    if check:
                        why = _actions_problem(acts, scene.duration)
                        if why:
                            raise ValueError(f"vehicles.{name}.actions: {why}")
                    state["actions"] = tuple(acts)
                vehicles[vindex[name]] = _copy(v, **state)
            changes["vehicles"] = tuple(vehicles)
        new = _copy(scene, **changes)
        if check and moves_start:
            for a, b in start_overlaps(new)[:1]:
                raise ValueError(_overlap_reason(fs, vals, a, b))
        return new

    return build


# a vehicle's start pose: the fields that can put two outlines on top of each other
START_POSE = ("x", "y", "heading")


def _moves_start(scene: Scene, fs: Sequence[Field]) -> bool:
    """Whether the fields move a vehicle's start pose in a scene that must start apart (one without [impact] point,
    whose vehicles the scene file refuses to overlap at the start: crashlab.scene_file)."""
    return scene.impact.point is None and any(f.kind == "vehicle" and f.quantity in START_POSE for f in fs)


def _overlap_reason(fs: Sequence[Field], row, a: str, b: str) -> str:
    """Why a row is no valid scene: its start poses put a and b on top of each other."""
    given = ", ".join(f"{f.path} = {v:g}" for f, v in zip(fs, row) if f.kind == "vehicle" and f.quantity in START_POSE)
    return f"{given}: {a} and {b} overlap at the start"


def with_spec(spec, **changes):
    """A VehicleSpec with mass and/or yaw_inertia changed as a vehicle file's overrides change them
    (crashlab.vehicle.load_vehicle): the other quantities and the per-model sections kept as written, the
    mass within MASS_RANGE and the vehicle's consistency checks passed; ValueError otherwise."""
    new = dataclasses.replace(spec, **changes)
    if not MASS_RANGE[0] <= new.mass <= MASS_RANGE[1]:
        raise ValueError(f"mass {new.mass:g} kg is outside [{MASS_RANGE[0]:g}, {MASS_RANGE[1]:g}] kg")
    for _, problem in consistency_problems(new):  # the vehicle file's own checks (duck-typed spec)
        raise ValueError(problem)
    return new


def row_problems(scene: Scene, fs: Sequence[Field], values: np.ndarray) -> np.ndarray:
    """(N,) why each row of values (N, k; file units, in the order of `fs`) is no valid scene ("" where it
    is one): the checks `setter` makes with `check`, on whole columns (a population of variants: the ranges and
    the start poses' overlap). A mass, yaw inertia or action is checked row by row (the vehicle's consistency
    checks, crashlab.vehicle; the actions' order)."""
    values = np.asarray(values, dtype=float)
    why = np.full(len(values), "", dtype=object)
    for c, f in enumerate(fs):
        lo, hi = field_range(scene, f)
        for k in np.flatnonzero(~((values[:, c] >= lo) & (values[:, c] <= hi)) & (why == "")):  # NaN fails
            why[k] = f"{f.path} = {values[k, c]:g} is outside [{lo:g}, {hi:g}] {f.unit}"
    acts = {f.vehicle for f in fs if f.kind == "action"}
    specs = {f.vehicle for f in fs if f.kind == "spec"}
    if acts or specs:  # the rarer fields: the setter's own checks on the rows that passed the ranges
        build = setter(scene, fs, check=True)
        for k in np.flatnonzero(why == ""):
            try:
                build(values[k])
            except ValueError as err:
                why[k] = str(err)
    elif _moves_start(scene, fs):  # the start poses, on whole columns (the setter's check, row by row)
        pose = vehicle_columns(scene, fs, values, START_POSE)
        for a, b, hit in start_overlap_rows(scene, pose["x"], pose["y"], pose["heading"]):
            for k in np.flatnonzero(hit & (why == "")):
                why[k] = _overlap_reason(fs, values[k], a, b)
    return why


def vehicle_columns(scene: Scene, fs: Sequence[Field], values: np.ndarray, quantities: Sequence[str]) -> dict:
    """quantity -> (N, nv) array in SI of each vehicle's start state or spec quantity (x, y, heading, speed,
    yaw_rate, mass, yaw_inertia) in every row: the scene's value, or the row's where a field sets it."""
    values = np.asarray(values, dtype=float)
    names = scene.vehicle_names
    out = {}
    for q in quantities:
        base = [getattr(v.spec if q in VEHICLE_SPEC else v, q) for v in scene.vehicles]
        col = np.tile(np.asarray(base, dtype=float), (len(values), 1))
        for c, f in enumerate(fs):
            if f.vehicle is not None and f.quantity == q and f.kind in ("vehicle", "spec"):
                col[:, names.index(f.vehicle)] = f.to_si_array(values[:, c])
        out[q] = col
    return out


def set_fields(scene: Scene, paths: Sequence[str | Field], values: Sequence[float]) -> Scene:
    """The scene with several fields set at once (file units); see `setter`."""
    return setter(scene, paths)(values)


def set_field(scene: Scene, path: str | Field, value: float) -> Scene:
    """The scene with one field set (file units)."""
    return setter(scene, [path])([value])
