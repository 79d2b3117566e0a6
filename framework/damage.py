"""Damage analysis (CRASH3): crush energy from a measured crush profile, the energy equivalent speed (EES) and,
for two vehicles, the delta-V from their energies and masses (docs/physics.md §28).

A crush profile is n = 2, 4 or 6 residual crush depths C1..Cn [m], measured at equal spacing over the damaged
width L [m] of one side of the vehicle (front, rear, left or right), from left to right seen from outside the vehicle
(the order only matters for the centroid of the damage). The side's CRASH3 stiffness A [N/m], B [N/m^2] comes
from the vehicle file's [structure] (crashlab.structure.Structure; the class default when the file gives none).

Conventions (those of the impact rows, docs/physics.md §21): PDOF in degrees in vehicle axes, the direction
the force comes from, 0 = from straight ahead, counter-clockwise positive (+90 from the left); the damage
offset [m] is the position of the centre of the damaged width: for the front and rear, to the left of the
vehicle's centreline (positive left); for a flank, ahead of the CG (positive forward). Both flanks have the side
structure ([structure.side]); `report` also takes side = "side" with a PDOF, the flank it points at (left for
PDOF > 0); damage evidence names its flank (the impact rows tell them apart).

Damage as evidence: `DamageEvidence` ([evidence.damage.<vehicle>] of a study file), `damage_ees` (the EES from
the damage and its sigma), `damage_residual` (simulated against measured, in sigma units).

Only the core is imported (crashlab.errors, crashlab.vehicle, crashlab.units).
"""
from __future__ import annotations

import math
import numbers
from collections.abc import Sequence
from typing import Annotated, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, Strict, field_validator

from .errors import InputError
from .structure import FACE_STRUCTURE, STRUCK_FACES, Structure, crush_zone_warning
from .units import kmh_to_ms, ms_to_kmh, wrap_deg
from .vehicle import VehicleSpec

PROFILE_POINTS = (2, 4, 6)  # the CRASH3 measurement protocols
DAMAGE_WIDTH_MIN = 0.1  # m, the narrowest damaged width (the structure width's lower bound, crashlab.structure)
PDOF_LIMIT = 45.0  # deg: the largest angle between the force and the side's normal the correction is used for
# deg: the direction the force comes from when it is normal to the side (vehicle axes, docs/physics.md §21)
SIDE_NORMAL = {"front": 0.0, "rear": 180.0, "left": 90.0, "right": -90.0, "side": 90.0}
# the delta-method sigma of damage evidence holds for a relative stiffness error up to about 0.3 and crush
# errors small beside the crush (docs/physics.md §28): (sigma_stiffness, sigma_crush / mean crush) limits
SIGMA_FIRST_ORDER = (0.3, 0.5)


# ---------------------------------------------------------------- checks of the inputs
def finite_number(value, key: str, where: str) -> float:
    # any real number (numpy's too: numbers.Real), not a boolean (numpy's is no numbers.Real)
    if isinstance(value, bool) or not isinstance(value, numbers.Real) or not math.isfinite(value):
        raise InputError(where, key, f"must be a finite number, got {value!r}")
    return float(value)


def check_profile(profile: Sequence[float], key: str = "profile", where: str = "damage") -> list[float]:
    """The profile as floats: 2, 4 or 6 finite, non-negative depths [m] of at most 5 m; InputError otherwise
    (all zero is allowed: `report` warns that its EES is an upper bound). A 1-D numpy array is a list."""
    if isinstance(profile, np.ndarray) and profile.ndim == 1:
        profile = profile.tolist()
    if isinstance(profile, (str, bytes)) or not isinstance(profile, Sequence):
        raise InputError(where, key, f"a list of {', '.join(map(str, PROFILE_POINTS))} crush depths [m]")
    if len(profile) not in PROFILE_POINTS:
        n = len(profile)
        raise InputError(where, key, f"{n} crush depth{'' if n == 1 else 's'} given: CRASH3 uses 2, 4 or 6 equally "
                         "spaced points over the damaged width")
    out = [finite_number(c, f"{key}[{i + 1}]", where) for i, c in enumerate(profile)]
    for i, c in enumerate(out):
        if c < 0:
            raise InputError(where, f"{key}[{i + 1}]", f"crush depth {c:g} m is negative (residual crush is "
                             "measured inwards from the undamaged outline)")
    if max(out) > 5.0:
        raise InputError(where, key, f"crush depth {max(out):g} m: more than 5 m is not a crush depth in metres")
    return out


