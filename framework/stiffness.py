"""CRASH3 stiffness coefficients A, B of one side of a vehicle from its crash tests: Campbell's crash plot fitted
to the tests' residual crush profiles (docs/physics.md §28 "Stiffness from crash tests"), the way a
reconstructionist replaces a class estimate by the vehicle's own coefficients.

A test: the vehicle's test mass m [kg], the impact speed V [m/s], the residual crush profile C1..Cn (2, 4 or 6
equally spaced depths [m]) over the crush width L [m]; into a fixed rigid barrier, or struck by (or striking) a
rigid moving barrier of mass M [kg] at the closing speed V. The energy the crush absorbed is, as the crash plot
counts it (Campbell, SAE 740565; the CRASH3 Technical Manual), the kinetic energy the impact takes out of the
closing motion, E = ½ m* V² (1 − e²), m* = m for the fixed barrier, m M / (m + M) for a moving one, e the
restitution (0 by the crash plot's convention, which counts the rebound's energy as crush energy).

The crush energy of a profile with A, B (damage.crush_energy) is E = A S1 + B S2 + G L, G = A² / 2B, with
S1 = ∫ C dx and S2 = ∫ C² / 2 dx over the width, the crush linear between the points. Written with
a0 = A / √B = √(2G) and s = √B it is E = a0 s S1 + s² S2 + a0² L / 2: for a uniform crush C, E = L (a0 + s C)² / 2,
Campbell's line EBS = b0 + b1 C with b0 = a0 √(L / m), b1 = s √(L / m). The fit: the no-damage speed b0 given
(a0 from it at the widest test's crush width W, the table's width, and the tests' mean mass: the b0 a vehicle
file's checks read) and s, or with two or more tests b0 too, by least squares of the tests' EBS (√(2 E / m), the
speed the model's energy gives against the test's; scipy.optimize.least_squares).

Only the core is imported (crashlab.damage, crashlab.errors, crashlab.scene, crashlab.structure, crashlab.vehicle).
"""
from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

import numpy as np
from pydantic import ValidationError
from scipy.optimize import least_squares

from .damage import DAMAGE_WIDTH_MIN, check_profile, finite_number, profile_moments
from .errors import InputError
from .scene import SPEED_MAX
from .structure import (
    CRUSH_REFERENCE,
    NO_DAMAGE_SPEED_MAX,
    NO_DAMAGE_SPEED_MIN,
    STRUCTURE_WIDTH_RANGE,
    StructureSideFile,
    crash_plot,
)
from .vehicle import MASS_RANGE, crush_56_problem

# m, the least spread of the tests' mean crush over which a fit of b0 from the tests is a line and not a
# guess (two tests 2 cm apart in crush leave b0 to their scatter): below it b0 must be given
CRUSH_SPREAD_MIN = 0.05
# m, the least mean residual crush of a test: below, no crash plot (a scuff, or a depth in km read as m)
CRUSH_MIN = 0.001
# the least slope s = sqrt(B) [sqrt(N)/m] of the fit's search (a bound of the solver, B > 0)
SLOPE_MIN = 1e-6
# 1/s, the least crash-plot slope b1 a fit may give: 1 m of crush for 3.6 km/h of EBS is no vehicle (a vehicle
# file's checks need b1 >= 3.8 1/s through C56 <= 2 m; the library's 20-40 1/s)
B1_MIN = 1.0


@dataclasses.dataclass(frozen=True)
class CrashTest:
    """One crash test of the side: test mass [kg], impact (closing) speed [m/s], residual crush profile [m] over
    `width` [m]; `barrier_mass` [kg] of a rigid moving barrier (None: a fixed rigid barrier)."""

    mass: float
    speed: float
    profile: tuple[float, ...]
    width: float
    barrier_mass: float | None = None
    label: str = ""

    @property
    def energy_mass(self) -> float:
        """kg, the mass whose ½ m* V² the impact takes out of the closing motion: m against a fixed barrier,
        m M / (m + M) against a moving one."""
        if self.barrier_mass is None:
            return self.mass
        return self.mass * self.barrier_mass / (self.mass + self.barrier_mass)

    def energy(self, restitution: float = 0.0) -> float:
        """J, the crush energy of the test: ½ m* V² (1 − e²)."""
        return 0.5 * self.energy_mass * self.speed ** 2 * (1.0 - restitution ** 2)

    def moments(self) -> tuple[float, float]:
        """(S1 [m²], S2 [m³]): ∫ C dx and ∫ C² / 2 dx over the width (damage.profile_moments)."""
        return profile_moments(self.profile, self.width)

    @property
    def mean_crush(self) -> float:
        """m, the profile's mean depth over the width (S1 / L)."""
        return self.moments()[0] / self.width


