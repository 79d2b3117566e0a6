"""Vehicle data: the library of vehicle files shipped with crashlab and the validated `VehicleSpec`.

Every number of a vehicle file, and of a scene's vehicle overrides (merged into the file, then checked
the same way), is a finite number (true/false are not numbers) within the physical range given in each
field's description: from a pedestrian or bicycle (50 kg, 0.2 m) to a loaded articulated truck (60 t,
30 m). Bounds that depend on other fields (axles inside the outline, the radii of gyration) are checked
together after the single fields.
"""
from __future__ import annotations

import dataclasses
import math
from importlib import resources
from pathlib import Path
from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from .errors import InputError
from .file_numbers import Real, bounded
from .input_files import check_kind, pydantic_error, read_toml
from .structure import (
    CRUSH_56_RANGE,
    CRUSH_56_SPEED,
    NO_DAMAGE_SPEED_MAX,
    NO_DAMAGE_SPEED_MIN,
    STRUCTURE_SIDES,
    StructureSection,
    crash_plot,
    structure_of,
)

MASS_RANGE = (50.0, 60000.0)  # kg: a pedestrian or bicycle .. a loaded articulated truck (EU limit 44 t)
# radius of gyration sqrt(I/m) about an axis, as a share of the diagonal of the vehicle's box in the plane
# normal to that axis: no mass distribution inside the box exceeds 1; road vehicles lie at 0.25-0.32
# (Clio: yaw 0.26, roll 0.27), a standing pedestrian near 0.3; below 0.1 is a unit slip or an inertia left
# unscaled after a mass override (it also makes the yaw mode stiff enough to stall explicit integrators)
GYRATION_SHARE = (0.1, 1.0)
# the wheels' layout against the body: the track at least TRACK_SHARE_MIN x the width (road vehicles 0.75-0.9; the
# library 0.82-0.88), the static stability factor track / 2 cg_height at least SSF_MIN (the lateral acceleration in g
# that tips the vehicle: passenger cars 1.0-1.5, NHTSA's rollover ratings, 66 FR 3388 (2001); a loaded articulated
# truck 0.35-0.5, Winkler & Ervin, UMTRI-99-19 (1999)), the wheelbase at least WHEELBASE_SHARE_MIN x the length
# (cars 0.5-0.65, a city bus 0.49). Below, a unit slip or a typo: a 1 cm track made the impulse model divide by zero
TRACK_SHARE_MIN, SSF_MIN, WHEELBASE_SHARE_MIN = 0.5, 0.3, 0.3


class _MultibodyPart(BaseModel):
    """A [multibody.*] table: the keys the 3D models read (models/common/vehicle_3d.py), typed and bounded; any
    other key is an error (a misspelt `[multibody.knuckel]` or `mas` left the default silently)."""
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)


Positive3 = tuple[Annotated[Real, Field(gt=0, le=1e7)], Annotated[Real, Field(gt=0, le=1e7)],
                  Annotated[Real, Field(gt=0, le=1e7)]]


_Axis15, _Axis2 = Annotated[Real, Field(gt=0, le=15)], Annotated[Real, Field(gt=0, le=2)]
# 2/eps of a superellipsoid: 2 is an ellipsoid, larger is boxier; below 2 the shape is not convex
_Exponent = Annotated[Real, Field(ge=2, le=20)]
ShapeExponents = tuple[_Exponent, _Exponent]


class MultibodyChassis(_MultibodyPart):
    semi_axes: tuple[_Axis15, _Axis15, _Axis15] | None = Field(
        None, description="m, contact superellipsoid about the chassis CG; each in (0, 15]")
    shape_exponents: ShapeExponents | None = Field(None, description="2/eps of the superellipsoid; each in [2, 20] "
                                                   "(convex)")
    structure_bottom: Real | None = bounded(
        0.0, 5.0, "m, height above the road of the body structure's lowest point (bumper, sill, skirt), static: the "
        "contact superellipsoid reaches down to it, its top kept (default: its own bottom, at most 0.45 m)",
        lo_open=True, default=None)
    mass: Real | None = bounded(1.0, MASS_RANGE[1], "kg, the chassis body", default=None)
    inertia: Positive3 | None = Field(None, description="kg m^2, the chassis body: Ixx, Iyy, Izz; each in (0, 1e7]")


