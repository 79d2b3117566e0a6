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
