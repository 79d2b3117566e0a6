"""The input files (TOML) read and checked against their pydantic schemas: whatever keeps a file from being
read, and the first thing its schema refuses, is one InputError line naming the file and the key (an unknown
key with the nearest known one, "did you mean"; a bound in the key's unit, as its description states it).
Scene, vehicle, study and posterior files all go through here.
"""
from __future__ import annotations

import difflib
import math
import re
import tomllib
import typing
from pathlib import Path

from pydantic import BaseModel, ValidationError

from .errors import InputError
from .units import US_UNITS, split_unit, us_factor, us_unit

TOML_BYTES_MAX = 64 << 20  # bytes: a scene, study or vehicle file is a few kB


def read_toml(path: Path, what: str = "file") -> dict:
    """A TOML file as a dict; anything that keeps it from being read is an InputError naming the file: not
    found, a path the system refuses (too long: a name of more than 255 bytes), malformed, not UTF-8, an
    integer of more than Python's 4,300 digits, arrays or tables nested deeper than Python's recursion
    allows (the line and its key named), larger than TOML_BYTES_MAX (a device such as /dev/zero read forever)."""
    try:
        with open(path, "rb") as fh:
            data = fh.read(TOML_BYTES_MAX + 1)
        if len(data) <= TOML_BYTES_MAX:
            return tomllib.loads(data.decode())
    except FileNotFoundError:
        raise InputError(path, what, "file not found") from None
    except tomllib.TOMLDecodeError as err:
        bom = " (the file begins with a byte-order mark, U+FEFF, which TOML does not allow: save it as UTF-8 " \
              "without BOM)" if data.startswith(b"\xef\xbb\xbf") else ""
        raise InputError(path, "(syntax)", f"malformed TOML: {err}{bom}") from None
    except UnicodeDecodeError:
        raise InputError(path, "(encoding)", "not a UTF-8 text file") from None
    except OSError as err:
        raise InputError(path, what, err.strerror or str(err)) from None
    except ValueError:  # int(): more digits than sys.get_int_max_str_digits()
        raise InputError(path, _line_key(path, rf"[0-9_]{{{_INT_DIGITS_MAX},}}"),
                         f"an integer of more than {_INT_DIGITS_MAX:,} digits") from None
    except RecursionError:
        raise InputError(path, _line_key(path, r"(?:[\[{]\s*){100,}"),
                         "arrays or tables nested too deep (hundreds of levels)") from None
    raise InputError(path, what, f"larger than {TOML_BYTES_MAX >> 20} MB: not a scene, study or vehicle file")


def file_kind(data: dict) -> str | None:
    """The kind of input file `data` is by its top-level keys: "scene" ([[vehicles]], no scene named), "study" (it
    names a scene, or has [[free]] or [evidence], and no [[vehicles]]), "vehicle" (mass and wheelbase), else None
    (too little to tell: the schema's own messages say what is wrong)."""
    if "vehicles" in data and "scene" not in data:
        return "scene"
    if "vehicles" not in data and {"scene", "free", "evidence"} & set(data):
        return "study"
    if {"mass", "wheelbase"} <= set(data):
        return "vehicle"
    return None


KIND_SIGN = {"scene": "it has [[vehicles]]", "study": "it names a scene and what to search",
              "vehicle": "it gives one vehicle's mass and wheelbase"}


def check_kind(path, data: dict, expected: str) -> None:
    """InputError when the file read as a `expected` (scene, study, vehicle) file is of another kind: one line
    saying which, where the schema said only "unknown key" of its first key (a probe, 2026-11-28)."""
    kind = file_kind(data)
    if kind is not None and kind != expected:
        raise InputError(path, "(top level)", f"this is a {kind} file ({KIND_SIGN[kind]}), not a {expected} file")


# pydantic's error types of a violated bound (ge, gt, le, lt)
BOUND_ERRORS = ("greater_than", "greater_than_equal", "less_than", "less_than_equal")
_INT_DIGITS_MAX = 4300  # Python's default int <-> str conversion limit (sys.get_int_max_str_digits)