def _argument(ok: bool, name: str, value, what: str) -> None:
    """ValueError naming the argument of a law below called with a value outside its domain (no file, no key:
    `report` and the command line check their inputs with InputError first)."""
    if not ok:
        raise ValueError(f"{name} = {value!r}: {what}")


def _segments(profile: Sequence[float], width: float) -> None:
    """The laws' profile: at least 2 finite depths >= 0 [m] over a finite width > 0 [m]."""
    _argument(len(profile) >= 2 and all(math.isfinite(c) and c >= 0.0 for c in profile), "profile", profile,
              "at least 2 finite crush depths >= 0 [m]")
    _argument(math.isfinite(width) and width > 0.0, "width", width, "a finite damaged width > 0 [m]")


def _stiffness(A: float, B: float) -> None:
    _argument(math.isfinite(A) and A >= 0.0, "A", A, "a finite stiffness A >= 0 [N/m]")
    _argument(math.isfinite(B) and B > 0.0, "B", B, "a finite stiffness B > 0 [N/m^2]")


def _side(side: str, where: str, key: str = "side") -> str:
    if side not in SIDE_NORMAL:
        raise InputError(where, key, f"unknown side {side!r}: one of {', '.join(SIDE_NORMAL)} (side: the flank the "
                         "PDOF points at)")
    return side


# ---------------------------------------------------------------- the laws (docs/physics.md §28)
def flank_sign(side: str, pdof_deg: float) -> float:
    """+1 for the left flank, -1 for the right; side = "side": the flank the PDOF points at (left for PDOF >= 0)."""
    if side in ("left", "right"):
        return 1.0 if side == "left" else -1.0
    return 1.0 if wrap_deg(pdof_deg) >= 0 else -1.0


def pdof_angle(side: str, pdof_deg: float | None) -> float:
    """Angle [deg] between the force and the normal of the struck side; a flank's normal is +90 (left) or -90
    (right, `flank_sign`)."""
    _argument(side in SIDE_NORMAL, "side", side, f"one of {', '.join(SIDE_NORMAL)}")
    if pdof_deg is None:
        return 0.0
    normal = SIDE_NORMAL[side] if side in ("front", "rear") else 90.0 * flank_sign(side, pdof_deg)
    return wrap_deg(pdof_deg - normal)


def pdof_factor(alpha_deg: float, key: str = "pdof", where: str = "damage") -> tuple[float, str | None]:
    """CRASH3's correction of the crush energy for a force oblique to the damaged surface, 1 + tan^2(alpha),
    and a warning or None. The correction is used up to |alpha| = 45 deg, where it reaches 2; beyond, the
    tangential force would exceed what friction in the crush zone can carry, and the factor is held at 2
    (the limit McHenry gives for the revised energy correction factor) with a warning. A force more than
    90 deg off the normal pulls the side outwards and cannot have crushed it: InputError."""
    a = abs(finite_number(alpha_deg, key, where))
    if a >= 90.0 - 1e-9:
        raise InputError(where, key, f"the force is {a:.1f} deg off the normal of the struck side: it cannot have "
                         "crushed this side (check the side and the PDOF: vehicle axes, the direction the force "
                         "comes from, 0 = from straight ahead, +90 = from the left)")
    if a <= PDOF_LIMIT + 1e-9:
        return 1.0 + math.tan(math.radians(alpha_deg)) ** 2, None
    return 2.0, (f"the force is {a:.1f} deg off the normal of the struck side: the CRASH3 PDOF correction "
                 f"1 + tan^2 is held at its {PDOF_LIMIT:g} deg value 2 (beyond, friction in the crush zone cannot "
                 "carry the tangential force the correction assumes); the energy is uncertain here (it depends on how "
                 "far the surfaces slid)")


