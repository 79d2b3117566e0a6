"""The file reference (docs/reference.md) and the JSON Schemas are generated from the pydantic schemas
((crashlab.cli.schema_docs)): every field is described, the docs equal the generator's output, the printed
schemas accept the bundled files."""
from __future__ import annotations

import json
import tomllib
from pathlib import Path

import pytest

from crashlab.cli import main
from crashlab.cli.schema_docs import iter_fields, missing_descriptions, reference_markdown, schema_roots

REPO = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize("kind", ["scene", "study", "vehicle"])
def test_every_field_has_a_description(kind):
    model, extras = schema_roots()[kind]
    assert len(list(iter_fields(model, extras))) > 10  # the walk reaches the nested tables
    missing = missing_descriptions(model, extras)
    assert not missing, "fields without a description (add Field(description=...)):\n" + "\n".join(missing)


def test_missing_description_is_reported():
    from pydantic import BaseModel, Field

    class Inner(BaseModel):
        a: float = Field(1.0, description="m, described")
        b: float = 2.0

    class Outer(BaseModel):
        inner: list[Inner] = Field(default_factory=list, description="tables")

    assert missing_descriptions(Outer) == ["Inner.b (inner[].b)"]


def test_reference_md_is_the_generators_output():
    on_disk = (REPO / "docs" / "reference.md").read_text(encoding="utf-8")
    assert on_disk == reference_markdown(schema_roots()), \
        "docs/reference.md is stale: run `crashlab schema --markdown > docs/reference.md`"


def test_reference_lists_unit_range_default():
    md = reference_markdown(schema_roots())
    row = next(line for line in md.splitlines() if line.startswith("| `vehicles[].speed` |"))
    assert row.split(" | ")[1:6] == ["number", "km/h", "mph", "[0, 400]", "0"]
    row = next(line for line in md.splitlines() if line.startswith("| `mass` |"))
    assert row.split(" | ")[1:6] == ["number", "kg", "lb", "[50, 60000]", "required"]
    row = next(line for line in md.splitlines() if line.startswith("| `vehicles[].heading` |"))
    assert row.split(" | ")[2:4] == ["deg", ""]  # no US form: read as written
    assert "| `free[].lower` |" in md and "| `infer.walkers` |" in md and "| `questions[].expr` |" in md


def _schema(kind, capsys):
    assert main(["schema", kind]) == 0
    return json.loads(capsys.readouterr().out)


def _check(data, schema, root, path="") -> list[str]:
    """A small JSON Schema check (objects, arrays, $ref, allOf/anyOf, required, additionalProperties,
    type, enum, bounds): jsonschema is not a dependency."""
    if "$ref" in schema:
        return _check(data, root["$defs"][schema["$ref"].split("/")[-1]], root, path)
    errors = []
    for sub in schema.get("allOf", []):
        errors += _check(data, sub, root, path)
    if "anyOf" in schema:
        if all(_check(data, sub, root, path) for sub in schema["anyOf"]):
            errors.append(f"{path}: matches none of anyOf")
        return errors
    if "const" in schema and data != schema["const"]:
        errors.append(f"{path}: {data!r} is not {schema['const']!r}")
    if "enum" in schema and data not in schema["enum"]:
        errors.append(f"{path}: {data!r} not in {schema['enum']}")
    t = schema.get("type")
    ok = {"object": dict, "array": (list, tuple), "string": str, "number": (int, float), "integer": int,
          "boolean": bool, "null": type(None)}
    if t and not isinstance(data, ok[t]):
        return errors + [f"{path}: {type(data).__name__} is not {t}"]
    if isinstance(data, (int, float)) and not isinstance(data, bool):
        if "minimum" in schema and data < schema["minimum"] or "maximum" in schema and data > schema["maximum"]:
            errors.append(f"{path}: {data} out of bounds")
    if isinstance(data, dict):
        props = schema.get("properties", {})
        errors += [f"{path}.{k}: required" for k in schema.get("required", []) if k not in data]
        for k, v in data.items():
            if k in props:
                errors += _check(v, props[k], root, f"{path}.{k}")
            elif isinstance(schema.get("additionalProperties"), dict):
                errors += _check(v, schema["additionalProperties"], root, f"{path}.{k}")
            elif schema.get("additionalProperties") is False:
                errors.append(f"{path}.{k}: unknown key")
    if isinstance(data, (list, tuple)):
        for i, v in enumerate(data):
            sub = schema.get("prefixItems", [])[i] if i < len(schema.get("prefixItems", [])) else schema.get("items")
            if sub:
                errors += _check(v, sub, root, f"{path}[{i}]")
    return errors


def _files(kind):
    if kind == "vehicle":
        return sorted((REPO / "framework" / "vehicles").glob("*.toml"))
    files = sorted(p for p in (REPO / "studies").rglob("*.toml"))
    scenes = [p for p in files if "vehicles" in tomllib.loads(p.read_text())]
    return scenes if kind == "scene" else \
        [p for p in files if "free" in tomllib.loads(p.read_text())]


@pytest.mark.parametrize("kind", ["scene", "study", "vehicle"])
def test_printed_schema_accepts_the_bundled_files(kind, capsys):
    schema = _schema(kind, capsys)
    assert schema["$schema"].startswith("https://json-schema.org/")
    files = _files(kind)
    assert files
    for f in files:
        errors = _check(tomllib.loads(f.read_text()), schema, schema)
        assert not errors, f"{f.relative_to(REPO)}: {errors}"


def test_printed_schema_refuses_bad_input(capsys):
    """The check can fail: an unknown key, a speed out of range and a wrong type are found."""
    schema = _schema("scene", capsys)
    assert set(schema["properties"]) >= {"name", "duration", "road", "impact", "vehicles", "barriers",
                                          "reference", "uncertain"}
    bad = {"vehicles": [{"name": "a", "vehicle": "clio", "speed": 500, "colour": "red"}], "duration": "long",
           "uncertain": [{"field": "road.friction", "distribution": "gaussian"}]}
    errors = " ".join(_check(bad, schema, schema))
    assert "colour: unknown key" in errors and ".speed: 500 out of bounds" in errors
    assert ".duration: str is not number" in errors and "gaussian" in errors


def test_printed_schema_takes_the_words_the_loader_takes(capsys):
    """restitution = "speed" and point = "engagement" load, but the schema said number and array-or-null (a
    probe, 2026-11-28): an editor flagged valid files. Now each is its type or its word, and nothing else."""
    schema = _schema("scene", capsys)
    car = {"name": "V1", "vehicle": "clio"}
    for impact in ({"restitution": "speed"}, {"point": "engagement"}, {"restitution": 0.2, "point": [1.0, 2.0]}):
        assert not _check({"impact": impact, "vehicles": [car]}, schema, schema), impact
    for impact in ({"restitution": "sped"}, {"restitution": 1.5}, {"point": "engaged"}, {"point": [1.0, 1e6]}):
        assert _check({"impact": impact, "vehicles": [car]}, schema, schema), impact


def test_version(capsys):
    from importlib.metadata import version
    with pytest.raises(SystemExit) as e:
        main(["--version"])
    assert e.value.code == 0
    assert capsys.readouterr().out.strip() == f"crashlab {version('crashlab')}"