def _line_key(path, pattern: str) -> str:
    """'KEY (line N)' of the first line of the file matching `pattern`, for a refusal that tomllib does not
    locate; "(syntax)" when none does."""
    try:
        text = Path(path).read_text(encoding="utf-8", errors="replace")
    except OSError:
        return "(syntax)"
    for n, line in enumerate(text.splitlines(), 1):
        if re.search(pattern, line):
            key = line.split("=", 1)[0].strip() if "=" in line else ""
            return f"{key} (line {n})" if key and len(key) < 80 else f"(line {n})"
    return "(syntax)"


def _shown(value) -> str:
    """A short one-line rendering of a bad input value, in TOML spelling for booleans."""
    if isinstance(value, bool):
        return "true" if value else "false"
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def schema_in(annotation):
    """The pydantic model an annotation holds (itself, or inside list[...], dict[..., ...], X | None, tuple[...]),
    or None."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return annotation
    for arg in typing.get_args(annotation):
        found = schema_in(arg)
        if found is not None:
            return found
    return None


def _field_at(schema, part):
    """The pydantic field named (or aliased) `part` of `schema`, or None."""
    if schema is None:
        return None
    return schema.model_fields.get(part) or next((f for f in schema.model_fields.values() if f.alias == part), None)


def _dict_depth(annotation) -> int:
    """How many dict levels hold an annotation's model (dict[str, dict[str, M]]: 2), whose keys are names of the
    file's own (reference.<source>.<vehicle>)."""
    if typing.get_origin(annotation) is dict:
        return 1 + _dict_depth(typing.get_args(annotation)[1])
    return max((_dict_depth(a) for a in typing.get_args(annotation)), default=0)


def _walk(schema, parts):
    """(the pydantic model, the field) at the dotted `parts` of a file with the schema `schema`, list indices and
    the keys of a dict's table (a reference's source and vehicle names) stepped over; (None, None) where lost."""
    field, mapping = None, 0
    for part in parts:
        if isinstance(part, int) or schema is None:
            continue
        found = _field_at(schema, part)
        if found is None and mapping:  # a name of the file's own in a dict of tables
            mapping -= 1
            continue
        field = found
        schema = None if found is None else schema_in(found.annotation)
        mapping = 0 if found is None else _dict_depth(found.annotation)
    return schema, field


def keys_at(schema, loc) -> list[str]:
    """The keys the table at `loc` (a pydantic error's location, list indices included) of a file with the
    pydantic schema `schema` accepts; [] where unknown."""
    schema = _walk(schema, loc)[0]
    if schema is None:
        return []
    return [f.alias or name for name, f in schema.model_fields.items()]


def unit_at(schema, loc) -> str:
    """The unit of the key at `loc` of a file with the pydantic schema `schema`, as its description states it
    (crashlab.units.split_unit); "" where unknown or unitless."""
    keys = [p for p in loc if not isinstance(p, int)]
    if not keys:
        return ""
    field = _field_at(_walk(schema, keys[:-1])[0], keys[-1])
    unit = split_unit(field.description)[0] if field is not None else ""
    return "" if unit == "-" else unit


def pydantic_error(file, err: ValidationError, prefix: str = "", schema=None, system: str = "si",
                   given=None) -> InputError:
    """The first validation error as one InputError line (file, dotted key, problem); with the file's pydantic
    `schema`, an unknown key gets the nearest known one ("did you mean"). A file written in US units (`system`
    "us", crashlab.file_units) has a violated bound said in its units, with its value from `given` (the table as
    the file gives it, before the conversion)."""
    errors = err.errors()
    first = errors[0]
    if first["type"] == "missing":  # a misspelt key is both missing and unknown: the unknown one names the typo
        first = next((e for e in errors if e["type"] == "extra_forbidden" and e["loc"][:-1] == first["loc"][:-1]),
                     first)
    key = ".".join(str(p) for p in first["loc"]) or "(top level)"
    msg = first["msg"].removeprefix("Value error, ")
    if first["type"] == "extra_forbidden":
        msg = "unknown key"
        close = difflib.get_close_matches(str(first["loc"][-1]), keys_at(schema, first["loc"][:-1]), n=1)
        if close:
            msg += f"; did you mean {close[0]!r}?"
    elif first["type"] == "missing":
        msg = "missing key"
    elif first["type"] == "string_pattern_mismatch":
        msg = pattern_problem(first.get("ctx", {}).get("pattern", ""), first.get("input"))
    elif first["type"].endswith("_type") or first["type"] in ("finite_number", "bool_parsing", "literal_error"):
        msg += f", got {_shown(first.get('input'))}"
    elif first["type"] in BOUND_ERRORS:  # the bound in the key's unit, and what the file gave
        unit = unit_at(schema, first["loc"])
        if system == "us" and unit in US_UNITS:  # the file's own value and unit, not the converted ones
            msg = _us_bound_problem(first, unit, given)
        else:
            msg = f"{msg}{' ' + unit if unit else ''}, got {_shown(first.get('input'))}"
    return InputError(file, prefix + key, msg)