def profile_moments(profile: Sequence[float], width: float) -> tuple[float, float]:
    """(S1 [m²], S2 [m³]): the integrals over the width of C and of C² / 2 for a profile of n equally spaced
    depths, the crush linear between the points: per segment of width d between depths Ci, Cj,
    d (Ci + Cj) / 2 and d (Ci² + Ci Cj + Cj²) / 6 (crush_energy, crashlab.stiffness)."""
    _segments(profile, width)
    d = width / (len(profile) - 1)
    pairs = list(zip(profile[:-1], profile[1:]))
    return (sum(d * (ci + cj) / 2.0 for ci, cj in pairs),
            sum(d * (ci * ci + ci * cj + cj * cj) / 6.0 for ci, cj in pairs))


def crush_energy(profile: Sequence[float], width: float, A: float, B: float) -> float:
    """J, CRASH3 crush energy of a profile of n equally spaced depths over `width` [m], without the PDOF
    correction: the integral over the width of A C + B C^2 / 2 + G (G = A^2 / 2B), the crush linear between the
    points: A S1 + B S2 + G width (profile_moments)."""
    _stiffness(A, B)
    s1, s2 = profile_moments(profile, width)
    return A * s1 + B * s2 + A * A / (2.0 * B) * width


def crush_centroid(profile: Sequence[float], width: float) -> tuple[float, float]:
    """(lateral position of the centroid of the crushed area from the centre of the damaged width, in the
    direction of C1 -> Cn [m]; its depth below the undamaged outline [m]); an all-zero profile: (0, 0)."""
    _segments(profile, width)
    n = len(profile)
    d = width / (n - 1)
    area = s_lat = s_depth = 0.0
    for k, (ci, cj) in enumerate(zip(profile[:-1], profile[1:])):
        a = d * (ci + cj) / 2.0
        if a <= 0.0:
            continue
        x0 = -width / 2.0 + k * d
        s_lat += d * d * (ci + 2.0 * cj) / 6.0 + x0 * a        # first moment of the trapezoid about x = 0
        s_depth += d * (ci * ci + ci * cj + cj * cj) / 6.0     # first moment about the outline (depth)
        area += a
    return (s_lat / area, s_depth / area) if area > 0.0 else (0.0, 0.0)


def ees(energy: float, mass: float) -> float:
    """m/s, energy equivalent speed sqrt(2 E / m) (docs/physics.md §21, §28)."""
    _argument(math.isfinite(energy) and energy >= 0.0, "energy", energy, "a finite energy >= 0 [J]")
    _argument(math.isfinite(mass) and mass > 0.0, "mass", mass, "a finite mass > 0 [kg]")
    return math.sqrt(2.0 * energy / mass)


def effective_mass_factor(yaw_inertia: float, mass: float, moment_arm: float) -> float:
    """gamma = k^2 / (k^2 + h^2): the share of the mass an eccentric impulse with moment arm h [m] about the
    CG acts on (k^2 = I / m) (CRASH3; Brach, Vehicle Accident Analysis and Reconstruction Methods)."""
    _argument(math.isfinite(yaw_inertia) and yaw_inertia > 0.0, "yaw_inertia", yaw_inertia, "finite and > 0 [kg m^2]")
    _argument(math.isfinite(mass) and mass > 0.0, "mass", mass, "a finite mass > 0 [kg]")
    _argument(math.isfinite(moment_arm), "moment_arm", moment_arm, "a finite moment arm [m]")
    k2 = yaw_inertia / mass
    return k2 / (k2 + moment_arm * moment_arm)


# the largest restitution published for vehicle impacts: about 0.5 at the lowest closing speeds (Cipriani et al.
# 2002, SAE 2002-01-0540: 0.475 at 1 m/s; Howard et al. 1993, SAE 931842: 0.2-0.4 at delta-V 2-5 mph); beyond it the
# delta-V from a crush energy, which grows as sqrt((1 + e) / (1 - e)), rests on no vehicle data (docs/physics.md §28)
RESTITUTION_PUBLISHED_MAX = 0.5