class MultibodyWheel(_MultibodyPart):
    semi_axes: tuple[_Axis2, _Axis2, _Axis2] | None = Field(
        None, description="m, the wheel's superellipsoid about its centre; each in (0, 2]; kept for the record, not "
        "used (the 3D tyre is the torus of [multibody.tyre])")
    shape_exponents: ShapeExponents | None = Field(None, description="2/eps of the wheel's superellipsoid; each in "
                                                   "[2, 20] (convex); kept for the record, not used")
    mass: Real | None = bounded(0.0, 2000.0, "kg, one wheel", lo_open=True, default=None)
    inertia: Positive3 | None = Field(None, description="kg m^2, one wheel: Ixx, Iyy, Izz; each in (0, 1e7]")


class MultibodyKnuckle(_MultibodyPart):
    mass: Real | None = bounded(0.0, 2000.0, "kg, one knuckle", lo_open=True, default=None)


class MultibodySuspension(_MultibodyPart):
    chassis_points: tuple[tuple[Annotated[Real, Field(ge=-30, le=30)], ...], ...] | None = Field(
        None, description="m, four [x, y, z] points in the chassis frame, each coordinate in [-30, 30]")
    stiffness: Real | None = bounded(0.0, 1e8, "N/m per corner", lo_open=True, default=None)
    damping: Real | None = bounded(0.0, 1e7, "N s/m per corner", default=None)
    free_length: Real | None = bounded(0.0, 5.0, "m, unloaded strut length", lo_open=True, default=None)

    @model_validator(mode="after")
    def _four_points(self):
        pts = self.chassis_points
        if pts is not None and (len(pts) != 4 or any(len(p) != 3 for p in pts)):
            raise ValueError("chassis_points: four points [x, y, z] (FL, FR, RL, RR)")
        return self


class MultibodyTyre(_MultibodyPart):
    torus_radius_1: Real | None = bounded(0.0, 1.5, "m, major radius of the tyre torus", lo_open=True, default=None)
    torus_radius_2: Real | None = bounded(0.0, 1.5, "m, minor radius of the tyre torus", lo_open=True, default=None)
    radial_stiffness: Real | None = bounded(0.0, 1e9, "N/m, radial tyre stiffness", lo_open=True, default=None)
    longitudinal_slip_stiffness: Real | None = bounded(0.0, 1e9, "N, longitudinal slip stiffness (force per unit slip)",
                                                       lo_open=True, default=None)
    cornering_stiffness: Real | None = bounded(0.0, 1e7, "N/rad, cornering stiffness of one tyre", lo_open=True,
                                               default=None)
    camber_stiffness: Real | None = bounded(0.0, 1e7, "N/rad, camber stiffness of one tyre", default=None)
    rolling_resistance: Real | None = bounded(0.0, 1.0, "-, rolling resistance coefficient", default=None)
    radial_damping: Real | None = bounded(0.0, 1e8, "N s/m, radial tyre damping: kept for the record, not used (the "
                                          "3D models damp the tyre at 1 % of critical; models/multibody/README.md)",
                                          default=None)


class MultibodySection(_MultibodyPart):
    """[multibody] of a vehicle file (models/common/vehicle_3d.py reads it; defaults there)."""
    chassis: MultibodyChassis | None = Field(None, description="[multibody.chassis]: the chassis body")
    wheel: MultibodyWheel | None = Field(None, description="[multibody.wheel]: each of the four wheels")
    knuckle: MultibodyKnuckle | None = Field(None, description="[multibody.knuckle]: each of the four knuckles")
    suspension: MultibodySuspension | None = Field(None, description="[multibody.suspension]: the four struts")
    tyre: MultibodyTyre | None = Field(None, description="[multibody.tyre]: the tyre model of each wheel")


VEHICLE_CLASSES = ("small", "compact", "mid-size", "large", "SUV", "pickup", "van", "heavy")

# keys of a vehicle file that describe it (for people and `crashlab vehicles`) and reach no model
METADATA_KEYS = ("class", "sources")


