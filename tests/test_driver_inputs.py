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
     "vehicles.V1.actions.1.t", ["time order"]),
    ({"vehicles": [{"actions": [{"t": 1.0, "brake": 0.5, "ramp": 0.8}, {"t": 1.5, "steer": 2.0}]}]},
     "vehicles.V1.actions.0.ramp", ["longer"]),
    ({"vehicles": [{"actions": [{"t": 1.0, "brake": 1.5}]}]}, "vehicles.V1.actions.0.brake", []),
    ({"vehicles": [{"actions": [{"t": 1.0}]}]}, "vehicles.V1.actions.0", ["none"]),
    ({"vehicles": [{"actions": [{"t": 9.0, "brake": 1.0}]}]}, "vehicles.V1.actions.0.t", ["duration"]),
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
    assert_one_error_line(res, path, "vehicles.V1.actions.1.t", ["time order"])


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


# ---- the impulse kernel's reuse of driver inputs (steady_next), wheel points, remembered action tables ----

def _random_vehicle(rng):
    """A random valid vehicle dict (file units): random start wheels and steer, 0-5 actions at random times
    in [0.05, 4.5] s (at least 0.02 s apart), each changing the steer by at least 1 deg (so the inputs change
    right after every action's start: at it for a jump, just after it within a ramp) and perhaps the wheels
    and brake, a ramp of 0 or up to just before the next action."""
    states = ("rolling", "locked", "locked_after_impact", "braked")
    times = []
    for t in np.sort(rng.uniform(0.05, 4.5, rng.integers(0, 6))):
        if not times or t - times[-1] >= 0.02:
            times.append(float(t))
    steer = float(rng.uniform(-30, 30))
    actions = []
    for k, t in enumerate(times):
        new = float(rng.uniform(-30, 30))
        while abs(new - steer) < 1.0:
            new = float(rng.uniform(-30, 30))
        a = {"t": t, "steer": new}
        if rng.uniform() < 0.5:
            a["wheels"] = str(rng.choice(states))
        if rng.uniform() < 0.5:
            a["brake"] = float(rng.uniform())
        room = (times[k + 1] - t) if k + 1 < len(times) else 0.45
        if rng.uniform() < 0.6:
            a["ramp"] = float(rng.uniform(0.0, 0.999) * min(room, 0.45))
        actions.append(a)
        steer = new
    return {"wheels": str(rng.choice(states)), "steer": float(rng.uniform(-30, 30)), "actions": actions}


def _steady_reference(actions, t):
    """steady_next from the Action list itself: -inf within the ramp of the last action started at t, else
    the next action's start (inf if none)."""
    k = max((i for i, a in enumerate(actions) if a.t <= t), default=None)
    if k is not None and t < actions[k].t + actions[k].ramp:
        return -math.inf
    k = -1 if k is None else k
    return actions[k + 1].t if k + 1 < len(actions) else math.inf


def test_steady_next_says_how_long_the_inputs_read_at_t_hold():
    """For random valid action tables (packed together, padded: each vehicle read with its own row count)
    and random t, plus every action's start and ramp end: steady_next is -inf exactly within a ramp (and
    the inputs are ramping there); otherwise it is the next action's start T, which is when driver_inputs
    first changes on a 1 ms grid (T <= first change <= T + 1 ms; never, for T = inf), and at every t' in
    [t, T) with ahead(t', T) driver_inputs (also its left limit, up to T itself), next_change and ramping
    equal their values at t exactly (what the impulse kernel reuses, docs/physics.md §2a)."""
    from crashlab.models.common import driver_inputs as di
    rng = np.random.default_rng(11)
    dt = 1e-3
    grid = np.arange(0.0, 5.0, dt)
    checked = {"ramp": 0, "finite": 0, "inf": 0, "reuse": 0}
    for _ in range(12):
        sc = build_scene([_random_vehicle(rng) | {"y": 10.0 * i} for i in range(4)])
        tables, rows = di.pack_action_tables(sc.vehicles)
        for v, A, n in zip(sc.vehicles, tables, rows):
            n = int(n)
            assert np.array_equal(A[:n], di.pack_actions(v))
            on_grid = np.array([di.driver_inputs(A, n, g) for g in grid])
            probes = list(rng.uniform(0.0, 5.0, 40)) + [a.t for a in v.actions] + [a.t + a.ramp for a in v.actions]
            for t in probes:
                T = di.steady_next(A, n, t)
                assert T == _steady_reference(v.actions, t), (t, T)
                now = di.driver_inputs(A, n, t)
                if T == -math.inf:
                    assert di.ramping(A, n, t)
                    checked["ramp"] += 1
                    continue
                assert T > t
                changed = np.any(on_grid != np.array(now), axis=1) & (grid > t)
                if T == math.inf:
                    assert not changed.any(), (t, grid[np.argmax(changed)])
                    checked["inf"] += 1
                else:
                    first = grid[np.argmax(changed)]
                    assert changed.any() and T <= first <= T + dt * (1 + 1e-9), (t, T, first)
                    assert di.driver_inputs(A, n, T, True) == now  # a step ending at T keeps the law
                    checked["finite"] += 1
                law = di.next_change(A, n, t)
                end = min(T, 5.5)
                later = [t, end - 1e-11 * (1 + abs(end))] + list(rng.uniform(t, end, 15))
                for t2 in later:
                    if not (t <= t2 < T and di.ahead(t2, T)):
                        continue
                    assert di.driver_inputs(A, n, t2) == now, (t, t2, T)
                    assert t2 == t or di.driver_inputs(A, n, t2, True) == now, (t, t2, T)
                    assert di.next_change(A, n, t2) == law and not di.ramping(A, n, t2), (t, t2, T)
                    checked["reuse"] += 1
    assert min(checked.values()) > 50, checked


