"""Stress sweep ((crashlab.tools.stress)): seeded random crashes judged by the physics guard.

Goal of issue 10 after the root-cause fixes: no impulse or pymunk run caught, at most 1 in 40 multibody and
exudyn runs. The full sweep is slow (`python -m pytest -m slow tests/test_stress_sweep.py`, or
`crashlab stress --model NAME --runs N`); the default run checks the generator and a small impulse sweep."""
from __future__ import annotations

import numpy as np
import pytest

import crashlab
import crashlab.vehicle
from crashlab.tools import stress


def test_random_scenes_are_seeded_and_collide():
    a, b = stress.random_scenes(20, seed=3), stress.random_scenes(20, seed=3)
    assert [s.vehicles for s in a] == [s.vehicles for s in b], "the same seed draws the same scenes"
    masses = np.array([v.spec.mass for s in a for v in s.vehicles])
    assert masses.min() >= 700 and masses.max() <= 3000
    clio = crashlab.vehicle.load_vehicle("clio")
    for v in (v for s in a for v in s.vehicles if v.spec.name == clio.name):  # inertias scale with the mass
        assert v.spec.yaw_inertia / v.spec.mass == pytest.approx(clio.yaw_inertia / clio.mass, rel=1e-12)
    df = stress.sweep(crashlab.get_model("impulse"), a + stress.extreme_scenes())
    assert (df.impacts > 0).mean() >= 0.9, "the drawn vehicles meet"
    assert list(df.scene[-5:]) == ["200 km/h into a wall", "200 km/h into a standing car", "200 km/h head-on",
                                   "700 kg against 3000 kg", "2 deg grazing contact"]
    assert (df.impacts[-5:] > 0).all(), "every extreme scene has its contact"


def test_every_failed_run_has_a_reason():
    df = stress.sweep(crashlab.get_model("impulse"), stress.random_scenes(40, seed=11))
    assert (df.reason[~df.ok] != "").all() and (df.violations[~df.ok] != "").all()
    assert (df.reason[df.ok] == "").all()


SWEEP = {"impulse": 500, "pymunk": 100, "multibody": 40, "exudyn": 15}
ALLOWED = {"impulse": 0, "pymunk": 0, "multibody": 1, "exudyn": 1}


@pytest.mark.slow
@pytest.mark.parametrize("model", list(SWEEP))
def test_stress_sweep(model):
    if model in ("pymunk", "exudyn"):
        pytest.importorskip(model)
    df = stress.sweep(crashlab.get_model(model), stress.random_scenes(SWEEP[model], seed=1) + stress.extreme_scenes())
    s = stress.summary(df)
    print(model, s)
    assert (df.reason[~df.ok] != "").all(), "a caught run always says why"
    assert s["caught"] <= ALLOWED[model], df[~df.ok][["scene", "speeds_kmh", "wheels", "reason"]].to_string()
