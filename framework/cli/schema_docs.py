"""Reference documentation and JSON Schemas generated from the file schemas (the pydantic models), so the
docs cannot drift from what the loaders accept.

A schema is a root model plus `extras`: keys the root keeps as plain tables or arrays (checked later by
their own model, e.g. a scene's `[[uncertain]]` by crashlab.uncertainty.UncertainFile) documented and
published with that model. The study's models come from crashlab.reconstruction, which is why this module
lives in the command line's package, above it (docs/architecture.md; schema_roots below).

Regenerate docs/reference.md with `crashlab schema --markdown > docs/reference.md`;
tests/test_schema_docs.py fails when it differs from the generator's output or when a field has no
description.
"""
from __future__ import annotations

import json
import re
import types
import typing
from typing import Literal, Union

import annotated_types as at
from pydantic import BaseModel
from pydantic.fields import FieldInfo
from pydantic_core import PydanticUndefined

from ..units import US_UNITS, split_unit, us_unit

JSON_SCHEMA_DIALECT = "https://json-schema.org/draft/2020-12/schema"
TITLES = {"scene": "Scene file", "vehicle": "Vehicle file", "study": "Study file"}


def scene_root():
    """(root model, extras) of a scene file."""
    from ..scene_file import SceneFile
    from ..uncertainty import UncertainFile
    return SceneFile, {"uncertain": UncertainFile}


def vehicle_root():
    """(root model, extras) of a vehicle file."""
    from ..vehicle import VehicleFile
    return VehicleFile, {}


# ---------------------------------------------------------------- walking the models
def _strip(ann):
    """The annotation without Annotated and without None; (annotation, optional)."""
    while typing.get_origin(ann) is typing.Annotated:
        ann = typing.get_args(ann)[0]
    origin = typing.get_origin(ann)
    if origin in (Union, types.UnionType):
        args = [a for a in typing.get_args(ann) if a is not type(None)]
        if len(args) < len(typing.get_args(ann)):
            inner = args[0] if len(args) == 1 else Union[tuple(args)]
            return _strip(inner)[0], True
    return ann, False


def _is_model(ann) -> bool:
    return isinstance(ann, type) and issubclass(ann, BaseModel)


def type_name(ann) -> str:
    """A reader's name of a field's type: number, integer, string, boolean, table, one of ..., array of ..."""
    ann, _ = _strip(ann)
    origin, args = typing.get_origin(ann), typing.get_args(ann)
    if ann is float:
        return "number"
    if ann is int:
        return "integer"
    if ann is str:
        return "string"
    if ann is bool:
        return "boolean"
    if ann is dict or origin is dict:
        if args and _is_model(_strip(args[1])[0]):
            return "table of tables"
        return "table"
    if _is_model(ann):
        return "table"
    if origin is Literal:
        return "one of " + ", ".join(json.dumps(a) for a in args)
    if origin is list:
        inner = _strip(args[0])[0] if args else None
        if _is_model(inner):
            return "array of tables"
        return "array of " + (type_name(args[0]) if args else "values")
    if origin is tuple:
        if len(args) == 2 and args[1] is Ellipsis:
            return "array of " + type_name(args[0])
        names = [type_name(a) for a in args]
        return f"array of {len(names)} {names[0]}s" if len(set(names)) == 1 else "[" + ", ".join(names) + "]"
    if origin in (Union, types.UnionType):
        return " or ".join(type_name(a) for a in args)
    return getattr(ann, "__name__", str(ann))


def _num(v) -> str:
    return f"{v:g}" if isinstance(v, float) else str(v)


def _metadata(ann) -> list:
    """Constraints in Annotated layers of an annotation, through Optional (not into arrays)."""
    out = []
    while True:
        if typing.get_origin(ann) is typing.Annotated:
            args = typing.get_args(ann)
            for m in args[1:]:
                out.extend(m.metadata if isinstance(m, FieldInfo) else [m])
            ann = args[0]
            continue
        if typing.get_origin(ann) in (Union, types.UnionType):
            args = [a for a in typing.get_args(ann) if a is not type(None)]
            if len(args) == 1:
                ann = args[0]
                continue
        return out


def range_text(field, ann=None) -> str:
    """The bounds of a field (Field(ge/gt/le/lt/min_length/max_length)) as [lo, hi], (lo, hi], >= lo, ...;
    an array of bounded numbers (all alike) as `each [lo, hi]`."""
    ann = field.annotation if ann is None else ann
    own = _bounds(list(field.metadata) + _metadata(ann), _strip(ann)[0] is str)
    inner, _ = _strip(ann)
    if typing.get_origin(inner) in (tuple, list) and typing.get_args(inner):
        items = {_bounds(_metadata(a), False) for a in typing.get_args(inner) if a is not Ellipsis}
        if len(items) == 1 and "" not in items:
            own = "; ".join(x for x in (own, "each " + items.pop()) if x)
    return own


