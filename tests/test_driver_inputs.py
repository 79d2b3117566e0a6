"""Driver actions and friction zones: the shared look-ups (docs/physics.md §2a) and their input checks."""
import math
import subprocess
import sys

import numpy as np
import pytest
from conftest import assert_one_error_line, build_scene

from crashlab.errors import InputError
from crashlab.models.common.driver_inputs import (
    PATCH,
    driver_inputs,
    pack_action_tables,
    pack_actions,
    pack_zones,
    road_friction,
)
from crashlab.models.common.wheel_states import BRAKED, LOCKED, ROLLING

WET = {"friction": 0.3, "polygon": [[10.0, -5.0], [30.0, -5.0], [30.0, 5.0], [10.0, 5.0]], "name": "wet patch"}


def test_actions_hold_and_ramp():
    sc = build_scene([{"steer": 2.0, "actions": [
        {"t": 0.9, "wheels": "locked"},
        {"t": 2.0, "wheels": "rolling", "brake": 0.6, "steer": -4.0, "ramp": 0.5},
        {"t": 3.0, "wheels": "braked"}]}])
    A = pack_actions(sc.vehicles[0])
    n = len(A)
    assert driver_inputs(A, n, 0.0) == (ROLLING, 0.0, pytest.approx(math.radians(2.0)))
    assert driver_inputs(A, n, 0.9)[0] == LOCKED and driver_inputs(A, n, 0.8999)[0] == ROLLING
    mode, brake, steer = driver_inputs(A, n, 2.25)  # half-way through the ramp
    assert mode == ROLLING and brake == pytest.approx(0.3) and steer == pytest.approx(math.radians(-1.0))
    assert driver_inputs(A, n, 2.6)[1:] == (pytest.approx(0.6), pytest.approx(math.radians(-4.0)))
    assert driver_inputs(A, n, 3.5) == (BRAKED, 1.0, pytest.approx(math.radians(-4.0)))  # braked: full brake
    tables, rows = pack_action_tables(sc.vehicles + build_scene([{}]).vehicles)
    assert tables.shape == (2, 4, 7) and list(rows) == [4, 1]


def test_zone_friction_blends_over_the_patch_and_keeps_the_friction_work():
    sc = build_scene(road={"friction": 0.8, "zones": [WET, {"friction": 0.1, "polygon": [[20, 0], [25, 0], [25, 2]]}]})
    Z = pack_zones(sc.road)
    assert road_friction(0.0, 0.0, 0.8, *Z) == 0.8
    assert road_friction(15.0, 0.0, 0.8, *Z) == pytest.approx(0.3)
    assert road_friction(24.0, 0.5, 0.8, *Z) == pytest.approx(0.1)  # the later zone wins
    assert road_friction(10.0, 0.0, 0.8, *Z) == pytest.approx(0.55)  # on the boundary: half the patch inside
    # the friction work along a path across the boundary equals the sharp boundary's (symmetric blend)
    xs = np.linspace(9.0, 11.0, 20001)
    mu = np.array([road_friction(x, 0.0, 0.8, *Z) for x in xs])
    assert np.trapezoid(mu, xs) == pytest.approx(0.8 * 1.0 + 0.3 * 1.0, rel=1e-6)
    assert np.all(mu[xs < 10 - PATCH / 2] == 0.8) and np.all(np.abs(mu[xs > 10 + PATCH / 2] - 0.3) < 1e-12)


