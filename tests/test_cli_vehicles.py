"""`crashlab vehicles` and `--json` (issue 24 item 1): every library vehicle's key numbers and the structure of
each side that can be struck (CRASH3 A, B, the width they hold over, published / estimate / class default), within
120 columns; the expected values are read from the vehicle files here, not through crashlab.cli.vehicles."""
from __future__ import annotations

import json
import tomllib
from pathlib import Path

import pytest

import crashlab

LIBRARY = Path(crashlab.__file__).parent / "vehicles"
SIDES = ("front", "rear", "side")


def _files() -> dict:
    """library name -> the vehicle file's TOML, read directly."""
    out = {p.stem: tomllib.loads(p.read_text()) for p in sorted(LIBRARY.glob("*.toml"))}
    assert len(out) >= 20
    return out


def _expected_structure(data: dict) -> dict:
    """side -> (A, B, width, kind, source) from a vehicle file's own [structure.<side>]; a side it does not give
    takes the class default (its numbers not checked here: None)."""
    out = {}
    for side in SIDES:
        given = (data.get("structure") or {}).get(side)
        if given is None:
            out[side] = (None, None, data["length"] if side == "side" else data["width"], "class default", None)
            continue
        src = given.get("source", "")
        kind = ("no source" if not src else "estimate" if src.startswith("estimate") else
                "measured" if src.startswith("measured") else "published")
        width = given.get("width", data["length"] if side == "side" else data["width"])
        out[side] = (given["A"], given["B"], width, kind, src)
    return out


def _main(capsys, *args):
    from crashlab.cli import main
    code = main(["vehicles", *args])
    return code, capsys.readouterr()


def test_vehicles_json_gives_every_side_of_every_vehicle_as_its_file_does(capsys):
    code, out = _main(capsys, "--json")
    assert code == 0 and out.err == ""
    records = {r["vehicle"]: r for r in json.loads(out.out)}
    files = _files()
    assert set(records) == set(files)
    for name, data in files.items():
        r = records[name]
        assert (r["name"], r["class"], r["mass"], r["length"], r["width"], r["yaw_inertia"]) == (
            data["name"], data["class"], data["mass"], data["length"], data["width"], data["yaw_inertia"]), name
        assert r["yaw_inertia_source"] == data["sources"]["yaw_inertia"]
        assert set(r["structure"]) == set(SIDES)
        for side, (a, b, width, kind, src) in _expected_structure(data).items():
            s = r["structure"][side]
            assert (s["width"], s["kind"]) == (width, kind), (name, side)
            if a is not None:
                assert (s["A"], s["B"], s["source"]) == (a, b, src), (name, side)
    # the three sides differ (a table repeating the front's numbers fails here)
    clio = records["clio"]["structure"]
    assert len({(s["A"], s["B"], s["width"]) for s in clio.values()}) == 3


def test_vehicles_table_shows_every_side_within_120_columns(capsys):
    code, out = _main(capsys)
    assert code == 0 and out.err == ""
    lines = out.out.splitlines()
    assert max(len(line) for line in lines) <= 120
    assert any("A [kN/m]" in line and "B [kN/m^2]" in line and "width [m]" in line for line in lines)
    rows = {}
    for line in lines:
        parts = line.split()
        if len(parts) >= 6 and parts[1] in SIDES and parts[0] != "vehicle":
            rows[parts[0], parts[1]] = parts[2:]
    files = _files()
    for name, data in files.items():
        for side, (a, b, width, kind, _) in _expected_structure(data).items():
            shown = rows[name, side]
            assert shown[2] == f"{width:.3f}" and " ".join(shown[3:]) == kind, (name, side, shown)
            if a is not None:
                assert shown[:2] == [f"{a / 1e3:.1f}", f"{b / 1e3:.0f}"], (name, side, shown)
        vehicle_line = next(line for line in lines if line.split()[:2] == [name, data["class"]])
        assert f"{data['mass']:.1f}" in vehicle_line.split() and f"{data['yaw_inertia']:.1f}" in vehicle_line.split()
    assert len(rows) == 3 * len(files)


def test_a_side_without_structure_is_the_class_default_and_a_side_without_source_says_so(tmp_path, capsys):
    from crashlab.cli.vehicles import format_library_table, vehicle_record
    text = (LIBRARY / "clio.toml").read_text()
    data = tomllib.loads(text)
    head, rest = text.split("[structure.rear]", 1)
    rest = rest[rest.index("[structure.side]"):]  # the rear removed
    side_src = data["structure"]["side"]["source"]
    f = tmp_path / "mine.toml"
    f.write_text(head + rest.replace(f"source = {json.dumps(side_src)}", ""))
    assert "source" not in tomllib.loads(f.read_text())["structure"]["side"]
    r = vehicle_record(f)
    assert r["vehicle"] == "mine"
    assert r["structure"]["front"]["kind"] == "estimate"
    assert r["structure"]["rear"]["kind"] == "class default" and "class default" in r["structure"]["rear"]["source"]
    assert r["structure"]["rear"]["width"] == data["width"]
    side = r["structure"]["side"]
    assert side["kind"] == "no source" and side["A"] == data["structure"]["side"]["A"]
    table = format_library_table([r])
    assert any(line.split()[:2] == ["mine", "rear"] and line.endswith("class default") for line in table.splitlines())
    assert any(line.split()[:2] == ["mine", "side"] and line.endswith("no source") for line in table.splitlines())


@pytest.mark.parametrize("source, kind", [("measured: LVIPD", "measured"), ("estimate: I = m a b", "estimate"),
                                          ("Francisco 2013, Table 3.3", "published"), ("", "no source"),
                                          ("derived: a = L/2 - ...", "derived")])
def test_the_kind_of_a_source_is_its_first_word(source, kind):
    from crashlab.cli.vehicles import source_kind
    assert source_kind(source) == kind