def check_test(test: CrashTest, key: str, where: str = "command line") -> CrashTest:
    """The test with its numbers checked (InputError naming `key`, one line): masses and speed finite and > 0, a
    CRASH3 profile (damage.check_profile), a crush width of at least DAMAGE_WIDTH_MIN."""
    mass = finite_number(test.mass, f"{key} mass", where)
    speed = finite_number(test.speed, f"{key} speed", where)
    width = finite_number(test.width, f"{key} width", where)
    lo, hi = MASS_RANGE
    if not lo <= mass <= hi:
        raise InputError(where, f"{key} mass", f"{mass:.6g} kg: a vehicle's test mass lies within {lo:g}-{hi:g} kg")
    if not 0.0 < speed * 3.6 <= SPEED_MAX:
        raise InputError(where, f"{key} speed", f"{speed * 3.6:.6g} km/h: the impact speed must be > 0 and at most "
                         f"{SPEED_MAX:g} km/h")
    if not DAMAGE_WIDTH_MIN <= width <= STRUCTURE_WIDTH_RANGE[1]:
        raise InputError(where, f"{key} width", f"{width:.6g} m: the crush width must lie within "
                         f"{DAMAGE_WIDTH_MIN:g}-{STRUCTURE_WIDTH_RANGE[1]:g} m")
    barrier = test.barrier_mass
    if barrier is not None:
        barrier = finite_number(barrier, f"{key} barrier mass", where)
        if not lo <= barrier <= hi:
            raise InputError(where, f"{key} barrier mass", f"{barrier:.6g} kg: a moving barrier's mass lies within "
                             f"{lo:g}-{hi:g} kg")
    profile = tuple(check_profile(list(test.profile), f"{key} profile", where))
    checked = CrashTest(mass, speed, profile, width, barrier, test.label)
    if checked.mean_crush < CRUSH_MIN:
        raise InputError(where, f"{key} profile", f"mean residual crush {checked.mean_crush:.3g} m: a test without "
                         f"crush (under {CRUSH_MIN * 1000:g} mm) gives no crash plot (at most the no-damage speed b0)")
    return checked


@dataclasses.dataclass(frozen=True)
class StiffnessFit:
    """A, B [N/m, N/m²] and G [J/m] of the side from its tests over `width` [m] (the widest test's crush width, the
    table's); b0 [m/s] (given or fitted) and b1 [1/s] of the crash plot at that width and the tests' mean `mass`
    [kg], as a vehicle file's checks read them; per test its crush energy [J], EBS [m/s] and the EBS the fitted A,
    B give its profile [m/s]; warnings."""

    A: float
    B: float
    G: float
    b0: float
    b1: float
    b0_fitted: bool
    width: float
    mass: float
    energies: tuple[float, ...]
    ebs: tuple[float, ...]
    ebs_fitted: tuple[float, ...]
    warnings: tuple[str, ...]