def pair_delta_v(e_total: float, m1: float, m2: float, gamma1: float = 1.0, gamma2: float = 1.0,
                 restitution: float = 0.0) -> tuple[float, float]:
    """m/s, (dV1, dV2): the CG speed changes of two vehicles whose crush absorbed e_total [J] together, from
    the impulse P = sqrt(2 E mu (1 + e) / (1 - e)) along the PDOF, mu = M1 M2 / (M1 + M2) with the effective
    masses M = gamma m; dV = P / m. For e = 0 and gamma = 1: dV1 = sqrt(2 E m2 / (m1 (m1 + m2)))."""
    if not 0.0 <= restitution < 1.0:
        raise InputError("damage", "restitution", f"{restitution:g}: must lie in [0, 1)")
    _argument(math.isfinite(e_total) and e_total >= 0.0, "e_total", e_total, "a finite energy >= 0 [J]")
    for name, value in (("m1", m1), ("m2", m2)):
        _argument(math.isfinite(value) and value > 0.0, name, value, "a finite mass > 0 [kg]")
    for name, value in (("gamma1", gamma1), ("gamma2", gamma2)):
        _argument(0.0 < value <= 1.0, name, value, "an effective-mass factor in (0, 1]")
    M1, M2 = gamma1 * m1, gamma2 * m2
    mu = M1 * M2 / (M1 + M2)
    impulse = math.sqrt(2.0 * e_total * mu * (1.0 + restitution) / (1.0 - restitution))
    return impulse / m1, impulse / m2


# ---------------------------------------------------------------- one vehicle's damage
def _geometry(spec: VehicleSpec, side: str, offset: float, alpha_deg: float, pdof_deg: float,
              lateral: float, depth: float) -> float:
    """m, the moment arm about the CG of the force through the centroid of the damage along the PDOF."""
    if side == "front":
        # C1 -> Cn runs from right to left seen from ahead (left to right seen from outside, facing the car)
        px, py = spec.cg_to_front - depth, offset + lateral
    elif side == "rear":
        px, py = -spec.cg_to_rear + depth, offset - lateral
    else:
        flank = flank_sign(side, pdof_deg)
        px, py = offset - flank * lateral, flank * (spec.width / 2.0 - depth)
    th = math.radians(pdof_deg)
    ux, uy = -math.cos(th), -math.sin(th)  # the force's direction (it comes from the PDOF)
    return abs(px * uy - py * ux)


