"""`--units us`: printed tables, CSV files, JSON and reports in US customary units (ft, mph, lb, lbf, ft-lbf),
converted where they are shown; the computation and the files it reads stay in the file units (crashlab.units,
crashlab.file_units).

One home for the conversion. A column's (or a JSON key's) unit is said once, in one of two ways:
- its header names it: "x [m]", "heading [deg, -180..180]" (printed tables);
- a units map (name or pattern -> unit) names it: {"x": "m", "d_<source>_m": "m, ...", "<vehicle>.delta_v": "km/h"}:
  a `<word>` in a pattern stands for any text (unit_of).
A unit with a US form (crashlab.units.US_UNITS) is converted by crashlab.units.us_factor and the name says the
shown unit (shown_name: "x [ft]", "distance_m" -> "distance_ft", "V1.speed" -> "V1.speed [mph]"); degrees,
seconds, sigmas and coefficients stay as they are."""
from __future__ import annotations

import functools
import re

from ..units import SUFFIXES, US_UNITS, us_factor, us_unit

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
    "name" in its file unit; other columns as they are."""
    df = df.copy()
    names = {}
    for c in df.columns:
        m = HEADER.match(str(c))
        if m and m["unit"] in _FROM_US and not m["rest"]:
            si = _FROM_US[m["unit"]]
            df[c] = df[c] * us_factor(si)
            names[c] = m["name"]
    return df.rename(columns=names)


def json_in(data: dict, system: str) -> dict:
    """A JSON document (`simulate --json`, `compare --json`, `reconstruct --json`, ...) with every number whose
    key's unit (its "units" map: a key or a pattern, unit_of; an impact row's by "impacts.<key>") has a US form
    converted, and the map saying the US unit."""
    if system != "us":
        return data
    units = data.get("units", {})

    def walk(value, key=None, in_impacts=False):
        if isinstance(value, dict):
            return {k: walk(v, k, in_impacts) for k, v in value.items()}
        if isinstance(value, list):
            return [walk(v, key, in_impacts or key == "impacts") for v in value]
        if isinstance(value, (int, float)) and not isinstance(value, bool) and key is not None:
            return value_in(value, unit_of(f"impacts.{key}" if in_impacts else key, units), system)
        return value

    out = {k: walk(v, k) for k, v in data.items() if k != "units"}
    out["units"] = {k: (us_unit(unit_word(u)) + str(u)[len(unit_word(u)):] if unit_word(u) in US_UNITS else u)
                    for k, u in units.items()}
    return out
