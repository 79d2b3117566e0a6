"""`--units us`: printed tables and JSON in US customary units (ft, mph, lb, lbf, ft-lbf), converted where they
are shown; the computation and the files it reads stay in the file units (crashlab.units, crashlab.file_units).

A table says its units in its headers ("x [m]", "heading [deg, -180..180]"); a JSON result in its "units" map
(key -> unit, "impacts.<column>" for the impact rows). A unit with a US form (crashlab.units.US_UNITS) is
converted by crashlab.units.us_factor and renamed; degrees, seconds and coefficients stay as they are."""
from __future__ import annotations

import re

from ..units import US_UNITS, us_factor, us_unit

HEADER = re.compile(r"^(?P<name>.*) \[(?P<unit>[^\],]+)(?P<rest>,[^\]]*)?\]$")


def table_in(df, system: str):
    """The table with every column whose header names a unit of US_UNITS in its US unit (system "us"), or as
    it is (system "si")."""
    if system != "us":
        return df
    df = df.copy()
    names = {}
    for c in df.columns:
        m = HEADER.match(str(c))
        if m and m["unit"] in US_UNITS:
            df[c] = df[c] / us_factor(m["unit"])
            names[c] = f"{m['name']} [{us_unit(m['unit'])}{m['rest'] or ''}]"
    return df.rename(columns=names)


def _unit_word(text: str) -> str:
    """The unit a JSON units entry starts with ("km/h, global" -> "km/h")."""
    return str(text).split(",")[0].strip()


def json_in(data: dict, system: str) -> dict:
    """A `simulate --json` / `compare --json` document with every value whose key's unit (its "units" map; an
    impact row's by "impacts.<key>") has a US form converted, and the map saying the US unit."""
    if system != "us":
        return data
    units = data.get("units", {})

    def factor(key, in_impacts):
        if not in_impacts and key not in units and key.startswith("d_") and key.endswith(("_m", "_deg")):
            key = "d_<source>" + key[key.rindex("_"):]  # a difference to a published result (JSON_UNITS)
        unit = units.get(f"impacts.{key}" if in_impacts else key)
        word = _unit_word(unit) if unit else ""
        return us_factor(word) if word in US_UNITS else 1.0

    def walk(value, key=None, in_impacts=False):
        if isinstance(value, dict):
            return {k: walk(v, k, in_impacts) for k, v in value.items()}
        if isinstance(value, list):
            return [walk(v, key, in_impacts or key == "impacts") for v in value]
        if isinstance(value, (int, float)) and not isinstance(value, bool) and key is not None:
            f = factor(key, in_impacts)
            return value / f if f != 1.0 else value
        return value

    out = {k: walk(v, k) for k, v in data.items() if k != "units"}
    out["units"] = {k: (us_unit(_unit_word(u)) + str(u)[len(_unit_word(u)):] if _unit_word(u) in US_UNITS else u)
                    for k, u in units.items()}
    return out