# a pattern that refuses control characters in a name or a text: its message says so
_CONTROL_PATTERN = re.compile(r"\^\[\^\\x00-\\x1f\\x7f\][+*]\$")
# a pattern that is an enumeration of words, ^(a|b|c)$: its message names them
_ENUMERATION = re.compile(r"\^\(([\w-]+(?:\|[\w-]+)*)\)\$")


def pattern_problem(pattern: str, value) -> str:
    """What a string that does not match the schema's `pattern` is refused for, in the file's terms: no control
    characters (where that is the pattern's purpose), one of the words of an enumeration ^(a|b)$, or the
    pattern itself; with the value the file gave."""
    if _CONTROL_PATTERN.fullmatch(pattern):
        return "no control characters (line breaks, tabs) allowed"
    words = _ENUMERATION.fullmatch(pattern)
    if words:
        return f"one of {', '.join(words.group(1).split('|'))}, got {_shown(value)}"
    return f"must match the pattern {pattern}, got {_shown(value)}"


# pydantic's bound errors in words, as its messages say them
_BOUND_WORDS = {"greater_than": "greater than", "greater_than_equal": "greater than or equal to",
                "less_than": "less than", "less_than_equal": "less than or equal to"}


def _us_bound_problem(error: dict, unit: str, given) -> str:
    """A violated bound of a file written in US units (crashlab.file_units converted it before the check): the
    bound in the key's US unit, rounded towards the values it accepts (exact in the file unit beside it), and the
    value as the file gives it (from `given`, the table before the conversion, where the error's location finds
    a number there; else the checked value converted back)."""
    factor = us_factor(unit)
    bound = next(iter(error.get("ctx", {}).values()), None)
    value = _at(given, error["loc"])
    if value is None:
        checked = error.get("input")
        value = (float(f"{checked / factor:.12g}") if isinstance(checked, (int, float))
                 and not isinstance(checked, bool) else checked)
    shown = f"{_shown(value)} {us_unit(unit)}" if isinstance(value, (int, float)) else _shown(value)
    if not isinstance(bound, (int, float)):
        return f"{error['msg']} {unit}, got {shown}"
    limit = _towards(bound / factor, up=error["type"].startswith("greater"))
    return (f"Input should be {_BOUND_WORDS[error['type']]} {limit} {us_unit(unit)} ({bound:g} {unit}), "
            f"got {shown}")


def _at(data, loc):
    """The number at `loc` (a pydantic error's location) of `data`, or None."""
    for part in loc:
        try:
            data = data[part]
        except (KeyError, IndexError, TypeError):
            return None
    return data if isinstance(data, (int, float)) and not isinstance(data, bool) else None


def _towards(x: float, up: bool) -> str:
    """x with four significant figures (at least one decimal), rounded up (a lower bound) or down (an upper one):
    a value the exact bound refuses never lies on the accepted side of the bound shown."""
    if x == 0 or not math.isfinite(x):
        return f"{x:g}"
    decimals = max(1, 3 - math.floor(math.log10(abs(x))))
    scale = 10 ** decimals
    r = (math.ceil if up else math.floor)(x * scale - (1e-9 if up else -1e-9)) / scale
    return f"{r:.{decimals}f}".rstrip("0").rstrip(".")
