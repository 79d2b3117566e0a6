"""multibody's realisation of driver actions (docs/physics.md §2a; models/multibody/README.md "Driver actions
and friction zones"): what tests/test_driver_laws.py does not reach (the analytic stopping, zone, split-mu,
brake-fraction and steer-path cases are there, for every model).

Clio from the library, rolling resistance 0, friction 0.8, along +x; one short run per test."""
import math

import numpy as np
import pytest
from conftest import build_scene

import crashlab
from crashlab.models.common.vehicle_3d import T_R1, T_R2, build_scene_vehicles, steer_angles
from crashlab.models.multibody import driver_control as DC
from crashlab.units import G

MU = 0.8


@pytest.fixture(scope="module")
def model():
    return crashlab.get_model("multibody")


def _run(model, vehicle, duration):
    sc = build_scene([{"name": "V1", "overrides": {"rolling_resistance": 0.0}} | vehicle], road={"friction": MU},
                     duration=duration, stop_at_rest=False)
    out = model.simulate(sc)
    assert out.outcome_ok, out.warnings
    return sc, out, out.trajectories["V1"]


def _speed_at(tr, t):
    return float(np.interp(t, tr["t"], np.hypot(tr["vx"], tr["vy"])))


def test_compiled_ackermann_is_the_common_steer_angles(model):
    sc = build_scene([{"name": "V1"}])
    veh = build_scene_vehicles(sc)[0]
    for steer in (-0.3, -0.05, 0.0, 0.02, 0.4):
        ref = steer_angles(veh, steer)
        for k in (0, 1):
            assert DC.ackermann(veh.wheelbase, veh.axle_y[k], steer) == pytest.approx(ref[k], abs=1e-14)


def test_locked_then_released_wheels_spin_up_and_the_car_rolls_on(model):
    """Locked for 0.5 s from 50 km/h (mu g), then rolling (the joint lock released at the action time): the
    tyres spin the wheels up, taking momentum m (v1 - v) = sum I_yy v / R^2, then the car keeps its speed."""
    v0 = 50 / 3.6
    sc, out, tr = _run(model, {"speed": 50.0, "wheels": "locked", "actions": [{"t": 0.5, "wheels": "rolling"}]},
                       1.5)
    veh = build_scene_vehicles(sc)[0]
    spin_mass = sum(veh.BODY[5 + k, 2] / (veh.TYR[k, T_R1] + veh.TYR[k, T_R2]) ** 2 for k in range(4))
    v1 = v0 - MU * G * 0.5
    expected = v1 * veh.mass / (veh.mass + spin_mass)
    assert _speed_at(tr, 0.45) == pytest.approx(v0 - MU * G * 0.45, rel=0.02)
    assert _speed_at(tr, 1.0) == pytest.approx(expected, rel=0.01)
    assert _speed_at(tr, 1.5) == pytest.approx(_speed_at(tr, 1.0), rel=0.005)


def test_rolling_braked_rolling_locked_both_ways(model):
    """rolling (keeps speed) -> braked at 0.3 s (ABS: ~eta mu g) -> rolling at 0.8 s (keeps speed) -> locked at
    1.3 s (mu g): each phase's deceleration within a few % of its law."""
    acts = [{"t": 0.3, "wheels": "braked"}, {"t": 0.8, "wheels": "rolling"}, {"t": 1.3, "wheels": "locked"}]
    _, out, tr = _run(model, {"speed": 70.0, "actions": acts}, 1.8)

    def decel(t0, t1):
        return (_speed_at(tr, t0) - _speed_at(tr, t1)) / (t1 - t0)

    assert abs(decel(0.05, 0.28)) < 0.02 * MU * G
    assert 0.85 * MU * G < decel(0.45, 0.78) < 1.0 * MU * G
    assert abs(decel(0.95, 1.28)) < 0.03 * MU * G
    assert decel(1.45, 1.78) == pytest.approx(MU * G, rel=0.03)


def test_steer_ramp_turns_the_knuckles_with_the_driver(model):
    """Steer ramped to 5 deg over 1 s at 20 km/h: after the ramp the yaw rate is the kinematic v tan(delta)/L
    (1 m/s^2 lateral: within 5 %), and the steering constraint holds (the knuckles follow the rheonomic row
    and jump with the steer rate at the ramp's ends; with the angle set only, Baumgarte dragged them behind
    by 3e-3 rad)."""
    v = 20 / 3.6
    sc, out, tr = _run(model, {"speed": 20.0, "actions": [{"t": 0.2, "steer": 5.0, "ramp": 1.0}]}, 2.5)
    L = sc.vehicles[0].spec.wheelbase
    r = float(np.interp(2.4, tr["t"], tr["yaw_rate"]))
    assert r == pytest.approx(v * math.tan(math.radians(5.0)) / L, rel=0.05)
    assert out.diagnostics["max_constraint_drift_angular"] < 5e-4
