"""The structure of a vehicle's sides that can be struck: CRASH3 stiffness coefficients A, B over a width, from
the vehicle file's [structure.<side>] or the class default (docs/physics.md §28)."""
from __future__ import annotations

import dataclasses
import math

from pydantic import BaseModel, ConfigDict, Field

from .file_numbers import Real, bounded

STRUCTURE_SIDES = ("front", "rear", "side")
# the faces an impact strikes (the impact rows' "side", damage evidence; their codes 0-3 in the models:
# crashlab.models.common.crush_structure.side_code): a flank is the left (+y in vehicle axes) or the right one, and
# both have the one side structure; FACE_STRUCTURE names the structure of each (and of "side" itself)
STRUCK_FACES = ("front", "rear", "left", "right")
# and the faces of a tilted vehicle (on its side, nose or roof) a 3D model's impact may strike (codes 4, 5:
# crush_structure.face_code), which no CRASH3 structure describes: the contact and the energy split take the side
# structure for them, with a warning (docs/physics.md §13a "A tilted body"); not damage evidence
TILTED_FACES = ("roof", "underbody")
IMPACT_FACES = STRUCK_FACES + TILTED_FACES
FACE_STRUCTURE = {"front": "front", "rear": "rear", "left": "side", "right": "side", "side": "side",
                  "roof": "side", "underbody": "side"}
A_RANGE = (0.0, 2e6)   # N/m: cars 20-80e3 (front), a bus or truck front some 1e5-5e5
B_RANGE = (0.0, 5e7)   # N/m^2: cars 1e5-2e6, a bus or truck front to some 1e7
# m/s, the largest no-damage speed b0 = sqrt(2 G w / m) a side may imply (G = A^2 / 2B over its width w): tests
# bracket 2.2-4.5 m/s (SAE 2010-01-0069); a pair of A, B each in range may still give an absurd G (B -> 0)
NO_DAMAGE_SPEED_MAX = 8.0
# m/s, the least: A in kN/m or lbf/in read as N/m (b0 1000 or 175 times too small) with B right; the library's
# sides 1.3-2.4 m/s, a side's crash plot 0.9 m/s (CRUSH_REFERENCE); a plausibility bound of ours, like the largest
NO_DAMAGE_SPEED_MIN = 0.3
# m, the range of the full-width residual crush C56 = (V56 - b0) / b1 a side's crash plot (b0 above, b1 = sqrt(B w / m))
# gives at the 56 km/h rigid-barrier speed V56 (US NCAP): a plausibility bound of ours, not a published one (the
# library's estimates give 0.24-0.70 m); outside it is no vehicle structure: A and B in kN/m or lb/in read as N/m
# (C56 of 17-43 m for a 1600 kg car), or B far too stiff for the mass (docs/physics.md §28 "Limits of the input")
CRUSH_56_SPEED = 15.6
CRUSH_56_RANGE = (0.05, 2.0)
STRUCTURE_WIDTH_RANGE = (0.1, 30.0)  # m, a side's structure width


# a structure table's source: text without control characters (line breaks, tabs)
SOURCE_PATTERN = r"^[^\x00-\x1f\x7f]*$"


class StructureSideFile(BaseModel):
    """[structure.front], [structure.rear] or [structure.side]: the CRASH3 stiffness of that side."""
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)

    A: Real = bounded(*A_RANGE, "N/m, CRASH3 stiffness coefficient A: force per unit width at the onset of residual "
                   "crush (F/w = A + B C)", lo_open=True)
    B: Real = bounded(*B_RANGE, "N/m^2, CRASH3 stiffness coefficient B: force per unit width per metre of residual "
                   "crush; G = A^2 / 2B is the energy per unit width absorbed without residual crush", lo_open=True)
    width: Real | None = bounded(*STRUCTURE_WIDTH_RANGE, "m, the width over which A and B hold (the widest damage "
                                 "they apply to); default the vehicle's width for front and rear, its length for a "
                                 "side; at most that", default=None)
    source: str = Field("", description="where A and B come from; an estimated pair's source starts with "
                        "'estimate:'", pattern=SOURCE_PATTERN)


