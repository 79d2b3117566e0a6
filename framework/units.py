"""Unit conversion at the boundary: files speak km/h and degrees, the models speak SI."""
import functools
import math
import re

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
    return float(_pint_registry().Quantity(1.0, US_UNITS[unit][1]).to(_PINT_SI[unit]).magnitude)


@functools.cache
def _pint_registry():
    """pint's unit registry, built once and only where US units are asked for (building it takes about 0.5 s)."""
    import pint
    return pint.UnitRegistry()


def us_unit(unit: str) -> str:
    """The US unit shown for a file/SI unit ("m" -> "ft"); the unit itself where it has none (deg, s)."""
    return US_UNITS[unit][0] if unit in US_UNITS else unit


# ---------------------------------------------------------------- shown units (`--units si|us`)
# Printed tables, CSV files, JSON and reports in US customary units (ft, mph, lb, lbf, ft-lbf), converted where
# they are shown; the computation and the files it reads stay in the file units (crashlab.file_units reads a
# file written in US units). One home for the conversion. A column's (or a JSON key's) unit is said once, in
# one of two ways:
# - its header names it: "x [m]", "heading [deg, -180..180]" (printed tables);
# - a units map (name or pattern -> unit) names it: {"x": "m", "d_<source>_m": "m, ...", "<vehicle>.delta_v":
#   "km/h"}: a `<word>` in a pattern stands for any text (unit_of).
# A unit with a US form (US_UNITS) is converted by us_factor and the name says the shown unit (shown_name:
# "x [ft]", "distance_m" -> "distance_ft", "V1.speed" -> "V1.speed [mph]"); degrees, seconds, sigmas and
# coefficients stay as they are.

HEADER = re.compile(r"^(?P<name>.*) \[(?P<unit>[^\],]+)(?P<rest>,[^\]]*)?\]$")
_FROM_US = {us: si for si, (us, _) in US_UNITS.items()}  # "ft" -> "m": a shown header read back (table_from_shown)


def unit_word(text) -> str:
    """The unit a units-map entry starts with ("km/h, global" -> "km/h"; "" for none)."""
    return str(text or "").split(",")[0].strip()


@functools.lru_cache(maxsize=256)
def _pattern(key: str):
    """A units-map key as a regular expression: `<word>` matches any non-empty text."""
    parts = re.split(r"(<[^<>]+>)", key)
    return re.compile("^" + "".join(".+?" if p.startswith("<") and p.endswith(">") else re.escape(p)
                                    for p in parts) + "$")


def unit_of(name: str, units: dict) -> str:
    """The unit of a column or key by the units map: its own entry, else the first pattern that matches it
    ("d_pc_m" by "d_<source>_m"); "" when the map says nothing."""
    if name in units:
        return unit_word(units[name])
    for key, unit in units.items():
        if "<" in key and _pattern(key).match(name):
            return unit_word(unit)
    return ""


def shown_name(name: str, unit: str, system: str) -> str:
    """A column's name as shown: in system "us" with the US unit of `unit` (a header's bracket rewritten, a
    unit suffix replaced: "distance_m" -> "distance_ft", else " [ft]" appended); as it is otherwise."""
    if system != "us" or unit not in US_UNITS:
        return name
    m = HEADER.match(name)
    if m and m["unit"] == unit:
        return f"{m['name']} [{us_unit(unit)}{m['rest'] or ''}]"
    si, us = SUFFIXES.get(unit, (None, None))
    if si and name.endswith("_" + si):
        return name[:-len(si)] + us
    return f"{name} [{us_unit(unit)}]"


def value_in(value, unit: str, system: str):
    """A number (or array) in `unit` as shown in `system`."""
    return value / us_factor(unit) if system == "us" and unit in US_UNITS else value


def unit_in(unit: str, system: str) -> str:
    """The unit shown for `unit` in `system` ("m" -> "ft" in "us")."""
    return us_unit(unit) if system == "us" else unit


def frame_in(df, system: str, units: dict | None = None):
    """The table (a pandas DataFrame) as shown in `system`: every column whose unit has a US form (its header's
    unit, else the units map's) converted and renamed (shown_name); as it is in "si"."""
    if system != "us":
        return df
    df = df.copy()
    names = {}
    for c in df.columns:
        m = HEADER.match(str(c))
        unit = m["unit"] if m else unit_of(str(c), units or {})
        if unit in US_UNITS:
            df[c] = df[c] / us_factor(unit)
            names[c] = shown_name(str(c), unit, system)
    return df.rename(columns=names)


