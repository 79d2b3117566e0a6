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
(a0 from it) and s, or with two or more tests b0 too, by least squares of the tests' EBS (√(2 E / m), the speed
the model's energy gives against the test's; scipy.optimize.least_squares).

Only the core is imported (crashlab.damage, crashlab.errors, crashlab.structure).
"""
from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

import numpy as np
from scipy.optimize import least_squares

from .damage import DAMAGE_WIDTH_MIN, _finite, check_profile
from .errors import InputError
from .structure import CRUSH_REFERENCE, NO_DAMAGE_SPEED_MAX, NO_DAMAGE_SPEED_MIN

# m/s, the least spread of the tests' mean crush over which a fit of b0 from the tests is a line and not a
# guess (two tests 2 cm apart in crush leave b0 to their scatter): below it b0 must be given
CRUSH_SPREAD_MIN = 0.05


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
        """(S1 [m²], S2 [m³]): ∫ C dx and ∫ C² / 2 dx over the width, the crush linear between the points (the
        integrals of damage.crush_energy)."""
        d = self.width / (len(self.profile) - 1)
        pairs = list(zip(self.profile[:-1], self.profile[1:]))
        return (sum(d * (ci + cj) / 2.0 for ci, cj in pairs),
                sum(d * (ci * ci + ci * cj + cj * cj) / 6.0 for ci, cj in pairs))

    @property
    def mean_crush(self) -> float:
        """m, the profile's mean depth over the width (S1 / L)."""
        return self.moments()[0] / self.width


def check_test(test: CrashTest, key: str, where: str = "command line") -> CrashTest:
    """The test with its numbers checked (InputError naming `key`, one line): masses and speed finite and > 0, a
    CRASH3 profile (damage.check_profile), a crush width of at least DAMAGE_WIDTH_MIN."""
    mass = _finite(test.mass, f"{key} mass", where)
    speed = _finite(test.speed, f"{key} speed", where)
    width = _finite(test.width, f"{key} width", where)
    if mass <= 0.0:
        raise InputError(where, f"{key} mass", f"{mass:g} kg: must be > 0")
    if speed <= 0.0:
        raise InputError(where, f"{key} speed", f"{speed:g}: the impact speed must be > 0")
    if width < DAMAGE_WIDTH_MIN:
        raise InputError(where, f"{key} width", f"{width:g} m: the crush width must be at least "
                         f"{DAMAGE_WIDTH_MIN:g} m")
    barrier = test.barrier_mass
    if barrier is not None:
        barrier = _finite(barrier, f"{key} barrier mass", where)
        if barrier <= 0.0:
            raise InputError(where, f"{key} barrier mass", f"{barrier:g} kg: must be > 0")
    profile = tuple(check_profile(list(test.profile), f"{key} profile", where))
    if max(profile) <= 0.0:
        raise InputError(where, f"{key} profile", "no residual crush: a test without crush gives no crash plot "
                         "(at most the no-damage speed b0)")
    return CrashTest(mass, speed, profile, width, barrier, test.label)


@dataclasses.dataclass(frozen=True)
class StiffnessFit:
    """A, B [N/m, N/m²] and G [J/m] of the side from its tests; b0 [m/s] (given or fitted) and b1 [1/s] of the
    crash plot for the tests' mean mass per crush width; per test its crush energy [J], EBS [m/s] and the EBS the
    fitted A, B give its profile [m/s]; warnings."""

    A: float
    B: float
    G: float
    b0: float
    b1: float
    b0_fitted: bool
    width: float
    energies: tuple[float, ...]
    ebs: tuple[float, ...]
    ebs_fitted: tuple[float, ...]
    warnings: tuple[str, ...]


