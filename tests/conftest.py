"""Shared fixtures: the repository root and a helper that builds scenes from dicts (file units)."""
from __future__ import annotations

import copy
from pathlib import Path

import pytest

from crashlab.scene import scene_from_dict

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
