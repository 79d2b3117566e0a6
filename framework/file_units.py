"""Files written in US customary units: a scene file that says `units = "us"` gives every length in ft, every
speed in mph, every mass in lb (and the other keys of docs/reference.md's US column); it is read by turning
those values into the file units the rest of crashlab speaks (m, km/h, kg, ...) before anything checks it.

The unit of a key is the one its schema's description starts with (crashlab.units.split_unit, the same that
docs/reference.md prints); a value whose unit depends on a field it names ([[uncertain]]'s bounds, a study's free
variables) takes that field's unit (crashlab.fields.UNITS). Degrees, seconds and coefficients have no US form
and are read as written. Every conversion is a factor (crashlab.units.us_factor, through pint)."""
from __future__ import annotations

from . import fields
from .errors import InputError
from .input_files import schema_in
from .units import UNIT_SYSTEMS, split_unit, us_factor

UNITS_KEY = "units"
# keys whose values are in the unit of the field the same table names (`field = "vehicles.V1.speed"`)
FIELD_VALUE_KEYS = ("lower", "upper", "mode", "mean", "sd")


def system_of(data: dict, file) -> str:
    """The unit system a file says it is written in ("si" when it says nothing); another word: InputError."""
    system = data.get(UNITS_KEY, "si") if isinstance(data, dict) else "si"
    if system not in UNIT_SYSTEMS:
        raise InputError(file, UNITS_KEY, f"units = {system!r}: give one of {', '.join(map(repr, UNIT_SYSTEMS))}")
    return system


def scaled(value, factor: float):
    """A number or a (nested) list of numbers times factor; anything else (a word, a boolean) as it is."""
    if isinstance(value, bool) or factor == 1.0:
        return value
    if isinstance(value, (int, float)):
        return value * factor
    if isinstance(value, list):
        return [scaled(v, factor) for v in value]
    return value


def field_unit(path) -> str:
    """The file unit of a crashlab.fields path ("" when the path is no field: the schema's checks name it)."""
    try:
        return fields.parse(path).unit
    except (ValueError, KeyError, TypeError, AttributeError):
        return ""


def from_us(data, schema, nested: dict | None = None):
    """A copy of `data` (a table of a file with the pydantic `schema`) with every US value in its file unit.
    `nested` names schemas of keys the schema leaves open (a vehicle's `overrides`: the vehicle file's)."""
    if not isinstance(data, dict) or schema is None:
        return data
    nested = nested or {}
    out = {}
    by_alias = {f.alias or name: f for name, f in schema.model_fields.items()}
    for key, value in data.items():
        field = by_alias.get(key)
        if field is None:
            out[key] = value  # an unknown key: the schema's check names it
            continue
        inner = nested.get(key) or schema_in(field.annotation)
        if inner is not None:
            out[key] = _tables(value, inner, nested)
        elif key in FIELD_VALUE_KEYS and isinstance(data.get("field"), str):
            out[key] = scaled(value, us_factor(field_unit(data["field"])))
        else:
            out[key] = scaled(value, us_factor(split_unit(field.description)[0]))
    return out


def _tables(value, schema, nested):
    """A table, a list of tables, or tables keyed by names (reference.<source>.<vehicle>) of `schema`."""
    if isinstance(value, list):
        return [_tables(v, schema, nested) for v in value]
    if isinstance(value, dict) and not (value.keys() & set(f.alias or n for n, f in schema.model_fields.items())):
        return {k: _tables(v, schema, nested) for k, v in value.items()}
    return from_us(value, schema, nested)