class VehicleFile(BaseModel):
    """Schema of a vehicle file (SI units). [multibody] takes only the keys below; a third party's own section
    (a table of a name of its own) is kept as it is for the model that reads it."""

    model_config = ConfigDict(extra="allow", allow_inf_nan=False, populate_by_name=True)

    name: str = Field("", description="the vehicle's display name (make, model, year)")
    vehicle_class: Literal[VEHICLE_CLASSES] | None = Field(  # type: ignore[valid-type]
        None, alias="class", description="vehicle class of the library listing: " + ", ".join(VEHICLE_CLASSES))
    sources: dict[str, str] | None = Field(
        None, description="[sources] table: for each key of the file (a table such as multibody by its "
        "name) where its number comes from; an estimated number's entry starts with 'estimate:'")
    mass: Real = bounded(*MASS_RANGE, "kg, total")
    yaw_inertia: Real = Field(gt=0, description="kg m^2 about the vertical axis through the CG; radius of "
                              "gyration sqrt(I/m) in 0.1-1 x the diagonal of length and width")
    roll_inertia: Real = Field(gt=0, description="kg m^2 about the longitudinal axis; radius of gyration "
                               "0.1-1 x the diagonal of width and height")
    pitch_inertia: Real = Field(gt=0, description="kg m^2 about the lateral axis; radius of gyration "
                                "0.1-1 x the diagonal of length and height")
    length: Real = bounded(0.2, 30.0, "m, bumper to bumper")
    width: Real = bounded(0.2, 5.0, "m, overall width")
    height: Real = bounded(0.2, 6.0, "m, overall height")
    wheelbase: Real = Field(gt=0, description="m, front to rear axle; the axles lie inside the outline; at least "
                            "0.3 x the length")
    track: Real = Field(gt=0, description="m, centre to centre of the wheels of an axle; 0.5-1 x the width, and at "
                        "least 0.6 x cg_height (tipping over at 0.3 g)")
    cg_to_front_axle: Real = Field(gt=0, description="m, CG to front axle (horizontal); shorter than the wheelbase and "
                                  "than cg_to_front")
    cg_to_front: Real | None = Field(default=None, gt=0, description="m, CG to front bumper; default "
                                     "length / 2; shorter than the length")
    cg_height: Real = Field(ge=0, description="m, CG above the road; below the height")
    rolling_resistance: Real = bounded(0.0, 1.0, "coefficient f_r (tyres on asphalt 0.01-0.015, sand 0.3)",
                                    default=0.0)
    cornering_stiffness: Real = bounded(0.0, 1e6, "N/rad per tyre (cars 40-150e3, truck tyres to 5e5)",
                                     lo_open=True, default=60e3)
    wheel_radius: Real = bounded(0.1, 1.5, "m, rolling radius of the wheels", default=0.3)
    multibody: MultibodySection | None = Field(None, description="[multibody]: data of the 3D multibody models "
                                               "(models/common/vehicle_3d.py; defaults there)")
    structure: StructureSection | None = Field(None, description="[structure]: CRASH3 stiffness A, B of the front, "
                                               "rear and side (crashlab.damage; docs/physics.md §28); a side not "
                                               "given takes its class default")



def crush_56(A: float, B: float, w: float, mass: float) -> float:
    """m, the full-width residual crush of a 56 km/h rigid-barrier impact (CRUSH_56_SPEED) that a side of CRASH3
    stiffness A [N/m], B [N/m^2] over the width w [m] implies for a vehicle of `mass` [kg]: Campbell's crash plot
    EBS = b0 + b1 C with b0 = sqrt(2 G w / m), b1 = sqrt(B w / m) (docs/physics.md §28), C56 = (15.6 - b0) / b1."""
    b0, b1 = crash_plot(A, B, w, mass)
    return (CRUSH_56_SPEED - b0) / b1


def crush_56_problem(A: float, B: float, w: float, mass: float) -> str | None:
    """Why a side's A, B over w at `mass` is no vehicle structure (its C56 outside CRUSH_56_RANGE), else None."""
    c56, (lo, hi), (b0, b1) = crush_56(A, B, w, mass), CRUSH_56_RANGE, crash_plot(A, B, w, mass)
    if lo <= c56 <= hi:
        return None
    hint = "B too small for the mass, or not in N/m^2?" if c56 > hi else "B too large for the mass?"
    return (f"A = {A:g} N/m and B = {B:g} N/m^2 over the side's {w:g} m at {mass:g} kg give a residual crush of "
            f"{c56:.3g} m at a 56 km/h full-width rigid-barrier impact (C56 = ({CRUSH_56_SPEED:g} m/s - b0) / b1, "
            f"b0 = sqrt(2 G w / m) = {b0:.3g} m/s, b1 = sqrt(B w / m) = {b1:.3g} 1/s; docs/physics.md §28): "
            f"outside {lo:g}-{hi:g} m is no vehicle structure ({hint})")