def report(spec: VehicleSpec, side: str, profile: Sequence[float], width: float, offset: float = 0.0,
           pdof: float | None = None, where: str = "damage", prefix: str = "") -> dict:
    """One vehicle's damage: the crush energy (with the PDOF correction), EES and the effective-mass factor of
    the force through the damage centroid, as a JSON-serialisable dict (SI, speeds also in km/h). Bad input:
    InputError naming `where` (the scene, study or vehicle file, or "command line") and the key, `prefix` +
    side, profile, width, offset or pdof (e.g. prefix "--" on the command line, "evidence.damage.V1." in a
    study file)."""
    side = _side(side, where, prefix + "side")
    profile = check_profile(profile, prefix + "profile", where)
    width = finite_number(width, prefix + "width", where)
    offset = finite_number(offset, prefix + "offset", where)
    flank = FACE_STRUCTURE[side] == "side"
    structure: Structure = spec.structure[FACE_STRUCTURE[side]]
    limit, what = (spec.length, "length") if flank else (spec.width, "width")
    depth_limit, across = (spec.width, "width") if flank else (spec.length, "length")
    for i, c in enumerate(profile):
        if c >= depth_limit:
            raise InputError(where, f"{prefix}profile[{i + 1}]", f"crush depth {c:g} m is deeper than the vehicle's "
                             f"{across} {depth_limit:g} m across its {side}")
    if not DAMAGE_WIDTH_MIN <= width <= structure.width * (1 + 1e-9):
        raise InputError(where, prefix + "width", f"damaged width {width:g} m must be at least "
                         f"{DAMAGE_WIDTH_MIN:g} m (a CRASH3 profile is measured over a damaged width; a pole's is "
                         f"some 0.3 m) and at most the {side}'s structure width {structure.width:g} m (the "
                         f"vehicle's {what} {limit:g} m)")
    if flank:
        lo, hi = -spec.cg_to_rear, spec.cg_to_front
    else:
        lo, hi = -spec.width / 2.0, spec.width / 2.0
    if offset - width / 2.0 < lo - 1e-9 or offset + width / 2.0 > hi + 1e-9:
        raise InputError(where, prefix + "offset", f"the damage ({width:g} m wide about {offset:g} m) reaches "
                         f"outside the {side} ({lo:g} .. {hi:g} m from the "
                         f"{'CG' if flank else 'centreline'})")
    if pdof is not None:
        pdof = finite_number(pdof, prefix + "pdof", where)
        if not -180.0 <= pdof <= 180.0:  # (as [evidence.damage.V] holds it)
            raise InputError(where, prefix + "pdof", f"{pdof:g} deg: the PDOF lies in [-180, 180] deg")
    if side == "side" and pdof is None:  # the flank sets the moment arm (and so gamma and the delta-V)
        raise InputError(where, prefix + "pdof", "side \"side\" takes the flank the PDOF points at: give the PDOF, "
                         "or the side as left or right")
    pdof_used = SIDE_NORMAL[side] if pdof is None else pdof
    alpha = pdof_angle(side, pdof_used) + 0.0  # no -0
    factor, warning = pdof_factor(alpha, prefix + "pdof", where)
    e0 = crush_energy(profile, width, structure.A, structure.B)
    energy = e0 * factor
    lateral, depth = crush_centroid(profile, width)
    arm = _geometry(spec, side, offset, alpha, pdof_used, lateral, depth)
    gamma = effective_mass_factor(spec.yaw_inertia, spec.mass, arm)
    speed = ees(energy, spec.mass)
    warnings = [warning] if warning else []
    if structure.reference_mass and not 0.5 <= spec.mass / structure.reference_mass <= 2.0:
        warnings.append(f"the {side}'s stiffness is the class default, a crash plot of a {structure.reference_mass:g} "
                        f"kg vehicle, and this one is {spec.mass:g} kg: the crush energy is off by about their "
                        f"ratio (docs/physics.md §28); give the vehicle file's [structure.{FACE_STRUCTURE[side]}] or "
                        "its class")
    deep = crush_zone_warning(spec.name, spec, side, max(profile), measured=True)
    if deep:
        warnings.append(deep)
    if ees_is_upper_bound(profile):
        warnings.append("no residual crush: the CRASH3 energy is then G L, the most the side absorbs without "
                        "residual crush (docs/physics.md §28); the energy lies anywhere from 0 to it, so the EES "
                        "is an upper bound, not a measurement (as evidence it is scored one-sided)")
    return {
        "vehicle": spec.name, "mass": spec.mass, "side": side,
        # the flank of a side impact (side = "side": the one the PDOF points at), None for a front or rear
        "flank": ("left" if flank_sign(side, pdof_used) > 0 else "right") if flank else None,
        "profile": profile, "width": width,
        "offset": offset, "pdof": pdof_used, "pdof_angle": alpha, "pdof_factor": factor,
        "A": structure.A, "B": structure.B, "G": structure.G, "structure_width": structure.width,
        "structure_source": structure.source, "structure_default": structure.default,
        "energy_uncorrected": e0, "energy": energy, "ees": speed, "ees_kmh": ms_to_kmh(speed),
        "centroid_lateral": lateral, "centroid_depth": depth, "moment_arm": arm,
        "radius_of_gyration": math.sqrt(spec.yaw_inertia / spec.mass), "gamma": gamma,
        "warnings": warnings,
    }


