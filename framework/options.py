"""Model options as schemas: every option with its meaning, unit, range and default, and whether it is an
accuracy knob (a step size, a tolerance, an iteration count) with the direction that makes it finer.

A model declares `class Options(ModelOptions)` with one `option(...)` field per key; `CollisionModel`
validates the keys of a config table against it (unknown keys, wrong types and values out of range are
errors that name the key) and keeps the result as `model.options`. `crashlab models --options NAME`
prints the table, and the comparison studies sweep exactly the knobs declared here (`accuracy_knobs`),
for third-party models too.
"""
from __future__ import annotations

from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError

FINER = ("smaller", "larger")  # the direction of an accuracy knob that makes a run more accurate


class OptionError(ValueError):
    """A model option that is unknown, of the wrong type or out of range; `key` names it."""

    def __init__(self, model: str, key: str, problem: str):
        self.model, self.key, self.problem = model, key, problem
        super().__init__(f"model {model!r}: option {key}: {problem}")


class UnknownOptionError(OptionError, TypeError):
    """An option the model does not have (a TypeError too, as for an unknown keyword argument)."""


class ModelOptions(BaseModel):
    """Base of a model's options: unknown keys are refused, types are strict (True is not 1, 1 is a
    valid float), numbers must be finite, and the object is frozen (a model's options do not change)."""

    model_config = ConfigDict(extra="forbid", strict=True, frozen=True, allow_inf_nan=False,
                              validate_default=True)


def option(default: Any, description: str, unit: str = "", *, accuracy: Literal["smaller", "larger"] | None = None,
           **bounds) -> Any:
    """A field of a ModelOptions: `description` says what it means, `unit` its SI unit ("" for none),
    `accuracy` which direction makes the result finer for an accuracy knob (None: a physical parameter or
    a switch), `bounds` pydantic's gt/ge/lt/le."""
    if accuracy is not None and accuracy not in FINER:
        raise ValueError(f"accuracy must be one of {FINER} or None, not {accuracy!r}")
    return Field(default, description=description, json_schema_extra={"unit": unit, "accuracy": accuracy},
                 **bounds)


def parse(model_name: str, schema: type[ModelOptions] | None, values: dict) -> ModelOptions | None:
    """The validated options of a model; OptionError naming the first bad key."""
    if schema is None:
        if values:
            raise UnknownOptionError(model_name, sorted(values)[0], "this model takes no options")
        return None
    try:
        return schema(**values)
    except ValidationError as err:
        first = err.errors()[0]
        key = ".".join(str(p) for p in first["loc"])
        msg = first["msg"].removeprefix("Value error, ")
        if not key:  # a check across options (a model_validator) says "<key>: <problem>"
            head, _, rest = msg.partition(": ")
            key, msg = (head, rest) if head in schema.model_fields else ("(options)", msg)
        if first["type"] == "extra_forbidden":
            raise UnknownOptionError(model_name, key, f"unknown option; known: {', '.join(schema.model_fields)}") \
                from None
        raise OptionError(model_name, key, msg) from None


def _bounds(field) -> str:
    parts = []
    for meta in field.metadata:
        for attr, sign in (("gt", ">"), ("ge", ">="), ("lt", "<"), ("le", "<=")):
            v = getattr(meta, attr, None)
            if v is not None:
                parts.append(f"{sign} {v:g}" if isinstance(v, (int, float)) else f"{sign} {v}")
    return ", ".join(parts)


def describe(schema: type[ModelOptions] | None) -> list[dict]:
    """One dict per option: name, type, unit, default, range, accuracy (finer direction or ""), meaning."""
    if schema is None:
        return []
    rows = []
    for name, field in schema.model_fields.items():
        extra = field.json_schema_extra or {}
        ann = field.annotation
        rows.append({"name": name, "type": getattr(ann, "__name__", str(ann)), "unit": extra.get("unit", ""),
                     "default": field.default, "range": _bounds(field), "accuracy": extra.get("accuracy") or "",
                     "description": field.description or ""})
    return rows


def accuracy_knobs(schema: type[ModelOptions] | None) -> dict[str, str]:
    """name -> the direction ("smaller" or "larger") that makes the run finer, for every accuracy knob."""
    return {r["name"]: r["accuracy"] for r in describe(schema) if r["accuracy"]}

