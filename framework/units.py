"""Unit conversion at the boundary: files speak km/h and degrees, the models speak SI."""
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