def fit_stiffness(tests: Sequence[CrashTest], b0: float | None, restitution: float = 0.0,
                  where: str = "command line", side: str = "front") -> StiffnessFit:
    """A and B of one side from its crash tests (module docstring): b0 [m/s] given (the no-damage speed at the
    widest test's crush width W and the tests' mean mass m, a0 = b0 √(m / W)), or None to fit it with s from two
    or more tests whose mean crush spans at least CRUSH_SPREAD_MIN. InputError (one line) for bad tests or a fit
    the tests cannot carry; warnings where the table is outside what a vehicle file takes (table_problems)."""
    if not tests:
        raise InputError(where, "--test", "give at least one crash test")
    tests = [check_test(t, f"--test {k + 1}", where) for k, t in enumerate(tests)]
    if not 0.0 <= restitution < 1.0:
        raise InputError(where, "--restitution", f"{restitution:g}: must lie in [0, 1)")
    energies = np.array([t.energy(restitution) for t in tests])
    masses = np.array([t.mass for t in tests])
    ebs = np.sqrt(2.0 * energies / masses)
    s1, s2 = np.array([t.moments() for t in tests]).T
    widths = np.array([t.width for t in tests])
    # the table's width and the crash plot's b0, b1 there at the tests' mean mass (what a vehicle file's checks read)
    width, mass = float(np.max(widths)), float(np.mean(masses))
    scale = math.sqrt(mass / width)

    def model_ebs(a0, s):
        return np.sqrt(2.0 * (a0 * s * s1 + s * s * s2 + 0.5 * a0 * a0 * widths) / masses)

    if b0 is None:
        spread = max(t.mean_crush for t in tests) - min(t.mean_crush for t in tests)
        if len(tests) < 2 or spread < CRUSH_SPREAD_MIN:
            raise InputError(where, "--b0", f"fitting b0 needs two or more tests whose mean crush differs by at "
                             f"least {CRUSH_SPREAD_MIN:g} m (here {len(tests)} test(s), {spread:.3f} m): give b0")
        # start: the line through the tests' (mean crush, EBS) in Campbell's form, then the profiles' own integrals
        c = np.array([t.mean_crush for t in tests])
        slope, icpt = np.polyfit(c, ebs, 1)
        x0 = [max(icpt, 0.5) * scale, max(slope, 1.0) * scale]
        sol = least_squares(lambda x: model_ebs(x[0], x[1]) - ebs, x0, bounds=([0.0, SLOPE_MIN], [np.inf, np.inf]),
                            xtol=1e-14, ftol=1e-14, gtol=1e-14)
        a0, s = (float(v) for v in sol.x)
        if a0 / scale < NO_DAMAGE_SPEED_MIN:
            raise InputError(where, "--b0", f"the tests' crash plot reaches zero crush at {a0 / scale * 3.6:.2f} km/h "
                             f"(held at >= 0), below the {NO_DAMAGE_SPEED_MIN * 3.6:.1f} km/h a vehicle structure "
                             f"has: give b0 (the class estimates' {default_b0(side) * 3.6:.1f} km/h for a {side})")
    else:
        b0 = finite_number(b0, "--b0", where)
        if not 0.0 < b0 * 3.6 <= SPEED_MAX:
            raise InputError(where, "--b0", f"{b0 * 3.6:.6g} km/h: the no-damage speed must be > 0 and at most "
                             f"{SPEED_MAX:g} km/h")
        a0 = b0 * scale
        # each test alone: its quadratic in s, s^2 S2 + a0 S1 s + (a0^2 L / 2 - E) = 0
        no_damage = 0.5 * a0 * a0 * widths
        for k in range(len(tests)):
            if energies[k] <= no_damage[k]:
                raise InputError(where, f"--test {k + 1}", f"its energy {energies[k]:.0f} J (EBS "
                                 f"{ebs[k] * 3.6:.1f} km/h) is no more than the {no_damage[k]:.0f} J its "
                                 f"{widths[k]:g} m absorb without residual crush at b0 = {b0 * 3.6:.1f} km/h (its own "
                                 f"no-damage speed {math.sqrt(2 * no_damage[k] / masses[k]) * 3.6:.1f} km/h): the "
                                 "crush cannot come from this speed (check the speed, the profile or b0)")
        roots = (-a0 * s1 + np.sqrt((a0 * s1) ** 2 + 4.0 * s2 * (energies - no_damage))) / (2.0 * s2)
        sol = least_squares(lambda x: model_ebs(a0, x[0]) - ebs, [max(float(np.mean(roots)), 2 * SLOPE_MIN)],
                            bounds=([SLOPE_MIN], [np.inf]), xtol=1e-14, ftol=1e-14, gtol=1e-14)
        s = float(sol.x[0])
    if s / scale < B1_MIN:
        raise InputError(where, "--test", f"the tests' EBS does not rise with their crush (the crash plot's slope "
                         f"b1 = {s / scale:.3g} 1/s, under {B1_MIN:g}): they give no stiffness (check the speeds, "
                         "profiles and b0)")
    A, B = a0 * s, s * s
    fitted = model_ebs(a0, s)
    warnings = []
    worst = float(np.max(np.abs(fitted - ebs)))
    if len(tests) > 1 and worst > 0.1 * float(np.min(ebs)):
        warnings.append(f"the tests scatter about the fitted crash plot by up to {worst * 3.6:.1f} km/h of EBS "
                        "(more than 10 % of the slowest test's): one line may not describe them")
    if side == "side" and any(t.barrier_mass is not None for t in tests):
        warnings.append("a side test's moving barrier (FMVSS 214) is deformable: its own crush absorbs part of the "
                        "energy counted here as the car's, so A and B are an upper bound")
    warnings += table_problems(A, B, width, mass)
    b0_out, b1_out = crash_plot(A, B, width, mass)
    return StiffnessFit(A, B, 0.5 * a0 * a0, b0_out, b1_out, b0 is None, width, mass,
                        tuple(float(e) for e in energies), tuple(float(v) for v in ebs),
                        tuple(float(v) for v in fitted), tuple(warnings))


def table_problems(A: float, B: float, width: float, mass: float) -> list[str]:
    """Why a vehicle file of `mass` [kg] would refuse the structure table A, B over `width`: its bounds
    (StructureSideFile), the no-damage speed's range and the crash plot's 56 km/h crush (crashlab.vehicle's
    checks, docs/physics.md §28 "Limits of the input"); [] when it takes it."""
    try:
        StructureSideFile(A=A, B=B, width=width)
    except ValidationError as err:
        return [f"a vehicle file refuses this table: {e['loc'][0]} {e['msg']}" for e in err.errors()]
    b0 = crash_plot(A, B, width, mass)[0]
    if not NO_DAMAGE_SPEED_MIN <= b0 <= NO_DAMAGE_SPEED_MAX:
        return [f"a vehicle file of {mass:.0f} kg refuses this table: its no-damage speed {b0 * 3.6:.1f} km/h lies "
                f"outside {NO_DAMAGE_SPEED_MIN * 3.6:.1f}-{NO_DAMAGE_SPEED_MAX * 3.6:.1f} km/h (docs/physics.md §28 "
                "\"Limits of the input\")"]
    problem = crush_56_problem(A, B, width, mass)
    return [f"a vehicle file refuses this table: {problem}"] if problem else []


def default_b0(side: str) -> float:
    """m/s, the no-damage speed of `side` (front, rear, side) the class estimates take
    (crashlab.structure.CRUSH_REFERENCE)."""
    return CRUSH_REFERENCE[side][0]