@pytest.mark.parametrize("change, key, words", [
    ({"vehicles": [{"actions": [{"t": 1.0, "brake": 0.5}, {"t": 0.5, "brake": 1.0}]}]},
     "vehicles.0.actions.1.t", ["time order"]),
    ({"vehicles": [{"actions": [{"t": 1.0, "brake": 0.5, "ramp": 0.8}, {"t": 1.5, "steer": 2.0}]}]},
     "vehicles.0.actions.0.ramp", ["longer"]),
    ({"vehicles": [{"actions": [{"t": 1.0, "brake": 1.5}]}]}, "vehicles.0.actions.0.brake", []),
    ({"vehicles": [{"actions": [{"t": 1.0}]}]}, "vehicles.0.actions.0", ["none"]),
    ({"vehicles": [{"actions": [{"t": 9.0, "brake": 1.0}]}]}, "vehicles.0.actions.0.t", ["duration"]),
    ({"road": {"zones": [{"friction": 2.5, "polygon": WET["polygon"]}]}}, "road.zones.0.friction", []),
    ({"road": {"zones": [{"friction": 0.3, "polygon": [[0, 0], [1, 0]]}]}}, "road.zones.0.polygon", []),
    ({"road": {"zones": [{"friction": 0.3, "polygon": [[0, 0], [3, 2], [3, 0], [0, 3]]}]}},
     "road.zones.0.polygon", ["cross"]),
    ({"road": {"zones": [{"friction": 0.3, "polygon": [[0, 0], [1, 1], [2, 2]]}]}},
     "road.zones.0.polygon", ["area"]),
])
def test_bad_actions_and_zones_are_one_line_naming_the_key(change, key, words):
    vehicle = {"speed": 50.0} | change.get("vehicles", [{}])[0]
    with pytest.raises(InputError) as err:
        build_scene([vehicle], source="bad.toml", road=change.get("road", {}))
    line = str(err.value)
    assert line.startswith(f"bad.toml: {key}: ") and "\n" not in line, line
    assert all(w in line for w in words), line