def _bounds(metadata, is_str) -> str:
    lo = hi = None
    lo_open = hi_open = False
    n_min = n_max = None
    for m in metadata:
        if isinstance(m, at.Ge):
            lo = m.ge
        elif isinstance(m, at.Gt):
            lo, lo_open = m.gt, True
        elif isinstance(m, at.Le):
            hi = m.le
        elif isinstance(m, at.Lt):
            hi, hi_open = m.lt, True
        elif isinstance(m, at.MinLen):
            n_min = m.min_length
        elif isinstance(m, at.MaxLen):
            n_max = m.max_length
    parts = []
    if lo is not None and hi is not None:
        parts.append(f"{'(' if lo_open else '['}{_num(lo)}, {_num(hi)}{')' if hi_open else ']'}")
    elif lo is not None:
        parts.append(f"{'>' if lo_open else '>='} {_num(lo)}")
    elif hi is not None:
        parts.append(f"{'<' if hi_open else '<='} {_num(hi)}")
    if n_min is not None or n_max is not None:
        unit = "characters" if is_str else "items"
        if n_max is None:
            parts.append(f"at least {n_min} {unit}")
        else:
            parts.append(f"{n_min or 0}-{n_max} {unit}")
    return "; ".join(parts)


def default_text(field) -> str:
    if field.default_factory is not None:
        value = field.default_factory()
    elif field.default is PydanticUndefined:
        return "required"
    else:
        value = field.default
    if value is None:
        return "absent"
    if isinstance(value, BaseModel):
        return "(table)"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float)):
        return _num(float(value)) if isinstance(value, float) else str(value)
    if isinstance(value, str):
        return json.dumps(value)
    return json.dumps(value)


_TRAILING_RANGE = re.compile(r";\s*(?:[\[(][^;]*[\])]|\|value\| <= [0-9.e+]+)$")


def _meaning(description: str, has_range: bool) -> tuple[str, str]:
    unit, meaning = split_unit(description)
    if has_range:  # the bounds are in their own column
        meaning = _TRAILING_RANGE.sub("", meaning).strip()
    return unit, meaning


def _key(name, field) -> str:
    return field.alias or name


def iter_fields(model: type[BaseModel], extras: dict | None = None, prefix: str = ""):
    """(key path, model, field name, field) of every field reachable from `model`, depth first; a key in
    `extras` (top level only) is walked as the model given there."""
    extras = extras or {}
    try:
        hints = typing.get_type_hints(model, include_extras=True)
    except (NameError, TypeError):
        hints = {}
    for name, field in model.model_fields.items():
        key = prefix + _key(name, field)
        yield key, model, name, field
        ann, _ = _strip(_annotation(field, hints.get(name)))
        origin, args = typing.get_origin(ann), typing.get_args(ann)
        if not prefix and name in extras:
            sub = extras[name]
            yield from iter_fields(sub, None, key + ("[]." if origin is list else "."))
        elif _is_model(ann):
            yield from iter_fields(ann, None, key + ".")
        elif origin is list and args and _is_model(_strip(args[0])[0]):
            yield from iter_fields(_strip(args[0])[0], None, key + "[].")
        elif origin is dict and args and _is_model(_strip(args[1])[0]):
            inner = _strip(args[1])[0]
            yield from iter_fields(inner, None, key + f".<{_placeholder(name)}>.")
        elif origin is dict and args and typing.get_origin(_strip(args[1])[0]) is dict:
            inner_args = typing.get_args(_strip(args[1])[0])
            if inner_args and _is_model(_strip(inner_args[1])[0]):
                yield from iter_fields(_strip(inner_args[1])[0], None, key + ".<source>.<vehicle>.")


def _annotation(field, hint):
    """The field's annotation, resolved from the module when pydantic kept a forward reference."""
    ann = field.annotation
    if hint is not None and ("ForwardRef" in repr(ann) or isinstance(ann, str)):
        return hint
    return ann


def _placeholder(name: str) -> str:
    return "vehicle" if name in ("rest", "edr", "reference", "damage") else "name"


def missing_descriptions(model, extras=None) -> list[str]:
    """`Model.field (key path)` of every reachable field without a description."""
    return [f"{m.__name__}.{n} ({k})" for k, m, n, f in iter_fields(model, extras) if not (f.description or "").strip()]