# The class defaults and the library's estimates (docs/physics.md §28): Campbell's crash plot through the
# no-damage speed b0, EBS = b0 + b1 C (C the residual crush), gives per unit of damaged width L
#     A = m b0 b1 / L,   B = m b1^2 / L,   G = m b0^2 / (2 L)
# (Campbell SAE 740565; CRASH3 Technical Manual, NHTSA DOT HS 805 732). One reference point per side:
# side -> (b0 [m/s], reference EBS [m/s], residual crush C at that EBS [m], damaged width L of the test [m] or
# None for the vehicle's width).
CRUSH_REFERENCE = {
    "front": (2.2, 15.6, 0.50, None),   # 5 mph no-damage; US NCAP 56 km/h full-width rigid barrier
    "rear": (2.2, 9.9, 0.40, None),     # FMVSS 301 30 mph 1814 kg rigid moving barrier into a 1500 kg car, e = 0
    "side": (0.9, 7.0, 0.30, 1.68),     # 2 mph; FMVSS 214-like moving deformable barrier, 1.68 m face
}
# class -> (mass [kg], width [m]): the means of the library's vehicles of each class
CLASS_REFERENCE = {"small": (971.0, 1.630), "compact": (1171.0, 1.702), "mid-size": (1544.0, 1.837),
                   "large": (1638.0, 1.850), "SUV": (1742.0, 1.796), "pickup": (1764.0, 1.842),
                   "van": (2045.0, 1.962), "heavy": (18000.0, 2.550)}
DEFAULT_CLASS = "mid-size"  # for a vehicle file without a class


def crash_plot(A: float, B: float, width: float, mass: float) -> tuple[float, float]:
    """(b0 [m/s], b1 [1/s]) of Campbell's crash plot EBS = b0 + b1 C that the stiffness A [N/m], B [N/m^2] over
    `width` [m] gives a vehicle of `mass` [kg]: b0 = sqrt(2 G w / m) (G = A^2 / 2B), b1 = sqrt(B w / m), the
    inverse of A = m b0 b1 / w, B = m b1^2 / w (docs/physics.md §28)."""
    return math.sqrt(A * A / B * width / mass), math.sqrt(B * width / mass)


def crash_plot_coefficients(side: str, mass: float, width: float) -> tuple[float, float]:
    """(A [N/m], B [N/m^2]) of the reference crash plot of `side` (CRUSH_REFERENCE) for a vehicle of `mass`
    [kg] and `width` [m] (the damaged width of a front or rear test; a side test uses its barrier's)."""
    b0, ebs, crush, test_width = CRUSH_REFERENCE[side]
    b1 = (ebs - b0) / crush
    w = test_width or width
    return mass * b0 * b1 / w, mass * b1 * b1 / w


def reference_class(vehicle_class: str | None) -> str:
    """The class whose crash plot a vehicle without [structure] takes: its own, else DEFAULT_CLASS."""
    return vehicle_class if vehicle_class in CLASS_REFERENCE else DEFAULT_CLASS


def class_structure(vehicle_class: str | None) -> dict:
    """side -> (A, B, source) of a class's default structure (docs/physics.md §28)."""
    cls = reference_class(vehicle_class)
    mass, width = CLASS_REFERENCE[cls]
    out = {}
    for side in STRUCTURE_SIDES:
        a, b = crash_plot_coefficients(side, mass, width)
        b0, ebs, crush, test_width = CRUSH_REFERENCE[side]
        out[side] = (a, b, f"estimate: class default of {cls!r}{'' if cls == vehicle_class else ' (no class given)'}"
                     f": A = m b0 b1 / L, B = m b1^2 / L with m = {mass:g} kg, L = {test_width or width:g} m, "
                     f"b0 = {b0:g} m/s, b1 = ({ebs:g} - {b0:g}) / {crush:g} m (docs/physics.md §28)")
    return out