def test_bad_action_from_the_command_line(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text('duration = 5.0\n[[vehicles]]\nname = "V1"\nvehicle = "clio"\nspeed = 50.0\n'
                    '[[vehicles.actions]]\nt = 1.0\nbrake = 0.5\n[[vehicles.actions]]\nt = 0.5\nsteer = 2.0\n')
    res = subprocess.run([sys.executable, "-m", "crashlab.cli", "simulate", str(path)], capture_output=True, text=True)
    assert_one_error_line(res, path, "vehicles.0.actions.1.t", ["time order"])


def test_a_model_that_does_not_honour_actions_refuses_them():
    import crashlab
    from crashlab.model import CollisionModel

    class Plain(CollisionModel):
        name = "plain"

        def simulate(self, scene):  # pragma: no cover - must not be reached
            raise AssertionError("a scene with actions reached a model that ignores them")

    sc = build_scene([{"speed": 50.0, "actions": [{"t": 1.0, "wheels": "locked"}]}], source="s.toml")
    with pytest.raises(InputError, match="s.toml: vehicles.0.actions: model 'plain' does not honour"):
        Plain().simulate(sc)
    zoned = build_scene([{"speed": 50.0}], source="z.toml", road={"zones": [WET]})
    with pytest.raises(InputError, match="z.toml: road.zones: "):
        Plain().simulate_batch([zoned])
    assert crashlab.scene.driver_input_key(build_scene([{"speed": 50.0}])) is None


def test_next_change_and_ramping_bound_the_steps():
    from crashlab.models.common.driver_inputs import next_change, ramping, steer_rate
    sc = build_scene([{"actions": [{"t": 1.0, "wheels": "locked"}, {"t": 2.0, "steer": 4.0, "ramp": 0.5}]}])
    A = pack_actions(sc.vehicles[0])
    n = len(A)
    assert [next_change(A, n, t) for t in (0.0, 1.0, 1.5, 2.0, 2.2, 2.5)] == [1.0, 2.0, 2.0, 2.5, 2.5, math.inf]
    assert [ramping(A, n, t) for t in (1.5, 2.0, 2.4, 2.5)] == [False, True, True, False]
    assert steer_rate(A, n, 2.2) == pytest.approx(math.radians(4.0) / 0.5) and steer_rate(A, n, 2.6) == 0.0
    # the left limit at an action's time keeps the law of the step that ends there
    assert driver_inputs(A, n, 1.0, True)[0] == ROLLING and driver_inputs(A, n, 1.0)[0] == LOCKED


def test_wheel_frictions_equal_the_per_point_friction_at_each_wheel():
    """The vehicle-level shortcut (skip a zone the wheels cannot reach, a convex zone holding them all) gives
    exactly road_friction at each wheel: random poses over convex, non-convex and overlapping zones."""
    from crashlab.models.common.driver_inputs import wheel_frictions
    zones = [WET, {"friction": 0.1, "polygon": [[20, 0], [25, 0], [25, 2]]},
             {"friction": 0.5, "polygon": [[0, -8], [8, -8], [8, 0], [4, -4], [0, 0]]},  # not convex
             {"friction": 0.0, "polygon": [[12, -2], [14, -2], [14, 2], [12, 2]]}]
    Z = pack_zones(build_scene(road={"friction": 0.8, "zones": zones}).road)
    rng = np.random.default_rng(7)
    front, rear, half = 1.24, 1.23, 0.70
    for x, y, h in zip(rng.uniform(-5, 35, 3000), rng.uniform(-10, 7, 3000), rng.uniform(-np.pi, np.pi, 3000)):
        c, s = math.cos(h), math.sin(h)
        got = wheel_frictions(x, y, c, s, front, rear, half, 0.8, *Z)
        body = [(front, half), (front, -half), (-rear, half), (-rear, -half)]
        want = [road_friction(x + c * bx - s * by, y + s * bx + c * by, 0.8, *Z) for bx, by in body]
        assert got == pytest.approx(want, abs=1e-12)


def test_wheel_friction_margin_bounds_how_far_the_wheels_may_move_before_a_friction_changes():
    """Where wheel_frictions_clearance reports a margin, every pose whose wheels moved less than it (CG shift
    + reach x heading change, as the impulse kernel's cache tests) gives the same four frictions; within a
    boundary's blend the margin is 0. Random poses over convex, non-convex and overlapping zones."""
    from crashlab.models.common.driver_inputs import wheel_frictions_clearance
    zones = [{"friction": 0.3, "polygon": [[0, -8], [30, -8], [30, 8], [0, 8]]},
             {"friction": 0.1, "polygon": [[10, -2], [14, -2], [14, 2], [10, 2]]},
             {"friction": 0.5, "polygon": [[40, -8], [48, -8], [48, 0], [44, -4], [40, 0]]}]  # not convex
    Z = pack_zones(build_scene(road={"friction": 0.8, "zones": zones}).road)
    front, rear, half = 1.24, 1.23, 0.70
    reach = math.hypot(max(front, rear), half)
    rng = np.random.default_rng(3)
    held = blended = 0
    for x, y, h in zip(rng.uniform(-10, 55, 4000), rng.uniform(-12, 12, 4000), rng.uniform(-np.pi, np.pi, 4000)):
        *f, margin = wheel_frictions_clearance(x, y, math.cos(h), math.sin(h), front, rear, half, 0.8, *Z)
        if margin <= 0:
            assert margin == 0.0
            blended += 1
            continue
        held += 1
        # a move using up to 99 % of the margin, shared between the CG shift (|dx| + |dy|) and the turn
        budget = 0.99 * min(margin, 5.0) * rng.uniform()
        turn = rng.uniform() * budget
        dxy = budget - turn
        a = rng.uniform(0, 2 * np.pi)
        norm1 = abs(math.cos(a)) + abs(math.sin(a))
        dx, dy = dxy * math.cos(a) / norm1, dxy * math.sin(a) / norm1
        h2 = h + rng.choice((-1, 1)) * turn / reach
        got = wheel_frictions_clearance(x + dx, y + dy, math.cos(h2), math.sin(h2), front, rear, half, 0.8, *Z)[:4]
        assert got == tuple(f)
    assert held > 2000 and blended > 20
