"""Restitution as a law of the closing speed (docs/physics.md §13b): `[impact] restitution = "speed"`.

The one home of the law every model uses (impulse kernel, pymunk, the chassis contact of multibody and
exudyn). Cipriani et al. 2002 (SAE 2002-01-0540), regression of restitution on the closing speed of low-speed
collinear car-to-car impacts:

    e(v) = 0.47477 - 0.26139 L + 0.03382 L^2 - 0.11639 L^3,   L = log10(v / (1 m/s))

Outside V_MIN..V_MAX the end value is held and `restitution_at` says so (never silently extrapolated: the
cubic falls below zero above about 16 m/s).

    SPEED                   the word of the scene file ("speed")
    speed_restitution(v)    e at closing speed v [m/s], held at the ends (plain Python and numba-compilable;
                            models/common/restitution_law.py registers it for compiled kernels)
    restitution_at(v, imp)  (e, warning or None) for an Impact: its constant, or the law at v
    E_SPEED_LAW             the sentinel a numba kernel receives for e when the law applies (negative)
"""

import math

SPEED = "speed"
CONSTANT = "constant"
# Cipriani et al. 2002, SAE 2002-01-0540 (as quoted in github:joe-cormier/pycrash, v converted from mph to m/s)
CIPRIANI = (0.47477, -0.26139, 0.03382, -0.11639)
# m/s, the range the law is held within (docs/physics.md §13b: the low-speed collinear tests it was fitted to;
# beyond about 8 m/s it is an extrapolation the source does not support)
V_MIN, V_MAX = 1.0, 8.0
E_SPEED_LAW = -1.0


def speed_restitution(v):
    """Restitution at the closing speed v [m/s] (Cipriani et al. 2002), v held within [V_MIN, V_MAX]."""
    v = min(max(abs(v), V_MIN), V_MAX)
    lg = math.log10(v)
    a0, a1, a2, a3 = CIPRIANI
    return a0 + lg * (a1 + lg * (a2 + lg * a3))


def kernel_value(impact) -> float:
    """The e a numba kernel is given for this Impact: its constant, or E_SPEED_LAW."""
    return E_SPEED_LAW if impact.restitution_law == SPEED else float(impact.restitution)


def range_warning(closing_speed: float) -> str | None:
    """The reason the law is held at an end value at this closing speed [m/s], or None within its data."""
    v = abs(closing_speed)
    if V_MIN <= v <= V_MAX:
        return None
    end = V_MIN if v < V_MIN else V_MAX
    return (f"restitution = \"speed\": closing speed {v * 3.6:.1f} km/h is outside the data of the law "
            f"(Cipriani et al. 2002, {V_MIN * 3.6:.1f}-{V_MAX * 3.6:.1f} km/h), {'below' if v < V_MIN else 'above'} "
            f"it; its end value "
            f"e = {speed_restitution(end):.3f} at {end * 3.6:.1f} km/h is used (docs/physics.md §13b)")


def restitution_at(closing_speed: float, impact) -> tuple[float, str | None]:
    """(e, warning or None) of an impact at this closing speed [m/s] for a scene's Impact."""
    if impact.restitution_law != SPEED:
        return float(impact.restitution), None
    return speed_restitution(closing_speed), range_warning(closing_speed)