# ---------------------------------------------------------------- outputs
def json_schema(model: type[BaseModel], extras: dict | None = None, title: str | None = None) -> dict:
    """The JSON Schema (draft 2020-12) of a file: pydantic's model_json_schema (by alias, the keys as
    written) with each extra key's own model in $defs, so editors complete and check those tables too."""
    schema = model.model_json_schema(by_alias=True)
    defs = schema.setdefault("$defs", {})
    for key, sub in (extras or {}).items():
        sub_schema = sub.model_json_schema(by_alias=True)
        defs.update(sub_schema.pop("$defs", {}))
        defs[sub.__name__] = sub_schema
        field = model.model_fields[key]
        prop = schema["properties"][_key(key, field)]
        ref = {"$ref": f"#/$defs/{sub.__name__}"}
        if typing.get_origin(_strip(field.annotation)[0]) is list:
            prop.pop("additionalProperties", None)
            prop["type"] = "array"
            prop["items"] = ref
        else:
            for k in ("type", "additionalProperties"):
                prop.pop(k, None)
            prop["allOf"] = [ref]
    out = {"$schema": JSON_SCHEMA_DIALECT}
    if title:
        out["title"] = title
    out.update({k: v for k, v in schema.items() if k != "title" or not title})
    return out


def _cell(text: str) -> str:
    return str(text).replace("|", "\\|").replace("\n", " ")


def markdown_table(model, extras=None) -> str:
    rows = ["| key | type | unit | US unit | range | default | meaning |", "|---|---|---|---|---|---|---|"]
    for key, owner, name, field in iter_fields(model, extras):
        try:
            hint = typing.get_type_hints(owner, include_extras=True).get(name)
        except (NameError, TypeError):
            hint = None
        ann = _annotation(field, hint)
        rng = range_text(field, ann)
        unit, meaning = _meaning(field.description, bool(rng))
        us = us_unit(unit) if unit in US_UNITS else ""
        rows.append("| " + " | ".join(_cell(c) for c in (f"`{key}`", type_name(ann), unit, us, rng,
                                                          default_text(field), meaning)) + " |")
    return "\n".join(rows)


def reference_markdown(roots: dict) -> str:
    """docs/reference.md: one section per file kind (roots: kind -> (model, extras))."""
    out = ["# File reference", "",
           "Generated from the schemas by `crashlab schema --markdown > docs/reference.md` "
           "(framework/cli/schema_docs.py); tests/test_schema_docs.py fails when this file differs from the "
           "generator's output. Do not edit by hand.", "",
           "Key paths: `a.b` is key `b` of table `[a]`; `a[].b` is key `b` of each `[[a]]` table; `<name>` is "
           "a key you choose (a vehicle's name, a reference source). Range: `[lo, hi]` closed, `(lo, hi]` open "
           "at lo. Numbers are finite; true/false are not numbers; unknown keys are refused unless said "
           "otherwise. `crashlab schema scene|study|vehicle` prints the JSON Schema of each file for editors. "
           "A scene or study file with `units = \"us\"` gives its numbers in the US unit column (ft, mph, lb; "
           "an [[uncertain]] or [[free]] table's numbers and a counterfactual's set and shift values in their "
           "field's US unit; with the thesis objective hv_reference and near_optimal in ft, with the misfit in "
           "sigmas; a question's numbers in the variables' US units), read into the unit column before any check; "
           "ranges and defaults are in the unit column. A study's base scene says its own units; model_options "
           "are in the units `crashlab models --options` gives. Vehicle files are read in the unit column. "
           "`--units us` shows what a command prints and writes in the US units; the files it reads keep theirs.",
           ""]
    for kind, (model, extras) in roots.items():
        out += [f"## {TITLES.get(kind, kind)}", ""]
        doc = (model.__doc__ or "").strip()
        if doc:
            out += [" ".join(doc.split()), ""]
        out += [markdown_table(model, extras), ""]
    return "\n".join(out)


def schema_roots() -> dict:
    """kind -> (root model, extras) of the scene, vehicle and study files, read from their schemas: the study's
    models live in the reconstruction, which the command line's package sits above (docs/architecture.md)."""
    from crashlab.reconstruction.posterior import InferSection, QuestionFile
    from crashlab.reconstruction.schema import StudyFile

    from ..uncertainty import UncertainFile
    return {"scene": scene_root(), "vehicle": vehicle_root(),
            "study": (StudyFile, {"infer": InferSection, "questions": QuestionFile, "uncertain": UncertainFile})}
