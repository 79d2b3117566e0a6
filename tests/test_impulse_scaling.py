"""Impulse model: what parked and distant vehicles cost (issue 12, scaling study).

A vehicle at rest sleeps; the step loops run over the awake vehicles and the pairs with an awake member,
and pairs of an awake vehicle and a static partner (a sleeping vehicle, a barrier) far apart are left out
until a vehicle has moved (models/impulse/kernel.py). None of this may change a result: far parked cars
exert no force, so the colliding pair's outcome with them must be bit-identical to the pair alone, and the
broad phase (which the skipping extends) must give the same results as testing every pair's outlines.
The diagnostics count the work: awake vehicles integrated (vehicle_steps) and outline tests.
"""
import numpy as np
import pytest
from test_impulse_stress import stress_scenes

import crashlab
from crashlab.comparison.scaling import scene as scaling_scene


def _same(a, b, n=None):
    """Bit-identical outcomes (the first n vehicles of a)."""
    sl = slice(0, n)
    assert np.array_equal(a.rest_si[sl], b.rest_si), "rest positions"
    assert np.array_equal(a.final_si[sl], b.final_si), "end velocities"
    assert np.array_equal(np.asarray(a.contact_si)[sl], np.asarray(b.contact_si), equal_nan=True), "contact"
    assert a.impact_rows == b.impact_rows, "impact rows"
    assert a.diagnostics["t_end"] == b.diagnostics["t_end"]


def test_parked_vehicles_change_nothing_and_cost_no_integration(impulse_model):
    two = impulse_model.simulate(scaling_scene(2, "parked"))
    sc8 = scaling_scene(8, "parked")
    eight = impulse_model.simulate(sc8)
    assert two.outcome_ok and eight.outcome_ok
    assert len(two.impact_rows) >= 2, "the pair collides"
    _same(eight, two, 2)
    # the parked cars stay exactly where they stood, at rest
    start = np.array([[v.x, v.y, v.heading] for v in sc8.vehicles[2:]])
    assert np.array_equal(eight.rest_si[2:], start)
    assert np.all(eight.final_si[2:] == 0.0)
    d2, d8 = two.diagnostics, eight.diagnostics
    assert d8["steps"] == d2["steps"]
    # no parked car is integrated, no pair with a parked car reaches the outline test
    assert d8["vehicle_steps"] == d2["vehicle_steps"] <= 2 * d2["steps"]
    assert d8["outline_tests"] == d2["outline_tests"] > 0


def test_sleeping_off_integrates_every_vehicle():
    m = crashlab.get_model("impulse", sleeping=False)
    out = m.simulate(scaling_scene(4, "parked", duration=0.5))
    d = out.diagnostics
    assert d["vehicle_steps"] == 4 * d["steps"]


@pytest.mark.parametrize("seed", [3, 11])
def test_broad_phase_and_skipping_give_the_results_of_every_pair_tested(seed, repo_root):
    """Random crashes (standing cars, barriers near the crash, 5-200 km/h) and the 3-vehicle scene: the same
    bits with the broad phase and the skipping of far static pairs as with every listed pair's outlines
    tested at every step, with fewer outline tests."""
    on, off = crashlab.get_model("impulse"), crashlab.get_model("impulse", broad_phase=False)
    three = crashlab.load_scene(repo_root / "studies" / "comparison" / "three_vehicles.toml")
    scenes = stress_scenes(12, seed) + [three]
    fewer = 0
    for sc in scenes:
        a, b = on.simulate(sc), off.simulate(sc)
        _same(a, b)
        assert a.diagnostics["outline_tests"] <= b.diagnostics["outline_tests"]
        fewer += a.diagnostics["outline_tests"] < b.diagnostics["outline_tests"]
    assert fewer >= len(scenes) // 2
