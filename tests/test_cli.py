"""The command line (README.md): models, simulate [--json] [--plot], compare, and bad input: status 2,
one line on stderr naming the file and the key, never a traceback."""
from __future__ import annotations

import json
import subprocess
import sys

import pytest


def run(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "crashlab.cli", *map(str, args)], capture_output=True,
                          text=True, timeout=300, cwd=cwd)


def test_models_lists_impulse():
    res = run("models")
    assert res.returncode == 0, res.stderr
    first = res.stdout.splitlines()[0]
    assert first.startswith("models:") and "impulse" in first.split(":", 1)[1].replace(",", " ").split()


def test_simulate_json_shape(pc_crash_dir):
    res = run("simulate", pc_crash_dir / "head_on.toml", "--json")
    assert res.returncode == 0, res.stderr
    data = json.loads(res.stdout)
    assert set(data["vehicles"]) == {"V1", "V2"}
    rest = data["vehicles"]["V1"]["rest"]
    assert set(rest) == {"x", "y", "heading", "speed", "at_rest"}
    # PC-Crash's case 1 compares positions at 5 s of free-rolling cars: an end pose, not a rest pose
    assert rest["at_rest"] is False and rest["speed"] == pytest.approx(22.5, rel=1e-6)
    assert rest["x"] == pytest.approx(32.14, abs=0.5), "the same result as the Python API"
    assert data["vehicles"]["V2"]["final_velocity"]["vx"] == pytest.approx(27.5, rel=0.005)
    assert isinstance(data["impacts"], list) and len(data["impacts"]) == 2
    assert {"t", "vehicle", "other", "dvx", "dvy", "delta_v", "energy", "kind"} <= set(data["impacts"][0])
    assert data["wall_time_s"] >= 0 and data["ok"] is True


def test_simulate_plot_writes_png(pc_crash_dir, tmp_path):
    png = tmp_path / "side.png"
    res = run("simulate", pc_crash_dir / "side.toml", "--plot", png)
    assert res.returncode == 0, res.stderr
    assert png.stat().st_size > 1000
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_compare_shows_references(pc_crash_dir):
    res = run("compare", pc_crash_dir / "offset.toml", "--models", "impulse")
    assert res.returncode == 0, res.stderr
    lines = res.stdout.splitlines()
    assert any(line.split()[:2] == ["pc_crash", "V1"] for line in lines)
    assert any(line.split()[:2] == ["pc_crash", "V2"] for line in lines)
    assert any(line.split()[:2] == ["impulse", "V1"] for line in lines)
    assert "d_pc_crash_m" in res.stdout


SCENE = """name = "bad"
duration = 2.0
[[vehicles]]
name = "V1"
vehicle = "clio"
x = 0.0
speed = 50.0
"""
SECOND = """[[vehicles]]
name = "V2"
vehicle = "clio"
x = 3.0
heading = 180.0
"""

BAD = {
    # case: (file text or None for a missing file, extra CLI args, text the key part must contain)
    "malformed": (SCENE.replace('name = "bad"', 'name = "bad'), [], "(syntax)"),
    "missing_key": (SCENE.replace('vehicle = "clio"\n', ""), [], "vehicles.0.vehicle"),
    "mistyped_key": (SCENE.replace("speed = 50.0", "sped = 50.0"), [], "vehicles.0.sped"),
    "unknown_vehicle": (SCENE.replace('"clio"', '"clo"'), [], "vehicles.0"),
    "unknown_model": (SCENE, ["--model", "impuls"], "--model"),
    "negative_mass": (SCENE + "[vehicles.overrides]\nmass = -1.0\n", [], "vehicles.0.overrides.mass"),
    "overlap": (SCENE + SECOND, [], "vehicles"),
    "missing_file": (None, [], "scene"),
}


CASES = [("simulate", c) for c in sorted(BAD)] + [("compare", c) for c in ("malformed", "unknown_model",
                                                                          "overlap", "missing_file")]


@pytest.mark.parametrize("command, case", CASES)
def test_bad_input_one_line_status_2(tmp_path, case, command):
    text, extra, key = BAD[case]
    path = tmp_path / "scene.toml"
    if text is not None:
        path.write_text(text)
    if command == "compare":
        extra = ["--models", extra[1]] if extra else []
    res = run(command, path, *extra)
    assert res.returncode == 2, (res.stdout, res.stderr)
    assert "Traceback" not in res.stderr and "Traceback" not in res.stdout
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1, res.stderr
    line = lines[0]
    assert str(path) in line, "names the file"
    assert f": {key}: " in line, f"names the key {key}: {line}"
    if case in ("unknown_vehicle", "unknown_model"):
        assert "did you mean" in line