def table_in(df, system: str):
    """A printed table whose headers name their units ("x [m]") as shown in `system` (frame_in)."""
    return frame_in(df, system)


def table_from_shown(df):
    """A CSV written by frame_in read back into file units: a column "name [ft]" (a US unit in brackets) becomes
    "name" in its file unit; other columns as they are (a unit suffix, "distance_ft", is not read back: the
    tables read again, posterior.csv, name their columns by variable labels)."""
    df = df.copy()
    names = {}
    for c in df.columns:
        m = HEADER.match(str(c))
        if m and m["unit"] in _FROM_US and not m["rest"]:
            si = _FROM_US[m["unit"]]
            df[c] = df[c] * us_factor(si)
            names[c] = m["name"]
    return df.rename(columns=names)


def json_number(value, digits: int | None = 6):
    """A number of a JSON document: None for None, NaN, inf or a non-number (JSON has neither NaN nor inf),
    rounded to `digits` decimals (None: as it is)."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        return None
    if not math.isfinite(v):
        return None
    return v if digits is None else round(v, digits)


def json_in(data: dict, system: str) -> dict:
    """A JSON document (`simulate --json`, `compare --json`, `reconstruct --json`, ...) with every number whose
    key's unit (its "units" map: a key or a pattern, unit_of; an impact row's by "impacts.<key>") has a US form
    converted, and the map saying the US unit."""
    if system != "us":
        return data
    units = data.get("units", {})

    def named(key, unit):  # a key named with its SI unit as a suffix takes the US one ("distance_m" -> "distance_ft")
        si, us = SUFFIXES.get(unit_word(unit), (None, None))
        return key[:-len(si)] + us if si and isinstance(key, str) and key.endswith("_" + si) else key

    def walk(value, key=None, in_impacts=False):
        if isinstance(value, dict):
            return {named(k, unit_of(k, units)): walk(v, k, in_impacts) for k, v in value.items()}
        if isinstance(value, list):
            return [walk(v, key, in_impacts or key == "impacts") for v in value]
        if isinstance(value, (int, float)) and not isinstance(value, bool) and key is not None:
            return value_in(value, unit_of(f"impacts.{key}" if in_impacts else key, units), system)
        return value

    out = {k: walk(v, k) for k, v in data.items() if k != "units"}
    out["units"] = {named(k, u): (us_unit(unit_word(u)) + str(u)[len(unit_word(u)):] if unit_word(u) in US_UNITS
                                  else u) for k, u in units.items()}
    return out


def uncertain_text(u, system: str) -> str:
    """An uncertain parameter's description (crashlab.uncertainty.Uncertain.describe) with its numbers and unit
    as shown in `system`."""
    import dataclasses
    if system != "us" or u.unit not in US_UNITS:
        return u.describe()
    f = 1.0 / us_factor(u.unit)
    shown = dataclasses.replace(u, **{k: getattr(u, k) * f for k in ("lower", "upper", "mean", "sd", "mode")
                                      if getattr(u, k) is not None})
    return shown.describe().replace(f" {u.unit}", f" {us_unit(u.unit)}")


def length_axes_in(ax, system: str) -> None:
    """A matplotlib top view drawn in m shown in ft with system "us": ticks at round ft values labelled in ft,
    "[m]" in the axis labels said "[ft]"; the drawing itself stays in m (as is every other number of a figure)."""
    if system != "us":
        return
    from matplotlib.ticker import FuncFormatter, MaxNLocator
    f = us_factor("m")

    class InFeet(MaxNLocator):
        def tick_values(self, vmin, vmax):
            return super().tick_values(vmin / f, vmax / f) * f

    for axis in (ax.xaxis, ax.yaxis):
        axis.set_major_locator(InFeet())
        axis.set_major_formatter(FuncFormatter(lambda v, _pos: f"{v / f:g}"))
        axis.set_label_text(axis.get_label_text().replace("[m]", f"[{us_unit('m')}]"))