def consistency_problems(v: VehicleFile) -> list[tuple[tuple[str, ...], str]]:
    """Bounds that join several fields: (the fields involved, the problem), first the first one checked."""
    out = []
    if v.cg_to_front_axle >= v.wheelbase:
        out.append((("cg_to_front_axle", "wheelbase"), "cg_to_front_axle must be shorter than the wheelbase"))
    front = v.length / 2 if v.cg_to_front is None else v.cg_to_front
    if front >= v.length:
        out.append((("cg_to_front", "length"), "cg_to_front must be shorter than the length"))
    elif v.cg_to_front_axle >= front or v.wheelbase - v.cg_to_front_axle >= v.length - front:
        out.append((("cg_to_front_axle", "wheelbase", "cg_to_front", "length"),
                    "the axles must lie inside the outline (cg_to_front_axle < cg_to_front and "
                    "wheelbase - cg_to_front_axle < length - cg_to_front)"))
    section, late = getattr(v, "structure", None), []
    for side in STRUCTURE_SIDES if isinstance(section, StructureSection) else ():
        given = getattr(section, side)
        limit, name = (v.length, "length") if side == "side" else (v.width, "width")
        if given is not None and given.width is not None and given.width > limit * (1 + 1e-9):
            out.append(((f"structure.{side}.width", name),
                        f"structure.{side}.width ({given.width!r} m) must not exceed the vehicle's {name} "
                        f"({limit!r} m)"))
        if given is not None:  # docs/physics.md §28: the side's G w is the vehicle's energy at this speed
            b0 = crash_plot(given.A, given.B, given.width or limit, v.mass)[0]
            speed = (f"A = {given.A:g} N/m and B = {given.B:g} N/m^2 give G = A^2/2B = "
                     f"{given.A * given.A / (2 * given.B):.4g} J/m, a no-damage speed sqrt(2 G w / m) of {b0:.3g} m/s "
                     f"over the side's {given.width or limit:g} m at {v.mass:g} kg (the speed whose energy the side "
                     f"absorbs without residual crush)")
            if not b0 <= NO_DAMAGE_SPEED_MAX:
                out.append(((f"structure.{side}.B", f"structure.{side}.A", "mass"),
                            f"{speed}: more than {NO_DAMAGE_SPEED_MAX:g} m/s is no vehicle structure (B too small "
                            f"for A?)"))
            else:  # after the other bounds: a mass or inertia they name is the likelier slip (e.g. 60 t on a car)
                problem = crush_56_problem(given.A, given.B, given.width or limit, v.mass)
                if problem:
                    late.append(((f"structure.{side}.B", f"structure.{side}.A", "mass"), problem))
                elif b0 < NO_DAMAGE_SPEED_MIN:  # B fits the mass: A alone is off (A in kN/m or lbf/in)
                    late.append(((f"structure.{side}.A", f"structure.{side}.B", "mass"),
                                 f"{speed}: less than {NO_DAMAGE_SPEED_MIN:g} m/s is no vehicle structure (A too "
                                 f"small for B: in kN/m or lbf/in, not N/m?)"))
    if v.track > v.width:
        out.append((("track", "width"), f"track ({v.track:g} m) must not exceed the width ({v.width:g} m)"))
    elif v.track < TRACK_SHARE_MIN * v.width:
        out.append((("track", "width"), f"track ({v.track:g} m) is less than {TRACK_SHARE_MIN:g} x the width "
                    f"({v.width:g} m): road vehicles have 0.75-0.9 (the wheels' centre to centre across an axle)"))
    elif v.cg_height > 0 and v.track / (2 * v.cg_height) < SSF_MIN:
        out.append((("track", "cg_height"), f"track ({v.track:g} m) and cg_height ({v.cg_height:g} m): the vehicle "
                    f"would tip over at {v.track / (2 * v.cg_height):.2g} g of lateral acceleration (track / 2 "
                    "cg_height; a loaded articulated truck 0.35-0.5, cars 1.0-1.5)"))
    if v.wheelbase < WHEELBASE_SHARE_MIN * v.length:
        out.append((("wheelbase", "length"), f"wheelbase ({v.wheelbase:g} m) is less than {WHEELBASE_SHARE_MIN:g} x "
                    f"the length ({v.length:g} m): road vehicles have 0.45-0.65"))
    if v.cg_height >= v.height:
        out.append((("cg_height", "height"), f"cg_height ({v.cg_height:g} m) must be below the height "
                    f"({v.height:g} m)"))
    lo, hi = GYRATION_SHARE
    for key, (da, db) in (("yaw_inertia", ("length", "width")), ("roll_inertia", ("width", "height")),
                          ("pitch_inertia", ("length", "height"))):
        k, diag = math.sqrt(getattr(v, key) / v.mass), math.hypot(getattr(v, da), getattr(v, db))
        if not lo * diag <= k <= hi * diag:
            out.append(((key, "mass", da, db),
                        f"{key} {getattr(v, key):g} kg m^2 with mass {v.mass:g} kg: radius of gyration "
                        f"sqrt(I/m) = {k:.3g} m lies outside {lo:g}-{hi:g} x the diagonal of {da} and {db} "
                        f"({diag:.3g} m) (an inertia in other units, or not scaled with an overridden mass?)"))
    # the 3D models' parts after the vehicle's own dimensions, which they are checked against
    return out + _multibody_problems(v, front) + late