def test_wheel_points_are_the_axle_and_track_corners():
    """wheel_point: the four wheels lie `front` ahead of and `rear` behind the CG along the heading and
    half_track to each side; front left / rear left on the left (positive lateral, vehicle frame). Their
    distances are the track, the wheelbase and the diagonal. Heading 30 deg and random poses."""
    from crashlab.models.common.driver_inputs import wheel_point
    front, rear, half = 1.24, 1.31, 0.72
    rng = np.random.default_rng(5)
    poses = [(3.0, -2.0, math.radians(30.0))] + list(zip(rng.uniform(-50, 50, 200), rng.uniform(-50, 50, 200),
                                                            rng.uniform(-np.pi, np.pi, 200)))
    for x, y, h in poses:
        c, s = math.cos(h), math.sin(h)
        p = np.array([wheel_point(x, y, c, s, front, rear, half, w) for w in range(4)])
        d = p - (x, y)
        along, lateral = d @ (c, s), d @ (-s, c)
        assert along == pytest.approx([front, front, -rear, -rear], abs=1e-12)
        assert lateral == pytest.approx([half, -half, half, -half], abs=1e-12)  # 0, 2 left; 1, 3 right
        dist = [math.dist(p[i], p[j]) for i, j in ((0, 1), (2, 3), (0, 2), (1, 3), (0, 3), (1, 2))]
        diagonal = math.hypot(front + rear, 2 * half)
        assert dist == pytest.approx([2 * half] * 2 + [front + rear] * 2 + [diagonal] * 2, abs=1e-12)
    # at 30 deg the front left wheel lies to the left of the heading: cross(heading, CG -> wheel) > 0
    x, y = wheel_point(0.0, 0.0, math.cos(math.pi / 6), math.sin(math.pi / 6), front, rear, half, 0)
    assert math.cos(math.pi / 6) * y - math.sin(math.pi / 6) * x == pytest.approx(half, abs=1e-12)


def test_action_tables_are_the_tables_of_the_vehicles_given():
    """pack_action_tables gives the tables of the vehicles given: the same vehicles equal tables; other
    actions (equal or not), other start wheels or steer their own; many short-lived actions tuples (ids
    that CPython reuses: an id-keyed memo would go stale) each their own; and fresh arrays: a caller
    writing into a result changes no later one."""
    import dataclasses

    from crashlab.models.common import driver_inputs as di
    from crashlab.scene import Action

    def fresh(vehicles):  # the tables packed from scratch
        t = [di.pack_actions(v) for v in vehicles]
        k = max(len(a) for a in t)
        return np.array([np.vstack([a] + [a[-1:]] * (k - len(a))) for a in t]), [len(a) for a in t]

    def check(vehicles):
        A, NA = di.pack_action_tables(vehicles)
        want, rows = fresh(vehicles)
        assert np.array_equal(A, want) and list(NA) == rows
        return A.copy(), NA.copy()

    sc = build_scene([{"steer": 2.0, "actions": [{"t": 1.0, "wheels": "locked"},
                                                 {"t": 2.0, "steer": 4.0, "ramp": 0.5}]},
                      {"y": 10.0, "actions": [{"t": 0.5, "brake": 0.7}]}])
    first = check(sc.vehicles)
    again = check(sc.vehicles)
    assert all(np.array_equal(a, b) for a, b in zip(first, again))
    variants = [
        sc.with_vehicle("V1", actions=(Action(t=1.0, wheels="braked"),)),
        sc.with_vehicle("V1", actions=tuple(list(sc.vehicles[0].actions))),  # equal, another tuple
        sc.with_vehicle("V1", actions=(Action(t=1.0, wheels="locked"), Action(t=2.0, steer=0.3, ramp=0.2))),
        sc.with_vehicle("V1", wheels="locked"),  # same actions tuple, other start wheels
        sc.with_vehicle("V1", steer=-0.1),  # same actions tuple, other start steer
        sc.with_vehicle("V2", wheels="braked"),
    ]
    for var in variants:
        check(var.vehicles)
    assert not np.array_equal(check(variants[3].vehicles)[0], first[0])
    assert not np.array_equal(check(variants[4].vehicles)[0], first[0])
    rng = np.random.default_rng(2)
    v = sc.vehicles[1]
    for _ in range(300):  # the previous tuple is dropped at once: its id is free for the next one
        check([dataclasses.replace(v, actions=(Action(t=float(rng.uniform(0, 4)), brake=float(rng.uniform())),))])
    A, NA = di.pack_action_tables(sc.vehicles)
    A[:] = -1.0
    NA[:] = 0
    after = check(sc.vehicles)
    assert all(np.array_equal(a, b) for a, b in zip(first, after))


def test_zone_arrays_are_fresh_copies():
    """pack_zones gives equal arrays for equal roads (remembered by the road's value), and fresh copies: a
    caller writing into a result changes no later one."""
    from crashlab.models.common import driver_inputs as di
    from crashlab.scene import Road, Zone

    def road():  # a new, equal Road each time
        return Road(0.8, (Zone(0.2, ((0.0, 0.0), (4.0, 0.0), (4.0, 3.0), (0.0, 3.0))),
                          Zone(0.5, ((1.0, 1.0), (6.0, 1.0), (3.0, 5.0)))))

    first = [a.copy() for a in di.pack_zones(road())]
    for a in di.pack_zones(road()):
        assert a.flags.writeable
        a[...] = 7
    assert all(np.array_equal(a, b) for a, b in zip(first, di.pack_zones(road())))
