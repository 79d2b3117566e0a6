"""The physics guard's energy_outside_contact and a one-sample transient (issue 27, item 2; docs/physics.md §19):
a rise above the tolerance at one sample alone, both neighbours within it, is the work of a driver's input that
jumps (exudyn's knuckles turned in one step), not a gain; a rise that stays, or lasts two samples, or is the run's
last sample, still fails."""
from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import build_scene
from test_guard import Scripted, _outcome, _traj

import crashlab

E0 = 0.5 * 1200.0 * 3.0 ** 2  # J: a 1.2 t car at 3 m/s (the column is the model's own energy)


def _run(energy):
    scene = build_scene([{"x": 0.0}, {"x": 20.0, "heading": 180.0}])
    t = np.linspace(0.0, 1.0, len(energy))
    traj = {"V1": _traj(t, np.zeros_like(t), energy=energy), "V2": _traj(t, np.zeros_like(t))}
    return Scripted(lambda s: _outcome(s, [[0, 0, 0], [20, 0, math.pi]], trajectories=traj)).simulate(scene)


def _column(spikes):
    e = np.full(101, E0)
    for k, de in spikes.items():
        e[k] += de
    return e


def test_a_one_sample_spike_that_returns_is_no_gain():
    """+1.6 kJ at one sample (tolerance 1.1 kJ), +54 J the next: passed."""
    out = _run(_column({50: 1600.0, 51: 54.0}))
    assert out.outcome_ok, out.warnings


@pytest.mark.parametrize("spikes, why", [({50: 1600.0, 51: 1600.0}, "two samples"),
                                         ({k: 1600.0 for k in range(50, 101)}, "a gain that stays"),
                                         ({100: 1600.0}, "the last sample: nothing shows it returns")])
def test_a_rise_that_is_no_one_sample_transient_still_fails(spikes, why):
    out = _run(_column(spikes))
    assert out.violations == ["energy_outside_contact"], why
    assert "V1 gains 1.6 kJ" in out.warnings[-1]


@pytest.mark.slow
def test_exudyn_parked_car_locking_and_steering_in_one_step():
    """The issue's case: a parked Clio whose one action locks the wheels and steers 15 deg at t = 0.5 s. Its
    energy column reads +1.6 kJ at 0.51 s (the index-3 steer constraint turns the knuckles and wheels in one
    step), about 50 J at 0.52 s: the run passes the guard (it failed before, "V1 gains 1.6 kJ without contact");
    the spike is there (this is the case the tolerance is for) and has returned below 0.1 kJ by 0.53 s."""
    pytest.importorskip("exudyn")
    scene = build_scene([{"name": "V1", "speed": 0.0, "actions": [{"t": 0.5, "wheels": "locked", "steer": 15.0}]}],
                        road={"friction": 0.8}, duration=1.0, stop_at_rest=False)
    out = crashlab.get_model("exudyn").simulate(scene)
    assert out.outcome_ok, out.warnings
    tr = out.trajectories["V1"]
    t, rise = np.asarray(tr["t"]), np.asarray(tr["energy"]) - tr["energy"][0]
    k = int(np.argmax(rise))
    assert t[k] == pytest.approx(0.51, abs=0.006) and rise[k] > 1.1e3
    assert rise[k + 1] < 0.2e3 and np.all(rise[k + 2:] < 0.1e3)
