"""US customary units (issue 26 item 4): a scene written in ft, mph and lb (`units = "us"`) gives the same results
as its SI twin (1e-9 relative), and `--units us` prints ft, mph, lb in every table header and JSON unit.

The twin is written here with the exact definitions (1 ft = 0.3048 m, 1 mile = 1609.344 m, 1 lb = 0.45359237 kg;
NIST SP 811), independent of the pint conversion the code uses."""
from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

import crashlab

FT, MPH, LB = 0.3048, 1.609344, 0.45359237  # m, km/h, kg per US unit (exact by definition)

SCENE = """{units}
name = "US twin"
duration = 6.0

[road]
friction = 0.8
[[road.zones]]
friction = 0.3
polygon = [[{z0}, {zm}], [{z1}, {zm}], [{z1}, {zp}], [{z0}, {zp}]]
[[road.lines]]
points = [[{l0}, {lm}], [{l1}, {lm}]]

[impact]
restitution = 0.1
friction = 0.3

[[vehicles]]
name = "V1"
vehicle = "clio"
x = 0.0
y = {y1}
heading = 0.0
speed = {v1}
wheels = "locked_after_impact"
[vehicles.overrides]
mass = {m1}
length = {len1}

[[vehicles]]
name = "V2"
vehicle = "clio"
x = {x2}
y = 0.0
heading = 90.0
speed = {v2}
wheels = "locked_after_impact"

[[barriers]]
x = {bx}
y = {by}
heading = 0.0
length = {bl}
width = {bw}

[reference.pc.V1]
x = {rx}
y = {ry}
heading = 26.0
vx = {rv}

[[uncertain]]
field = "vehicles.V1.speed"
distribution = "normal"
mean = {v1}
sd = {sd}
"""
SI = dict(z0=4.0, z1=20.0, zm=-5.0, zp=5.0, l0=-10.0, l1=30.0, lm=-3.5, y1=0.1, v1=50.0, m1=1150.0, len1=4.0,
          x2=3.5, v2=30.0, bx=25.0, by=12.0, bl=10.0, bw=0.5, rx=6.66, ry=1.64, rv=1.0, sd=3.0)
LENGTHS = {"z0", "z1", "zm", "zp", "l0", "l1", "lm", "y1", "len1", "x2", "bx", "by", "bl", "bw", "rx", "ry"}
SPEEDS = {"v1", "v2", "rv", "sd"}


def us_values():
    return {k: v / FT if k in LENGTHS else v / MPH if k in SPEEDS else v / LB if k == "m1" else v
            for k, v in SI.items()}


@pytest.fixture(scope="module")
def twins(tmp_path_factory):
    d = tmp_path_factory.mktemp("us")
    si, us = d / "si.toml", d / "us.toml"
    si.write_text(SCENE.format(units="", **{k: repr(v) for k, v in SI.items()}))
    us.write_text(SCENE.format(units='units = "us"', **{k: repr(v) for k, v in us_values().items()}))
    return si, us


def test_the_scene_is_read_into_the_si_scene(twins):
    a, b = (crashlab.load_scene(p) for p in twins)
    for va, vb in zip(a.vehicles, b.vehicles, strict=True):
        for attr in ("x", "y", "heading", "speed"):
            assert getattr(vb, attr) == pytest.approx(getattr(va, attr), rel=1e-12, abs=1e-12)
        assert vb.spec.mass == pytest.approx(va.spec.mass, rel=1e-12)
        assert vb.spec.length == pytest.approx(va.spec.length, rel=1e-12)
    assert b.barriers[0].length == pytest.approx(a.barriers[0].length, rel=1e-12)
    assert np.allclose(b.road.zones[0].polygon, a.road.zones[0].polygon, rtol=1e-12, atol=1e-12)
    assert b.references["pc"]["V1"]["x"] == pytest.approx(a.references["pc"]["V1"]["x"], rel=1e-12)
    assert b.uncertain[0].sd == pytest.approx(a.uncertain[0].sd, rel=1e-12)


@pytest.mark.parametrize("model", ["impulse", "pymunk"])
def test_us_scene_gives_the_si_twins_results(twins, model):
    a, b = (crashlab.simulate(crashlab.load_scene(p), model=model) for p in twins)
    assert a.outcome_ok and b.outcome_ok and len(a.impact_rows) > 0
    scale = np.maximum(1.0, np.abs(a.rest_si))
    assert np.max(np.abs(a.rest_si - b.rest_si) / scale) <= 1e-9
    for x, y in zip(a.impact_rows, b.impact_rows, strict=True):
        assert y["energy"] == pytest.approx(x["energy"], rel=1e-9)


def test_a_bad_units_word_is_one_line(tmp_path):
    f = tmp_path / "s.toml"
    f.write_text(SCENE.format(units='units = "imperial"', **{k: repr(v) for k, v in SI.items()}))
    res = subprocess.run([sys.executable, "-m", "crashlab.cli", "simulate", str(f)], capture_output=True, text=True)
    assert res.returncode == 2 and len(res.stderr.strip().splitlines()) == 1
    assert f"{f}: units:" in res.stderr


def cli(*args):
    res = subprocess.run([sys.executable, "-m", "crashlab.cli", *map(str, args)], capture_output=True, text=True,
                         timeout=600)
    assert res.returncode == 0, res.stderr
    return res.stdout


SI_HEADS = ("[m]", "[m,", "[km/h]", "[km/h,", "[kg]", "[J]", "[N]")


@pytest.mark.parametrize("command", [("simulate",), ("simulate", "--wide"), ("compare", "--models", "impulse,pymunk"),
                                     ("compare", "--models", "impulse", "--wide")])