def pair_report(r1: dict, r2: dict, restitution: float = 0.0) -> dict:
    """Two vehicles' reports (`report`) of the same impact: the total crush energy and each one's delta-V
    (pair_delta_v with their effective-mass factors), JSON-serialisable."""
    total = r1["energy"] + r2["energy"]
    dv1, dv2 = pair_delta_v(total, r1["mass"], r2["mass"], r1["gamma"], r2["gamma"], restitution)
    warnings = []
    if restitution > RESTITUTION_PUBLISHED_MAX:
        warnings.append(f"restitution {restitution:g} is above the values published for vehicle impacts (at most "
                        f"about {RESTITUTION_PUBLISHED_MAX:g}, at the lowest speeds): the delta-V, which grows as "
                        "sqrt((1 + e) / (1 - e)) at a given crush energy, rests on no vehicle data "
                        "(docs/physics.md §28)")
    return {"vehicles": [r1, r2], "energy_total": total, "restitution": restitution,
            "delta_v": [dv1, dv2], "delta_v_kmh": [ms_to_kmh(dv1), ms_to_kmh(dv2)], "warnings": warnings}


def format_report(rep: dict) -> str:
    """The text `crashlab damage` prints for a `report` or a `pair_report`."""
    if "vehicles" in rep:
        lines = [format_report(r) for r in rep["vehicles"]]
        lines.append(f"both: crush energy {rep['energy_total'] / 1e3:.1f} kJ, restitution {rep['restitution']:g}; "
                     + ", ".join(f"{r['vehicle']} delta-V {dv:.1f} km/h"
                                 for r, dv in zip(rep["vehicles"], rep["delta_v_kmh"])))
        return "\n".join(lines + [f"  warning: {w}" for w in rep["warnings"]])
    src = rep["structure_source"]
    src = ("class default" if rep["structure_default"] else "estimate, docs/physics.md §28"
           if src.startswith("estimate") else src if len(src) <= 60 else src[:57] + "...")
    chosen = f" ({rep['flank']} flank, the PDOF points at it)" if rep["side"] == "side" and rep.get("flank") else ""
    return "\n".join([
        f"{rep['vehicle']}: {rep['side']}{chosen}, {len(rep['profile'])}-point profile "
        f"{', '.join(f'{c:.3f}' for c in rep['profile'])} m over {rep['width']:.3f} m, offset {rep['offset']:.3f} m",
        f"  stiffness A {rep['A'] / 1e3:.1f} kN/m, B {rep['B'] / 1e3:.0f} kN/m^2, G {rep['G']:.0f} J/m ({src})",
        f"  PDOF {rep['pdof']:.1f} deg ({rep['pdof_angle']:.1f} deg off the normal, factor "
        f"{rep['pdof_factor']:.3f}); crush energy {rep['energy'] / 1e3:.1f} kJ; EES {rep['ees_kmh']:.1f} km/h",
        f"  moment arm {rep['moment_arm']:.2f} m, radius of gyration {rep['radius_of_gyration']:.2f} m, "
        f"effective-mass factor {rep['gamma']:.3f}"] + [f"  warning: {w}" for w in rep["warnings"]])


