"""Driver actions and friction zones in every model against analytic results (docs/physics.md §2a).

Every scene uses the library's Clio with rolling resistance 0 (so a free-rolling car keeps its speed and the
analytic distances need no rolling-resistance term) on friction 0.8, driving along +x from the origin.
Tolerances (issue 13): planar models (impulse, pymunk) 0.5 % on stopping distances and 1 % across a zone, 3D
models (multibody, exudyn: pitch, suspension and tyre dynamics) 2 % and 3 %; the brake fraction 2 % for all.
"""
import math

import numpy as np
import pytest
from conftest import build_scene

import crashlab
from crashlab.units import G

MODELS = ["impulse", "pymunk", "multibody", "exudyn"]
PLANAR = {"impulse", "pymunk"}
MU = 0.8
NO_RR = {"rolling_resistance": 0.0}
_models = {}


def model(name):
    if name not in _models:
        _models[name] = crashlab.get_model(name)
    m = _models[name]
    if not m.driver_inputs:
        pytest.skip(f"{name} does not honour driver actions yet")
    return m


def car(**kw):
    return {"name": "V1", "overrides": NO_RR} | kw


def run(name, vehicle, duration=8.0, zones=(), stop_at_rest=True):
    sc = build_scene([vehicle], road={"friction": MU, "zones": list(zones)}, duration=duration,
                     stop_at_rest=stop_at_rest)
    out = model(name).simulate(sc)
    assert out.outcome_ok, out.warnings
    return sc, out


@pytest.mark.parametrize("name", MODELS)
@pytest.mark.parametrize("kmh", [30.0, 60.0, 100.0])
def test_reaction_then_locked_braking_stops_in_the_analytic_distance(name, kmh):
    t_r = 1.0
    sc, out = run(name, car(speed=kmh, actions=[{"t": t_r, "wheels": "locked"}]))
    v = kmh / 3.6
    expected = v * t_r + v * v / (2 * MU * G)
    got = out.rest_si[0, 0] - sc.vehicles[0].x
    assert got == pytest.approx(expected, rel=0.005 if name in PLANAR else 0.02)


def crossing_distance(spec, v0, x_boundary, mu1, mu2):
    """CG travel of a locked car from x = 0 into a zone starting at x_boundary (§2a): mu1 until the front
    axle crosses, then the front on mu2 and the rear on mu1 (quasi-static load transfer) for a wheelbase,
    then mu2 (the car stops in phase 3 in the test scene)."""
    a, b, h = spec.cg_to_front_axle, spec.cg_to_rear_axle, spec.cg_height
    L = a + b
    s1 = x_boundary - a
    v1sq = v0 * v0 - 2 * mu1 * G * s1
    a2 = G * (mu2 * b + mu1 * a) / (L - (mu2 - mu1) * h)
    v2sq = v1sq - 2 * a2 * L
    assert v1sq > 0 and v2sq > 0
    return s1 + L + v2sq / (2 * mu2 * G)


@pytest.mark.parametrize("name", MODELS)
def test_locked_car_crossing_into_a_low_friction_zone_stops_at_the_analytic_distance(name):
    wet = {"friction": 0.3, "polygon": [[8.0, -5.0], [200.0, -5.0], [200.0, 5.0], [8.0, 5.0]], "name": "wet"}
    sc, out = run(name, car(speed=60.0, wheels="locked"), zones=[wet])
    expected = crossing_distance(sc.vehicles[0].spec, 60 / 3.6, 8.0, MU, 0.3)
    got = out.rest_si[0, 0] - sc.vehicles[0].x
    assert got == pytest.approx(expected, rel=0.01 if name in PLANAR else 0.03)


@pytest.mark.parametrize("name", MODELS)
def test_split_friction_yaws_towards_the_high_friction_side(name):
    ice_left = {"friction": 0.1, "polygon": [[-10.0, 0.0], [200.0, 0.0], [200.0, 5.0], [-10.0, 5.0]]}
    sc, out = run(name, car(speed=60.0, wheels="locked"), zones=[ice_left])
    # left wheels on ice, right wheels on 0.8: the right side brakes harder, the car turns right (clockwise)
    assert math.degrees(out.rest_si[0, 2] - sc.vehicles[0].heading) < -5.0


@pytest.mark.parametrize("name", MODELS)
def test_half_brake_decelerates_at_half_mu_g(name):
    sc, out = run(name, car(speed=60.0, actions=[{"t": 0.0, "brake": 0.5}]))
    v = 60 / 3.6
    got = out.rest_si[0, 0] - sc.vehicles[0].x
    assert got == pytest.approx(v * v / (2 * 0.5 * MU * G), rel=0.02)


def _path(out):
    tr = next(iter(out.trajectories.values()))
    return np.asarray(tr["t"]), np.asarray(tr["x"]), np.asarray(tr["y"])


@pytest.mark.parametrize("name", [m for m in MODELS if m != "impulse"])
def test_a_steer_ramp_gives_the_path_of_the_impulse_model(name):
    """20 km/h, steer ramped from 0 to 5 deg over 1 s from t = 0.5 s, 30 m of path: CG positions at equal
    times within 0.2 m of the impulse model's (issue 13: multibody; the others are held to the same)."""
    vehicle = car(speed=20.0, actions=[{"t": 0.5, "steer": 5.0, "ramp": 1.0}])
    _, ref = run("impulse", vehicle, duration=5.4, stop_at_rest=False)
    _, out = run(name, vehicle, duration=5.4, stop_at_rest=False)
    t0, x0, y0 = _path(ref)
    t1, x1, y1 = _path(out)
    t = np.linspace(0.0, min(t0[-1], t1[-1]), 200)
    assert t[-1] > 5.0
    gap = np.hypot(np.interp(t, t0, x0) - np.interp(t, t1, x1), np.interp(t, t0, y0) - np.interp(t, t1, y1))
    assert np.interp(t[-1], t0, y0) > 5.0  # the car has turned: the path is no straight line
    assert gap.max() < 0.2, gap.max()
