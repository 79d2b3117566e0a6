"""Unit conversion at the boundary: files speak km/h and degrees, the models speak SI."""
import functools
import math

KMH = 1.0 / 3.6  # m/s per km/h
G = 9.81  # m/s^2, standard gravity used by every model


def kmh_to_ms(v):
    return v / 3.6


def ms_to_kmh(v):
    return v * 3.6


def deg_to_rad(a):
    return a * math.pi / 180.0


def rad_to_deg(a):
    return a * 180.0 / math.pi


def wrap_deg(a):
    """Wrap an angle difference to (-180, 180] degrees."""
    return -((-a + 180.0) % 360.0 - 180.0)


# units a file key's description may start with ("m, CG position ..."; "km/h; [0, 400]"): the reference's Unit
# column and the unit of a bound in a range error
DESCRIBED_UNITS = ("kg m^2", "N s/m", "N/rad", "N/m^2", "N/m", "N", "m/deg", "deg/s", "deg", "km/h", "kg", "m", "s",
                   "-")


def split_unit(description: str) -> tuple[str, str]:
    """(unit, meaning) of a description that starts with a unit ("m, ...", "km/h; ...", "kg m^2 about ...")."""
    d = (description or "").strip()
    for u in DESCRIBED_UNITS:
        if d == u:
            return u, ""
        if d.startswith(u) and (d[len(u)] in ",;" or (d[len(u)] == " " and not u.isalpha())):
            return u, d[len(u) + 1:].strip()
    return "", d


# US customary units (`--units us`, a file's `units = "us"`): the US unit printed for each file/SI unit, and the
# pint expressions of both (docs/reference.md); every pair differs by a factor only (no offset)
US_UNITS = {"m": ("ft", "foot"), "km/h": ("mph", "mile/hour"), "kg": ("lb", "pound"),
            "kg m^2": ("lb ft^2", "pound*foot**2"), "N": ("lbf", "force_pound"), "N/m": ("lbf/ft", "force_pound/foot"),
            "N/m^2": ("lbf/ft^2", "force_pound/foot**2"), "N s/m": ("lbf s/ft", "force_pound*second/foot"),
            "N/rad": ("lbf/rad", "force_pound/radian"), "m/deg": ("ft/deg", "foot/degree"),
            "J": ("ft-lbf", "foot*force_pound"), "m/s": ("ft/s", "foot/second")}
_PINT_SI = {"m": "meter", "km/h": "kilometer/hour", "kg": "kilogram", "kg m^2": "kilogram*meter**2", "N": "newton",
            "N/m": "newton/meter", "N/m^2": "newton/meter**2", "N s/m": "newton*second/meter",
            "N/rad": "newton/radian", "m/deg": "meter/degree", "J": "joule", "m/s": "meter/second"}
UNIT_SYSTEMS = ("si", "us")
# a column or key named with its unit as a suffix ("distance_m", "speed_kmh"): the suffix of each unit with a US
# form, and of that US form ("distance_ft", "speed_mph")
SUFFIXES = {"m": ("m", "ft"), "km/h": ("kmh", "mph"), "kg": ("kg", "lb"), "J": ("J", "ftlbf"), "N": ("N", "lbf"),
            "m/s": ("ms", "fts")}


@functools.cache
def us_factor(unit: str) -> float:
    """How many of `unit` (a file/SI unit of US_UNITS' keys) one of its US unit is, through pint: 0.3048 for
    "m" (1 ft = 0.3048 m), 1.609344 for "km/h"; 1.0 for a unit without a US counterpart (deg, s, -)."""
    if unit not in US_UNITS:
        return 1.0
    import pint  # only where US units are asked for (its registry takes a fraction of a second to build)
    registry = pint.UnitRegistry()
    return float(registry.Quantity(1.0, US_UNITS[unit][1]).to(_PINT_SI[unit]).magnitude)


def us_unit(unit: str) -> str:
    """The US unit shown for a file/SI unit ("m" -> "ft"); the unit itself where it has none (deg, s)."""
    return US_UNITS[unit][0] if unit in US_UNITS else unit