# ---------------------------------------------------------------- damage as evidence (docs/physics.md §28)
class DamageEvidence(BaseModel):
    """[evidence.damage.<vehicle>]: a measured crush profile as evidence of the impact's severity. The EES
    from the damage (this module's `report`) is compared with the EES of the simulated impact; its sigma
    comes from the crush measurement and the stiffness uncertainty (`damage_ees`). A twin study leaves the
    profile out: its run fills it (crashlab.reconstruction.evidence, `profile_for_ees`)."""
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)

    side: Literal[STRUCK_FACES] = Field(description="the struck side: front, rear, left or right (both flanks have "
                                        "the side structure; the impact rows tell them apart)")
    profile: list[Annotated[float, Strict()]] | None = Field(None, description="m, 2, 4 or 6 residual crush "
                                                             "depths C1..Cn, equally spaced over the width, left "
                                                             "to right seen from outside the vehicle; absent "
                                                             "only in a twin (its run fills a uniform 6-point "
                                                             "profile)")
    width: Annotated[float, Strict()] = Field(gt=0, le=30, description="m, the damaged width; at least 0.1 m and "
                                               "at most the struck side's structure width (checked against the "
                                               "vehicle)")
    offset: Annotated[float, Strict()] = Field(0.0, ge=-15, le=15, description="m, the centre of the damage: "
                                               "left of the centreline (front, rear) or ahead of the CG (left, "
                                               "right)")
    pdof: Annotated[float, Strict()] | None = Field(None, ge=-180, le=180, description="deg, the principal "
                                                    "direction of force in vehicle axes (0 = from ahead, +90 = "
                                                    "from the left); default normal to the side")
    sigma_crush: Annotated[float, Strict()] = Field(gt=0, le=0.5, description="m, the standard deviation of each "
                                                    "crush depth's measurement; (0, 0.5]")
    sigma_stiffness: Annotated[float, Strict()] = Field(gt=0, le=1, description="-, the relative standard "
                                                        "deviation of the stiffness (A and B scaled together); "
                                                        "(0, 1]")

    @field_validator("side", mode="before")
    @classmethod
    def _name_the_flank(cls, value):
        if value == "side":
            raise ValueError('"side" does not say which flank: left or right (the simulated impacts are compared on '
                             "the flank the damage is on)")
        return value


def ees_is_upper_bound(profile: Sequence[float], sigma_crush: float = 0.0) -> bool:
    """A profile without residual crush, its mean depth within the measurement's sigma_crush of 0 (0: every depth
    0): its CRASH3 EES (about G L, the energy the side absorbs without residual crush) bounds the impact's from
    above, it does not measure it (docs/physics.md §28)."""
    _argument(len(profile) > 0, "profile", profile, "at least one crush depth")
    return sum(profile) / len(profile) <= sigma_crush


def crush_energy_gradient(profile: Sequence[float], width: float, A: float, B: float) -> list[float]:
    """dE/dC_i [J/m] of `crush_energy` (no PDOF correction): each segment (i, j) adds
    d [A/2 + B (2 C_i + C_j)/6] to C_i."""
    _segments(profile, width)
    _stiffness(A, B)
    n = len(profile)
    d = width / (n - 1)
    grad = [0.0] * n
    for k, (ci, cj) in enumerate(zip(profile[:-1], profile[1:])):
        grad[k] += d * (A / 2.0 + B * (2.0 * ci + cj) / 6.0)
        grad[k + 1] += d * (A / 2.0 + B * (ci + 2.0 * cj) / 6.0)
    return grad


def damage_ees(evidence: DamageEvidence, spec: VehicleSpec, where: str = "study",
               prefix: str = "evidence.damage.") -> tuple[float, float]:
    """(EES [km/h], sigma [km/h]) from a damage measurement: EES = sqrt(2 E / m) of `report`, and its
    first-order (delta-method) standard deviation from independent crush errors sigma_crush on every C_i and
    a common relative stiffness error sigma_stiffness (E proportional to the stiffness scale):
        sigma_E^2 = f^2 sum_i (dE/dC_i)^2 sigma_crush^2 + (E sigma_stiffness)^2,   sigma_EES = EES sigma_E / 2E
    (f the PDOF factor). Bad input: InputError naming `where` (the study file) and `prefix` + the key."""
    return damage_ees_report(evidence, spec, where, prefix)[:2]