# the 3D models' parts against the vehicle's own dimensions: a share the body may exceed its outline by, and the
# tyre torus (r1 + r2) differ from the wheel_radius by (rounding of a dimension written twice)
OUTLINE_TOL = 0.05
TORUS_RADIUS_TOL = 0.05
# [multibody] defaults that scale with the wheel, the one home of the numbers models/common/vehicle_3d.py builds
# with and the checks below use: the thesis Clio's wheel of radius MB_REFERENCE_RADIUS, 9 kg (x (R / 0.28)^3),
# its knuckle 1 kg, its tyre torus's minor radius 0.0825 m (x R / 0.28)
MB_REFERENCE_RADIUS = 0.28
MB_WHEEL_MASS, MB_KNUCKLE_MASS, MB_TORUS_R2 = 9.0, 1.0, 0.0825


def multibody_corner_masses(section: dict, wheel_radius: float) -> tuple[float, float]:
    """(wheel, knuckle) mass [kg] of one corner of the 3D models: [multibody.wheel] / [multibody.knuckle] mass,
    else the defaults."""
    sc = wheel_radius / MB_REFERENCE_RADIUS
    wheel = (section.get("wheel") or {}).get("mass", MB_WHEEL_MASS * sc ** 3)
    return float(wheel), float((section.get("knuckle") or {}).get("mass", MB_KNUCKLE_MASS))


def multibody_torus(section: dict, wheel_radius: float) -> tuple[float, float]:
    """(r1, r2) [m] of the tyre torus: [multibody.tyre] torus_radius_2, else the default; torus_radius_1, else
    the wheel_radius less r2."""
    tyre = section.get("tyre") or {}
    r2 = float(tyre.get("torus_radius_2", MB_TORUS_R2 * wheel_radius / MB_REFERENCE_RADIUS))
    return float(tyre.get("torus_radius_1", wheel_radius - r2)), r2


def unsprung_problem(section: dict, wheel_radius: float, mass: float) -> str | None:
    """Why four wheels and knuckles cannot be carried by a vehicle of `mass` (the chassis body takes the rest and
    needs at least half), None if they can."""
    wheel, knuckle = multibody_corner_masses(section, wheel_radius)
    if 4.0 * (wheel + knuckle) > 0.5 * mass:
        return (f"four wheels and knuckles of {wheel:g} + {knuckle:g} kg weigh more than half the mass "
                f"({mass:g} kg): the chassis body needs at least half")
    return None


