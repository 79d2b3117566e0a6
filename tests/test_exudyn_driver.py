"""exudyn's realisation of driver actions (docs/physics.md §2a; models/exudyn/README.md "Driver actions and
friction zones"): what tests/test_driver_laws.py does not reach. The analytic stopping, zone, split-mu,
brake-fraction and steer-path cases for every model are in tests/test_driver_laws.py.

Clio from the library, rolling resistance 0, friction 0.8, along +x; two short runs per test (a few s each)."""
import math

import numpy as np
import pytest

pytest.importorskip("exudyn")

from conftest import build_scene  # noqa: E402

import crashlab  # noqa: E402
from crashlab.models.common.vehicle_3d import T_R1, T_R2, build_scene_vehicles  # noqa: E402
from crashlab.units import G  # noqa: E402

MU = 0.8


def _run(vehicle, duration):
    sc = build_scene([{"name": "V1", "overrides": {"rolling_resistance": 0.0}} | vehicle], road={"friction": MU},
                     duration=duration, stop_at_rest=False)
    out = crashlab.get_model("exudyn").simulate(sc)
    assert out.outcome_ok, out.warnings
    return sc, out, out.trajectories["V1"]


def test_wheels_released_from_locked_spin_up_and_the_car_rolls_on():
    """Locked for 0.5 s from 50 km/h (decelerating at mu g), then rolling (the spin lock switched off): the
    tyres spin the wheels up, taking momentum m (v1 - v) = sum I_yy v / R^2, and the car then keeps its speed
    (f_r = 0). A lock that stayed on would stop the car; a model without the switch refused the scene."""
    v0 = 50 / 3.6
    sc, out, tr = _run({"speed": 50.0, "wheels": "locked", "actions": [{"t": 0.5, "wheels": "rolling"}]}, 1.5)
    veh = build_scene_vehicles(sc)[0]
    spin_mass = sum(veh.BODY[5 + k, 2] / (veh.TYR[k, T_R1] + veh.TYR[k, T_R2]) ** 2 for k in range(4))
    v1 = v0 - MU * G * 0.5
    expected = v1 * veh.mass / (veh.mass + spin_mass)
    speed = np.hypot(tr["vx"], tr["vy"])
    t = np.asarray(tr["t"])
    late = t > 1.0
    assert speed[late] == pytest.approx(expected, rel=0.005)        # 1.9 % below v1: the spin-up is seen
    assert np.ptp(speed[late]) < 0.01 * expected                      # rolling on, not braking


def test_a_steer_action_turns_the_knuckles_as_the_built_steer_angle():
    """A steer of 3 deg set by an action at t = 0 (the prismatic joints' chassis markers turned to the
    Ackermann angles) gives the steady yaw rate of a car built with 3 deg (knuckles built at the angles),
    turning left (positive steer). Measured: yaw rates equal to 3e-5 rad/s of 0.176; the action car's yaw
    builds up about 20 ms later (0.2 deg of heading after 0.1 s, then constant: 6 cm apart after 16 m)."""
    _, _, built = _run({"speed": 30.0, "steer": 3.0}, 2.0)
    _, _, acted = _run({"speed": 30.0, "actions": [{"t": 0.0, "steer": 3.0}]}, 2.0)
    t = np.asarray(built["t"])
    n = min(len(t), len(acted["t"]))
    steady = slice(int(np.searchsorted(t, 0.5)), n)
    r_built, r_acted = np.asarray(built["yaw_rate"])[steady], np.asarray(acted["yaw_rate"])[steady]
    assert r_built.min() > 0.1                                         # the built car turns left
    assert r_acted == pytest.approx(r_built, rel=2e-3)
    assert math.degrees(abs(built["heading"][n - 1] - acted["heading"][n - 1])) < 0.3
