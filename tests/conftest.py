"""Shared fixtures: the repository root and a helper that builds scenes from dicts (file units)."""
from __future__ import annotations

import copy
import subprocess
import sys
from pathlib import Path

import pytest

from crashlab.scene_file import scene_from_dict

REPO = Path(__file__).resolve().parent.parent
PC_CRASH = REPO / "studies" / "pc_crash"


def _vehicle(name="V1", **kw):
    v = {"name": name, "vehicle": "clio", "x": 0.0, "y": 0.0, "heading": 0.0, "speed": 0.0,
         "wheels": "rolling"}
    v.update(kw)
    return v


def build_scene(vehicles=None, source="<test scene>", **kw):
    """A scene dict in file units (m, deg, km/h) validated into a Scene.

    `vehicles` is a list of dicts (missing keys take the defaults of `_vehicle`); other keywords are
    top-level scene keys (road, impact, barriers, duration, stop_at_rest, name, reference)."""
    data = {"name": "test scene", "duration": 5.0, "stop_at_rest": True}
    data.update(copy.deepcopy(kw))
    vs = vehicles if vehicles is not None else [{}]
    data["vehicles"] = [_vehicle(**({"name": f"V{i + 1}"} | v)) for i, v in enumerate(vs)]
    return scene_from_dict(data, source=source)


# the study files' two free speeds of the side-collision twins (V1 30-70, V2 10-50 km/h)
FREE_SPEEDS = """[[free]]
vehicle = "V1"
field = "speed"
lower = 30.0
upper = 70.0
[[free]]
vehicle = "V2"
field = "speed"
lower = 10.0
upper = 50.0
"""



def side_twin_study(name: str, pop_size: int, generations: int, polish: int, free: str = FREE_SPEEDS) -> str:
    """A study's text: side.toml's collision as its own evidence (twin), NSGA-II with `pop_size` x
    `generations` (seed 1), the free variables `free`, `polish` polish evaluations, serial without timeout."""
    return f"""
name = "{name}"
scene = "{(PC_CRASH / 'side.toml').as_posix()}"
model = "impulse"
[optimizer]
name = "nsga2"
pop_size = {pop_size}
generations = {generations}
seed = 1
{free}[evidence]
twin = true
[polish]
evaluations = {polish}
[execution]
backend = "serial"
timeout_s = 0
"""

def two_frame_gif(scene, outcome, path, fps, system="si"):
    """Stands in for crashlab.tools.animation in report.html (the animation itself: tests/test_animation.py)."""
    from PIL import Image
    frames = [Image.new("P", (8, 8), c) for c in (0, 1)]
    frames[0].save(path, save_all=True, append_images=frames[1:], duration=int(1000 / fps), loop=0)
    return Path(path)


@pytest.fixture(scope="session", autouse=True)
def _two_frame_report_animation():
    """report.html's animation is a two-frame GIF in the tests (a real one takes seconds per --out run); a
    test that checks the real one asks for `real_report_animation`. Yields the real writer."""
    from crashlab.reconstruction import html_report
    real = html_report._animate
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(html_report, "_animate", two_frame_gif)
        yield real


@pytest.fixture
def real_report_animation(_two_frame_report_animation, monkeypatch):
    from crashlab.reconstruction import html_report
    monkeypatch.setattr(html_report, "_animate", _two_frame_report_animation)


@pytest.fixture(scope="session")
def repo_root() -> Path:
    return REPO


@pytest.fixture(scope="session")
def pc_crash_dir() -> Path:
    return PC_CRASH


@pytest.fixture
def make_scene():
    """`make_scene(vehicles=[{...}, ...], road={...}, impact={...}, barriers=[...], duration=...)`."""
    return build_scene


@pytest.fixture(scope="session")
def impulse_model():
    import crashlab
    return crashlab.get_model("impulse")


def _stress_sweep(model, speed, angles=(0.0, 45.0, 90.0, 135.0, 180.0)):
    """Numerical-stability sweep of a continuous-contact model: a rolling car at `speed` into a second car at
    half that speed turned by each angle (wheels locked at impact); every run ends ok with finite rest poses,
    velocities and impact records."""
    import numpy as np
    for angle in angles:
        sc = build_scene([{"name": "A", "x": 0.0, "speed": speed, "wheels": "rolling"},
                          {"name": "B", "x": 4.8, "heading": angle, "speed": speed / 2,
                           "wheels": "locked_after_impact"}], duration=3.0)
        out = model.simulate(sc)
        print(f"\n{model.name} {speed:.0f} km/h, {angle:.0f} deg: ok {out.outcome_ok}, {out.wall_time_s:.1f} s")
        assert out.outcome_ok, (speed, angle, out.warnings)
        assert out.impact_rows, (speed, angle)
        vals = [out.rest_si, out.final_si] + [np.array([r[k] for k in ("dvx", "dvy", "d_yaw_rate", "energy",
                                                                        "peak_force", "impulse")])
                                              for r in out.impact_rows]
        assert all(np.all(np.isfinite(v)) for v in vals), (speed, angle)


@pytest.fixture
def stress_sweep():
    """`stress_sweep(model, speed)`: see _stress_sweep."""
    return _stress_sweep


def assert_one_error_line(res, path, key, words=()):
    """A CLI run that refused bad input: exit 2, no traceback, one line on stderr naming the file and key."""
    assert res.returncode == 2, (res.stdout, res.stderr)
    assert "Traceback" not in res.stderr + res.stdout
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1, res.stderr
    assert f"{path}: {key}: " in lines[0], lines[0]
    for w in words:
        assert w in lines[0], lines[0]


def assert_refused_with_one_line(load, path, key, words=()):
    """load(path) raises InputError whose text is one line starting with the file and the key, naming words."""
    import pytest

    from crashlab.errors import InputError
    with pytest.raises(InputError) as err:
        load(path)
    line = str(err.value)
    assert line.startswith(f"{path}: {key}: ") and "\n" not in line, line
    for w in words:
        assert w in line, line


def write_vehicle_file(tmp_path, text: str, name: str = "car.toml") -> Path:
    """A vehicle file of `text` in tmp_path."""
    path = tmp_path / name
    path.write_text(text)
    return path


def damage_cli(*args, cwd=None):
    """`crashlab damage ARGS` as a user runs it (a subprocess)."""
    return subprocess.run([sys.executable, "-m", "crashlab.cli", "damage", *map(str, args)], capture_output=True,
                          text=True, timeout=120, cwd=cwd)