def _multibody_problems(v, front: float) -> list[tuple[tuple[str, ...], str]]:
    """[multibody] data that contradict the vehicle's dimensions (models/common/vehicle_3d.py reads them as
    given): the chassis body (centred on the CG) and the strut mounts inside the outline, the tyre torus as large
    as the wheel, the wheels and knuckles at most half the mass. v: a VehicleFile, or a VehicleSpec (a drawn or
    searched mass, fields.with_spec), whose section is read as written."""
    if isinstance(v, VehicleFile):
        sec = v.multibody.model_dump(exclude_none=True) if v.multibody is not None else {}
    else:
        sec = v.sections.get("multibody") or {}
    out = []
    grow = 1.0 + OUTLINE_TOL
    half = {"length": min(front, v.length - front), "width": v.width / 2, "height": v.height / 2}
    for q, (axis, name) in enumerate(zip((sec.get("chassis") or {}).get("semi_axes") or (), half)):
        if axis > half[name] * grow:
            out.append((("multibody.chassis.semi_axes", name),
                        f"multibody.chassis.semi_axes[{q}] ({axis:g} m) exceeds the vehicle's half {name} "
                        f"({half[name]:g} m from the CG; the chassis body, centred on the CG, lies inside the "
                        f"outline)"))
    for q, (x, y, z) in enumerate((sec.get("suspension") or {}).get("chassis_points") or ()):
        if not (-(v.length - front) * grow <= x <= front * grow and abs(y) <= v.width / 2 * grow
                and -v.cg_height * grow <= z <= (v.height - v.cg_height) * grow):
            out.append((("multibody.suspension.chassis_points",),
                        f"multibody.suspension.chassis_points[{q}] ({x:g}, {y:g}, {z:g}) m lies outside the "
                        f"vehicle (from the CG: {-(v.length - front):g} to {front:g} m along, +-{v.width / 2:g} m "
                        f"across, {-v.cg_height:g} to {v.height - v.cg_height:g} m up)"))
    r1, r2 = multibody_torus(sec, v.wheel_radius)
    if not (r1 > 0.0 and abs(r1 + r2 - v.wheel_radius) <= TORUS_RADIUS_TOL * v.wheel_radius):
        out.append((("multibody.tyre.torus_radius_1", "multibody.tyre.torus_radius_2", "wheel_radius"),
                    f"the tyre torus, torus_radius_1 {r1:g} m + torus_radius_2 {r2:g} m, must be the wheel_radius "
                    f"({v.wheel_radius:g} m) within {TORUS_RADIUS_TOL:.0%}, each part positive (a radius not "
                    f"given: the wheel_radius less the other, or its default)"))
    # the masses where the file gives one (a 50 kg pedestrian of the planar models gives none: vehicle_3d.build
    # checks the defaults when a 3D model builds it)
    if any((sec.get(part) or {}).get("mass") is not None for part in ("wheel", "knuckle")):
        problem = unsprung_problem(sec, v.wheel_radius, v.mass)
        if problem:
            out.append((("multibody.wheel.mass", "multibody.knuckle.mass", "mass"), problem))
    return out


def _non_finite(data, path=()):
    """The first key path (tuple) in nested tables/arrays whose value is a non-finite float, or None."""
    if isinstance(data, float):
        return path if not math.isfinite(data) else None
    items = data.items() if isinstance(data, dict) else enumerate(data) if isinstance(data, list) else ()
    for k, v in items:
        hit = _non_finite(v, (*path, k))
        if hit is not None:
            return hit
    return None


@dataclasses.dataclass(frozen=True)
class VehicleSpec:
    """What every model may need to know about a vehicle (SI). `sections` holds per-model data."""

    name: str
    mass: float
    yaw_inertia: float
    roll_inertia: float
    pitch_inertia: float
    length: float
    width: float
    height: float
    wheelbase: float
    track: float
    cg_to_front_axle: float
    cg_to_front: float
    cg_height: float
    rolling_resistance: float
    cornering_stiffness: float
    wheel_radius: float
    sections: dict = dataclasses.field(default_factory=dict, compare=False, hash=False)
    # side ("front", "rear", "side") -> Structure; every side is present after load_vehicle
    structure: dict = dataclasses.field(default_factory=dict, hash=False)

    @property
    def cg_to_rear_axle(self) -> float:
        return self.wheelbase - self.cg_to_front_axle

    @property
    def cg_to_rear(self) -> float:
        return self.length - self.cg_to_front


def library() -> list[str]:
    """Names of the vehicles shipped with crashlab."""
    return sorted(p.name[:-5] for p in resources.files("crashlab").joinpath("vehicles").iterdir()
                  if p.name.endswith(".toml"))


def _deep_merge(base: dict, update: dict) -> dict:
    out = dict(base)
    for k, v in update.items():
        out[k] = _deep_merge(out[k], v) if isinstance(v, dict) and isinstance(out.get(k), dict) else v
    return out