class StructureSection(BaseModel):
    """[structure] of a vehicle file: the sides that can be struck. A side not given takes the class default
    (CLASS_STRUCTURE, docs/physics.md §28)."""
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)

    front: StructureSideFile | None = Field(None, description="[structure.front]: the front (bumper to the "
                                            "front axle and beyond)")
    rear: StructureSideFile | None = Field(None, description="[structure.rear]: the rear")
    side: StructureSideFile | None = Field(None, description="[structure.side]: either side (left and right alike)")


@dataclasses.dataclass(frozen=True)
class Structure:
    """One side's CRASH3 stiffness (docs/physics.md §28): force per unit width F/w = A + B C for a residual
    crush C, over `width` [m]; `default` when the vehicle file gave none and the class default is used, for a
    vehicle of the class's `reference_mass` [kg] (CLASS_REFERENCE)."""

    A: float       # N/m
    B: float       # N/m^2
    width: float   # m
    source: str
    default: bool = False
    reference_mass: float | None = None

    @property
    def G(self) -> float:
        """J/m, the energy per unit width absorbed without residual crush: A^2 / 2B."""
        return self.A * self.A / (2.0 * self.B)


def structure_of(v) -> dict:
    """side -> Structure of a checked vehicle file (crashlab.vehicle.VehicleFile): the file's
    [structure.<side>], else the class default."""
    defaults = class_structure(v.vehicle_class)
    out = {}
    for side in STRUCTURE_SIDES:
        given = getattr(v.structure, side) if v.structure is not None else None
        extent = v.length if side == "side" else v.width
        if given is None:
            a, b, src = defaults[side]
            out[side] = Structure(a, b, extent, src, default=True,
                                  reference_mass=CLASS_REFERENCE[reference_class(v.vehicle_class)][0])
        else:
            out[side] = Structure(given.A, given.B, extent if given.width is None else given.width,
                                  given.source or "not given")
    return out


def crush_zone(spec, face: str) -> tuple[float, str, str]:
    """(depth [m], what bounds it, what lies behind it) of the crush zone behind a struck face of a vehicle
    (crashlab.vehicle.VehicleSpec): the front or rear overhang (bumper to axle), half the width for a flank (its
    centreline), half the height for a tilted vehicle's roof or underbody. A CRASH3 line comes from crash tests
    whose crush stays within it (docs/physics.md §28 "Crush zone")."""
    if face == "front":
        return spec.cg_to_front - spec.cg_to_front_axle, "front overhang", "wheels, engine and bulkhead"
    if face == "rear":
        return spec.cg_to_rear - spec.cg_to_rear_axle, "rear overhang", "rear axle and cabin floor"
    if face in ("roof", "underbody"):
        return spec.height / 2.0, "half height", "the car's far half"
    return spec.width / 2.0, "half width", "the car's far half"


def crush_zone_warning(vehicle: str, spec, face: str, crush: float, measured: bool = False) -> str | None:
    """The warning for a crush deeper than the struck face's crush zone (crush_zone), else None: the CRASH3 line is
    then extrapolated past the structure it was measured on (docs/physics.md §28 "Crush zone")."""
    depth, what, behind = crush_zone(spec, face)
    if crush <= depth:
        return None
    tail = (f"its crush energy extrapolates the CRASH3 line past the structure it holds for; the stiffer parts "
            f"behind it ({behind}) absorb more, so the energy is likely low" if measured else
            f"the contact extrapolates the CRASH3 line past the structure it holds for; the stiffer parts behind it "
            f"({behind}) are not modelled, so the crush is likely too deep")
    return (f"{vehicle}'s {face}: {'measured ' if measured else ''}crush {crush:.2f} m is deeper than its crush zone "
            f"({what} {depth:.2f} m): {tail} (docs/physics.md §28 \"Crush zone\")")