def fit_stiffness(tests: Sequence[CrashTest], b0: float | None, restitution: float = 0.0,
                  where: str = "command line") -> StiffnessFit:
    """A and B of one side from its crash tests (module docstring): b0 [m/s] given (the no-damage speed; a0 from
    it with the tests' mean m / L), or None to fit it with s from two or more tests whose mean crush spans at least
    CRUSH_SPREAD_MIN. InputError (one line) for bad tests or a fit the tests cannot carry."""
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
    # the crash plot's b0 and b1 for the tests' mean mass per unit crush width (one vehicle: the same for each)
    m_per_l = float(np.mean(masses / widths))

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
        x0 = [max(icpt, 0.5) * math.sqrt(m_per_l), max(slope, 1.0) * math.sqrt(m_per_l)]
        sol = least_squares(lambda x: model_ebs(x[0], x[1]) - ebs, x0, bounds=([0.0, 1e-9], [np.inf, np.inf]),
                            xtol=1e-14, ftol=1e-14, gtol=1e-14)
        a0, s = (float(v) for v in sol.x)
    else:
        b0 = _finite(b0, "--b0", where)
        if b0 < 0.0:
            raise InputError(where, "--b0", f"{b0:g}: the no-damage speed must be >= 0")
        a0 = b0 * math.sqrt(m_per_l)
        # each test alone: its quadratic in s, s^2 S2 + a0 S1 s + (a0^2 L / 2 - E) = 0
        roots = (-a0 * s1 + np.sqrt((a0 * s1) ** 2 - 4.0 * s2 * (0.5 * a0 * a0 * widths - energies))) / (2.0 * s2)
        if np.any(~np.isfinite(roots)) or np.any(roots <= 0.0):
            k = int(np.argmax(~np.isfinite(roots) | (roots <= 0.0)))
            raise InputError(where, f"--test {k + 1}", f"its energy {energies[k]:.0f} J is no more than the "
                             f"{0.5 * a0 * a0 * widths[k]:.0f} J absorbed without residual crush at b0 = "
                             f"{b0 * 3.6:.1f} km/h: the crush cannot come from this speed (check the speed, the "
                             "profile or b0)")
        sol = least_squares(lambda x: model_ebs(a0, x[0]) - ebs, [float(np.mean(roots))], bounds=([1e-9], [np.inf]),
                            xtol=1e-14, ftol=1e-14, gtol=1e-14)
        s = float(sol.x[0])
    A, B = a0 * s, s * s
    G = 0.5 * a0 * a0
    fitted = model_ebs(a0, s)
    warnings = []
    if b0 is None and a0 <= 1e-9:
        warnings.append("the tests' crash plot reaches zero crush at or below zero speed: b0 is held at 0 (give b0, "
                        "the published no-damage speeds are 2.2-4.5 m/s for fronts and rears)")
    b0_out = a0 / math.sqrt(m_per_l)
    if b0_out > NO_DAMAGE_SPEED_MAX or (b0_out < NO_DAMAGE_SPEED_MIN and not warnings):
        warnings.append(f"b0 = {b0_out * 3.6:.1f} km/h lies outside {NO_DAMAGE_SPEED_MIN * 3.6:.1f}-"
                        f"{NO_DAMAGE_SPEED_MAX * 3.6:.1f} km/h, the range a vehicle file's structure accepts "
                        "(docs/physics.md §28 \"Limits of the input\")")
    worst = float(np.max(np.abs(fitted - ebs)))
    if len(tests) > 1 and worst > 0.1 * float(np.min(ebs)):
        warnings.append(f"the tests scatter about the fitted crash plot by up to {worst * 3.6:.1f} km/h of EBS "
                        "(more than 10 % of the slowest test's): one line may not describe them")
    return StiffnessFit(A, B, G, b0_out, s / math.sqrt(m_per_l), b0 is None, float(np.max(widths)),
                        tuple(float(e) for e in energies), tuple(float(v) for v in ebs),
                        tuple(float(v) for v in fitted), tuple(warnings))


def default_b0(side: str) -> float:
    """m/s, the no-damage speed of `side` the class estimates take (crashlab.structure.CRUSH_REFERENCE)."""
    return CRUSH_REFERENCE["side" if side in ("left", "right") else side][0]