def test_every_printed_table_header_is_in_us_units(twins, command):
    si, _ = twins
    us_text = cli(*command, si, "--units", "us")
    heads = [line for line in us_text.splitlines() if "[" in line and "]" in line]
    assert heads and not any(h in line for line in heads for h in SI_HEADS), heads
    assert any("[ft]" in line for line in heads)
    assert any("[mph]" in line for line in heads)
    if command[0] == "simulate":
        assert any("[ft-lbf]" in line for line in heads)  # the impact table's energy
    si_text = cli(*command, si)
    if "--wide" not in command:
        assert max(len(line) for line in si_text.splitlines() if not line.startswith("warning")) <= 100


def test_json_in_us_units(twins):
    si, _ = twins
    a, b = (json.loads(cli("simulate", si, "--json", *extra)) for extra in ((), ("--units", "us")))
    ra, rb = a["results"][0], b["results"][0]
    for name in ("V1", "V2"):
        assert rb["vehicles"][name]["rest"]["x"] == pytest.approx(ra["vehicles"][name]["rest"]["x"] / FT, rel=1e-6)
        assert rb["vehicles"][name]["rest"]["heading"] == ra["vehicles"][name]["rest"]["heading"]
    for x, y in zip(ra["impacts"], rb["impacts"], strict=True):
        assert y["delta_v"] == pytest.approx(x["delta_v"] / MPH, rel=1e-6)
        assert y["energy"] == pytest.approx(x["energy"] / (FT * LB * 9.80665), rel=1e-6)  # ft-lbf
        assert y["t"] == x["t"] and y["pdof"] == x["pdof"]
    assert b["comparison"][0]["d_pc_ft"] == pytest.approx(a["comparison"][0]["d_pc_m"] / FT, rel=1e-6)
    assert b["units"]["x"] == "ft" and b["units"]["impacts.energy"] == "ft-lbf" and b["units"]["speed"] == "mph"


def test_csv_in_us_units(twins, tmp_path):
    import pandas as pd
    si, _ = twins
    cli("simulate", si, "--csv", tmp_path / "si")
    cli("simulate", si, "--csv", tmp_path / "us", "--units", "us")
    for name, column, factor in (("trajectories", "x", FT), ("trajectories", "vx", MPH), ("impacts", "energy",
                                                                                         FT * LB * 9.80665)):
        a, b = (pd.read_csv(tmp_path / d / f"{name}.csv") for d in ("si", "us"))
        us_column = next(c for c in b.columns if c.startswith(column + " ["))
        assert us_column in (f"{column} [ft]", f"{column} [mph]", f"{column} [ft-lbf]")
        np.testing.assert_allclose(b[us_column], a[column] / factor, rtol=1e-9, atol=1e-9)
    assert "heading [deg]" in pd.read_csv(tmp_path / "us" / "trajectories.csv").columns  # no US form: as it is


def test_a_us_override_of_the_chassis_inertia_is_converted(tmp_path):
    """multibody.chassis.inertia's description began "kg m^2:" and the unit parser found no unit: a US scene's lb
    ft^2 were kept as kg m^2 (23.7 times too large; a fuzzer, 2026-11-27). 1 lb ft^2 = 0.45359237 kg x
    (0.3048 m)^2."""
    f = tmp_path / "s.toml"
    f.write_text('name = "us"\nunits = "us"\nduration = 1.0\n[road]\nfriction = 0.8\n[[vehicles]]\nname = "V1"\n'
                 'vehicle = "clio"\n[vehicles.overrides.multibody.chassis]\ninertia = [10000.0, 20000.0, 30000.0]\n')
    got = crashlab.load_scene(f).vehicles[0].spec.sections["multibody"]["chassis"]["inertia"]
    assert got == pytest.approx([q * 0.45359237 * 0.3048 ** 2 for q in (10000.0, 20000.0, 30000.0)], rel=1e-12)


def test_a_us_file_shows_us_units_unless_told_otherwise(twins):
    """--units defaults to the file's own system (until 2026-11-28 always si: a study in mph wrote posterior.csv in
    km/h under bare column names, a factor 1.6 off for anyone reading it in the study's units, a probe found)."""
    si, us = twins
    a, b = (json.loads(cli("simulate", us, "--json", *extra)) for extra in ((), ("--units", "us")))
    for r in a["results"] + b["results"]:
        r.pop("wall_time_s")
    assert a == b
    c, d = (json.loads(cli("simulate", p, "--json")) for p in (si, us))
    assert c["units"] != d["units"]
    for x, y in zip(c["results"][0]["impacts"], d["results"][0]["impacts"], strict=True):
        assert y["delta_v"] == pytest.approx(x["delta_v"] / MPH, rel=1e-6)


def test_compare_json_keys_name_the_unit_they_hold(twins, tmp_path):
    """compare --json --units us kept the keys d_pc_m and distance_m for values in feet (a probe, 2026-11-28):
    a program reading the key's suffix was 3.28 times off. Now d_pc_ft, distance_ft, and the units map's too; a
    reference's heading is wrapped to (-180, 180] as the map says (it kept the file's 386 as 386)."""
    si, _ = twins
    turned = tmp_path / "turned.toml"
    turned.write_text(si.read_text().replace("heading = 26.0", "heading = 386.0", 1))
    a, b = (json.loads(cli("compare", turned, "--models", "impulse", "--json", *extra))
            for extra in ((), ("--units", "us")))
    ra, rb = a["comparison"][0], b["comparison"][0]
    assert "d_pc_m" in ra and "d_pc_ft" in rb and "d_pc_m" not in rb
    assert rb["d_pc_ft"] == pytest.approx(ra["d_pc_m"] / FT, rel=1e-6)
    assert "d_<source>_ft" in b["units"] and "d_<source>_m" not in b["units"]
    assert a["references"]["pc"]["V1"]["heading"] == pytest.approx(26.0)