def _has_key(data: dict, dotted: str) -> bool:
    """Whether nested tables `data` hold the key path `dotted` ("structure.front.B")."""
    for part in dotted.split("."):
        if not isinstance(data, dict) or part not in data:
            return False
        data = data[part]
    return True


def known_keys() -> list[str]:
    """The top-level keys of a vehicle file's schema (by name and by alias: `class`)."""
    fields = VehicleFile.model_fields
    return sorted(set(fields) | {f.alias for f in fields.values() if f.alias})


# difflib's similarity from which an unknown table is taken for a typo of a known key: a letter missed, added or
# swapped in structure, multibody or sources is 0.89-0.95 (`structures` 0.947, `mulitbody` 0.889); a model's own
# section of a word of its own stays below (`wheels` 0.80 to wheelbase, `inertia` 0.78, `chassis` 0.67 to class,
# `body` 0.62 to multibody: the default cutoff 0.6 took them all for typos)
TABLE_TYPO_CUTOFF = 0.85


def _close_key(key: str, cutoff: float = 0.6) -> str | None:
    """The known top-level key nearest to `key` (difflib, case ignored) with at least `cutoff` similarity."""
    import difflib
    close = difflib.get_close_matches(key.lower(), known_keys(), n=1, cutoff=cutoff)
    return close[0] if close else None


def _is_table(value) -> bool:
    """A table ([name]) or an array of tables ([[name]]): what a model's own section may be."""
    return isinstance(value, dict) or (isinstance(value, list) and bool(value)
                                       and all(isinstance(v, dict) for v in value))


def unknown_key_problem(data: dict) -> tuple[str, str] | None:
    """(key, problem) of the first top-level key of a vehicle file that its schema does not name and that is no
    model's own section: a value (`cg_to_frnt = 2.9`, `units = "us"`), or a table whose name is close to a known
    key (difflib: `[structures.front]`, a typo that silently left the class default); other tables are kept as
    sections of the models that read them ([multibody] and a third party's own), None if there is none."""
    known = set(known_keys())
    for key, value in data.items():
        if key in known:
            continue
        if _is_table(value):
            close = _close_key(key, TABLE_TYPO_CUTOFF)
            if close:
                return key, (f"unknown key; did you mean {close!r}? (a table of a name of its own is kept for a "
                             f"model that reads it; one this close to a known key is taken for a typo)")
            continue
        if key == "units":  # crashlab.file_units reads a scene's or a study's, not a vehicle file's
            return key, ("unknown key: a vehicle file is read in SI units (m, kg, N/m; docs/reference.md's unit "
                         "column); units = \"us\" is read in scene and study files")
        close = _close_key(key)
        return key, "unknown key" + (f"; did you mean {close!r}?" if close else "")
    return None


def source_key_problem(data: dict) -> tuple[str, str] | None:
    """(key, problem) of the first [sources] entry that names no key of the file: not a key of the schema, nor a
    table the file has (a model's own section); None if there is none. A typo (`wheelbse`) left the number it
    meant without a source and said nothing (a probe, 2026-11-28)."""
    sources = data.get("sources")
    if not isinstance(sources, dict):
        return None  # (not a table: the schema refuses it)
    known = set(known_keys()) - set(METADATA_KEYS)
    for key in sources:
        if key not in known and not (key in data and _is_table(data[key])):
            close = _close_key(key)
            return f"sources.{key}", ("names no key of the vehicle file (an entry says where that key's number "
                                      "comes from)" + (f"; did you mean {close!r}?" if close else ""))
    return None


