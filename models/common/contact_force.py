"""Contact force laws (docs/physics.md §13, §14) of the vehicle contacts (chassis_contact.py, road_contact.py).

Normal force (continuous, dissipative, Hertz-type):
    F_N = K delta^n [1 + chi(e) delta_dot / delta_dot0]        clamped to F_N >= 0 (no adhesion)
delta > 0 penetration, delta_dot its rate (> 0 approaching), delta_dot0 the rate at contact onset,
recorded once per contact (clamped below by v_min, §13). Laws (`chi(law, e)`):
    hertz                 0                   (elastic)
    hunt-crossley         3(1-e)/2
    lankarani-nikravesh   3(1-e^2)/4
    flores                8(1-e)/(5e)
    gonthier              (1-e^2)/e
    exact-restitution     root of 1 - chi e = (1 + chi) exp(-chi (1 + e)) in (0, 1/e) (§13), brentq,
                          cached per e: reproduces e exactly with the F_N >= 0 clamp.
The restitution e* a law really produces (§13, independent of K, n, m*, delta_dot0) is the root of
`restitution_relation`: 1 - chi e* = (1 + chi) exp(-chi (1 + e*)), unique in (0, 1/chi) (the left side
minus the right side is concave in e*, positive at 0 and negative at 1/chi); the tests solve it
(tests/test_contact_force.py, with the other convenience forms of these laws).
Flores, Gonthier and the exact law have chi -> inf as e -> 0: e is clamped to [E_MIN, E_MAX] =
[0.01, 0.999].

Friction (§14), magnitude ratio c(v) with F_T = -mu c(|v_T|) F_N v_T/|v_T|:
    coulomb     c = v / sqrt(v^2 + v_s^2)                     (regularised Coulomb, §14)
    threlfall   c = 1 - exp(-3 v / v0)                         [U] recalled form, Threlfall 1978,
                "The inclusion of Coulomb friction in mechanisms programs with particular reference to
                DRAM", Mech. Mach. Theory 13:475-483 (95 % of mu F_N at v = v0)
    ambrosio    c = 0 (v <= v0), (v - v0)/(v1 - v0), 1 (v >= v1)   [U] recalled form, Ambrosio 2003,
                "Impact of rigid and flexible multibody systems: deformation description and contact
                models", in Virtual Nonlinear Multibody Systems (NATO ASI, Kluwer), pp. 57-81
All three: c(0) = 0, c -> 1 for v >> tolerance, non-decreasing in v (tests). Ambrosio has no static
friction (c = 0 below v0: contacts creep, §14). Default tolerances are vehicle-scale
(v_s = v0 = 0.01 m/s, v1 = 0.1 m/s, §14), not the 1e-4/1e-3 m/s of the papers.
"""
import math
from functools import lru_cache

from numba import njit
from scipy.optimize import brentq

E_MIN = 0.01
E_MAX = 0.999
# friction tolerances [m/s] of the vehicle contacts (vehicle scale, §14): v0 and v1 of Threlfall/Ambrosio,
# v_s of the regularised Coulomb law
FRICTION_V0, FRICTION_V1, FRICTION_VS = 0.01, 0.1, 0.01
LAWS = ("hertz", "hunt-crossley", "lankarani-nikravesh", "flores", "gonthier", "exact-restitution")
FRICTION_LAWS = ("coulomb", "threlfall", "ambrosio")


def normal_law_name(law):
    """The canonical name of a normal force law (aliases accepted); ValueError for an unknown law."""
    k = law.lower().replace("_", "-").replace(" ", "-")
    aliases = {"hunt": "hunt-crossley", "lankarani": "lankarani-nikravesh", "nikravesh": "lankarani-nikravesh",
               "flores-machado": "flores", "exact": "exact-restitution"}
    k = aliases.get(k, k)
    if k not in LAWS:
        raise ValueError(f"unknown normal force law {law!r}; known: {', '.join(LAWS)}")
    return k


def _clamp_e(e):
    return min(max(float(e), E_MIN), E_MAX)


def restitution_relation(chi, e):
    """1 - chi e - (1 + chi) exp(-chi (1 + e)), written with expm1 for small chi."""
    x = chi * (1.0 + e)
    return -chi * e - math.expm1(-x) - chi * math.exp(-x)


@lru_cache(maxsize=1024)
def exact_chi(e):
    """chi that reproduces the target restitution e exactly (§13), root in (0, 1/e) by brentq."""
    e = _clamp_e(e)
    hi = 1.0 / e
    lo = 1e-6
    while restitution_relation(lo, e) <= 0.0 and lo > 1e-12:  # tiny root for e -> 1: move the bracket down
        lo *= 0.1
    return brentq(restitution_relation, lo, hi, args=(e,), xtol=1e-14, rtol=1e-14, maxiter=200)


def chi(law, e):
    """Hysteresis damping factor chi of a normal law at restitution coefficient e (§13)."""
    law = normal_law_name(law)
    if law == "hertz":
        return 0.0
    e = _clamp_e(e)
    if law == "hunt-crossley":
        return 1.5 * (1.0 - e)
    if law == "lankarani-nikravesh":
        return 0.75 * (1.0 - e * e)
    if law == "flores":
        return 8.0 * (1.0 - e) / (5.0 * e)
    if law == "gonthier":
        return (1.0 - e * e) / e
    return exact_chi(e)


@njit(cache=True)
def normal_force_chi(delta, delta_dot, delta_dot0, K, chi_, n=1.5, v_min=1e-3):
    """F_N = K delta^n (1 + chi delta_dot / max(delta_dot0, v_min)), 0 for delta <= 0, clamped >= 0."""
    if delta <= 0.0:
        return 0.0
    f = K * delta ** n * (1.0 + chi_ * delta_dot / max(delta_dot0, v_min))
    return f if f > 0.0 else 0.0


# ----------------------------------------------------------------------------------------------------
# friction (§14)
# ----------------------------------------------------------------------------------------------------
@njit(cache=True)
def friction_ratio_code(code, v, v0, v1, vs):
    """c(|v_T|) for code 0 coulomb (regularised), 1 threlfall, 2 ambrosio."""
    v = abs(v)
    if code == 0:
        return v / math.sqrt(v * v + vs * vs) if vs > 0.0 else (1.0 if v > 0.0 else 0.0)
    if code == 1:
        return -math.expm1(-3.0 * v / v0)
    if v <= v0:
        return 0.0
    if v >= v1:
        return 1.0
    return (v - v0) / (v1 - v0)


def friction_code(law):
    """The numba code of a friction law name (0 coulomb, 1 threlfall, 2 ambrosio)."""
    k = law.lower()
    if k not in FRICTION_LAWS:
        raise ValueError(f"unknown friction law {law!r}; known: {', '.join(FRICTION_LAWS)}")
    return FRICTION_LAWS.index(k)