def damage_ees_report(evidence: DamageEvidence, spec: VehicleSpec, where: str = "study",
                      prefix: str = "evidence.damage.") -> tuple[float, float, dict]:
    """`damage_ees` and the damage's `report` (its warnings, the PDOF factor, the stiffness used)."""
    if evidence.profile is None:
        raise InputError(where, prefix + "profile", "missing key: the measured crush depths [m] (only a twin's "
                         "run fills them)")
    rep = report(spec, evidence.side, evidence.profile, evidence.width, evidence.offset, evidence.pdof, where,
                 prefix)
    grad = crush_energy_gradient(rep["profile"], rep["width"], rep["A"], rep["B"])
    var_crush = sum((rep["pdof_factor"] * g * evidence.sigma_crush) ** 2 for g in grad)
    energy = rep["energy"]
    sigma_e = math.sqrt(var_crush + (energy * evidence.sigma_stiffness) ** 2)
    ees_kmh = rep["ees_kmh"]
    mean_crush = sum(rep["profile"]) / len(rep["profile"])
    if evidence.sigma_stiffness > SIGMA_FIRST_ORDER[0] or (
            evidence.sigma_crush > SIGMA_FIRST_ORDER[1] * mean_crush
            and not ees_is_upper_bound(rep["profile"], evidence.sigma_crush)):
        rep["warnings"].append(
            f"sigma_stiffness {evidence.sigma_stiffness:g}, sigma_crush {evidence.sigma_crush:g} m against a mean "
            f"crush of {mean_crush:.3g} m: the first order sigma holds for sigma_stiffness <= "
            f"{SIGMA_FIRST_ORDER[0]:g} and sigma_crush <= {SIGMA_FIRST_ORDER[1]:g} x the mean crush "
            "(docs/physics.md §28); beyond, the EES is not Gaussian and its sigma is a rough one")
    return ees_kmh, ees_kmh * sigma_e / (2.0 * energy), rep


def combined_ees(ees_values: Sequence[float]) -> float:
    """The EES of several impact rows of one vehicle (same unit): sqrt(sum EES_k^2), their energies added."""
    return math.sqrt(sum(e * e for e in ees_values))


def damage_residual(ees_simulated: float, damage_evidence: DamageEvidence, spec: VehicleSpec,
                    where: str = "study", prefix: str = "evidence.damage.") -> float:
    """(EES_simulated - EES_damage) / sigma [sigma units] for a vehicle's simulated EES [km/h] (its impact
    rows' `combined_ees`); NaN when the simulated EES is not finite (a run that cannot be scored). A profile
    within its sigma_crush of no residual crush bounds the EES from above (`ees_is_upper_bound`): only the excess
    is scored,
    max(0, EES_simulated - EES_damage) / sigma."""
    if ees_simulated is None or not math.isfinite(ees_simulated):
        return math.nan
    value, sigma = damage_ees(damage_evidence, spec, where, prefix)
    excess = ees_simulated - value
    bound = ees_is_upper_bound(damage_evidence.profile, damage_evidence.sigma_crush)
    return (max(excess, 0.0) if bound else excess) / sigma


def profile_for_ees(ees_kmh: float, spec: VehicleSpec, side: str, width: float, n: int = 6,
                    pdof: float | None = None, where: str = "damage", prefix: str = "") -> list[float]:
    """A uniform n-point profile [m] over `width` whose `report` EES is `ees_kmh` (for twin experiments):
    C solves f L (A C + B C^2/2 + G) = m EES^2 / 2; below the no-damage EES (f L G) it is all zeros. Bad
    input: InputError naming `where` and `prefix` + the key (as `report`)."""
    s = spec.structure[FACE_STRUCTURE[_side(side, where, prefix + "side")]]
    ees_kmh = finite_number(ees_kmh, prefix + "ees", where)
    width = finite_number(width, prefix + "width", where)
    _argument(ees_kmh >= 0.0, "ees_kmh", ees_kmh, "an EES >= 0 [km/h]")
    _argument(width > 0.0, "width", width, "a damaged width > 0 [m]")
    _argument(n in PROFILE_POINTS, "n", n, "2, 4 or 6 points (CRASH3)")
    factor, _ = pdof_factor(pdof_angle(side, SIDE_NORMAL[side] if pdof is None else pdof), prefix + "pdof", where)
    per_width = 0.5 * spec.mass * kmh_to_ms(ees_kmh) ** 2 / (factor * width) - s.G
    c = 0.0 if per_width <= 0 else (-s.A + math.sqrt(s.A * s.A + 2.0 * s.B * per_width)) / s.B
    return [c] * n