def _validate(data: dict, file, prefix: str = "", overridden: dict | None = None, system: str = "si",
              given=None) -> VehicleFile:
    """VehicleFile of `data`, every bad number blamed on `file` under `prefix` (the file itself, or the
    scene's overrides: then the problem is named by an overridden key where one is involved). The file's own
    top-level keys are checked first (unknown_key_problem; the overrides' in load_vehicle). `system` and
    `given`: the units of the scene that overrides and its overrides as written (a refused bound said in them)."""
    unknown = unknown_key_problem(data) if overridden is None else None
    unknown = unknown or source_key_problem(data)
    if unknown is not None:
        raise InputError(file, prefix + unknown[0], unknown[1])
    try:
        spec = VehicleFile.model_validate(data)
    except ValidationError as err:
        raise pydantic_error(file, err, prefix, VehicleFile, system, given) from None
    hit = _non_finite(data if overridden is None else overridden)
    if hit is not None:
        raise InputError(file, prefix + ".".join(map(str, hit)), "Input should be a finite number")
    for keys, problem in consistency_problems(spec):
        if overridden is not None and "wheel_radius" in overridden and keys[0].startswith("multibody.tyre.torus"):
            continue  # the file's torus, checked with the file, is scaled to the overridden wheel (vehicle_3d.build)
        named = [k for k in keys if overridden is None or _has_key(overridden, k)]
        if system == "us":  # the checks join converted numbers: say so rather than quote them as the file's
            problem += " (numbers in SI units: the file's US values converted)"
        raise InputError(file, prefix + (named or keys)[0], problem)
    return spec


def _stiffness_sources(overrides: dict, key: str, scene_file) -> dict:
    """The overrides, a [structure.<side>] whose A or B they set without a source given one naming them (the
    vehicle file's source no longer gives the numbers used)."""
    section = overrides.get("structure")
    if not isinstance(section, dict):
        return overrides
    out = dict(section)
    for side, given in section.items():
        if isinstance(given, dict) and {"A", "B"} & set(given) and "source" not in given:
            out[side] = {**given, "source": f"overridden in {scene_file}: {key}.structure.{side}"}
    return {**overrides, "structure": out}


def load_vehicle(ref: str, base_dir: Path | None = None, overrides: dict | None = None,
                 where: str = "vehicle", scene_file: str | Path = "<scene>", system: str = "si",
                 given: dict | None = None) -> VehicleSpec:
    """A vehicle from the library by name, or from a file path (relative to `base_dir`), with overrides.
    The file is checked first (its errors name it), then the file merged with the overrides, by the same
    checks (errors name the scene file and `<where>.overrides.<key>`). A scene written in US units: `system`
    "us" and `given` its overrides as written (the overrides converted to the file units), for its errors."""
    if ref.endswith(".toml"):
        path = (base_dir or Path.cwd()) / ref
        try:
            found = path.is_file()
        except OSError as err:  # a name too long for the system (more than 255 bytes)
            raise InputError(scene_file, where, f"vehicle file {ref!r}: {err.strerror or err}") from None
        if not found:
            raise InputError(scene_file, where, f"vehicle file {ref!r} not found")
    else:
        names = library()
        if ref not in names:
            import difflib
            close = difflib.get_close_matches(ref, names, n=1)
            hint = f"; did you mean {close[0]!r}?" if close else f"; the library has {', '.join(names)}"
            raise InputError(scene_file, where, f"unknown vehicle {ref!r}{hint}")
        path = Path(str(resources.files("crashlab").joinpath("vehicles", ref + ".toml")))
    data = read_toml(path, "vehicle")
    check_kind(path, data, "vehicle")
    spec = _validate(data, path)  # the file itself first, so its own errors are blamed on it
    if overrides:
        known = set(VehicleFile.model_fields) | set(data)
        for key, val in overrides.items():
            if key not in known:
                close = _close_key(key)
                raise InputError(scene_file, f"{where}.overrides.{key}",
                                 "unknown vehicle key" + (f"; did you mean {close!r}?" if close else ""))
            if key in data and isinstance(data[key], dict) != isinstance(val, dict):
                raise InputError(scene_file, f"{where}.overrides.{key}",
                                 "a table is overridden by a table, a value by a value")
        overrides = _stiffness_sources(overrides, f"{where}.overrides", scene_file)
        data = _deep_merge(data, overrides)
        spec = _validate(data, scene_file, f"{where}.overrides.", overrides, system, given)
    core = {k: getattr(spec, k) for k in VehicleSpec.__dataclass_fields__ if k not in ("sections", "structure")}
    # per-model sections as written (not the schema's dump, which would add None for absent keys)
    sections = {k: v for k, v in data.items()
                if k not in VehicleSpec.__dataclass_fields__ and k not in METADATA_KEYS}
    core["name"] = core["name"] or ref
    if core["cg_to_front"] is None:
        core["cg_to_front"] = spec.length / 2
    return VehicleSpec(**core, sections=sections, structure=structure_of(spec))
