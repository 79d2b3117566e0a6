"""The physics guard (crashlab.guard): every Outcome of every model, built-in or plugin, is checked;
a violation is outcome_ok False with the reason, never a quiet number. End poses of moving vehicles
are reported as such (out.rest speed, at_rest)."""
from __future__ import annotations

import math
import subprocess
import sys

import numpy as np
import pytest
from conftest import build_scene

import crashlab
from crashlab import guard
from crashlab.model import CollisionModel
from crashlab.outcome import Outcome
from crashlab.units import kmh_to_ms


def _two_cars(**kw):
    return build_scene([{"x": 0.0, "speed": 50.0}, {"x": 10.0, "heading": 180.0}], **kw)


class Scripted(CollisionModel):
    """A plugin that returns whatever outcome a test scripts: the guard must judge it like any model's."""

    name = "scripted"

    def __init__(self, make):
        self.make = make

    def simulate(self, scene):
        return self.make(scene)


def _outcome(scene, rest, final=None, raw=False, **kw):
    """An Outcome; its trajectories (a copy) end at its end state unless raw (the end_state check)."""
    final = np.zeros((len(scene.vehicles), 3)) if final is None else np.array(final, float)
    rest = np.array(rest, float)
    if kw.get("trajectories") and not raw:
        kw["trajectories"] = {n: {k: np.array(v, float) for k, v in tr.items()} for n, tr in kw["trajectories"].items()}
        for i, n in enumerate(scene.vehicle_names):
            tr = kw["trajectories"][n]
            for k, value in zip(("x", "y", "heading", "vx", "vy", "yaw_rate"), (*rest[i], *final[i])):
                tr[k][-1] = value
    return Outcome(scene.vehicle_names, rest, final, model="scripted", **kw)


def _traj(t, vx, **cols):
    t = np.asarray(t, float)
    base = {"t": t, "x": np.zeros_like(t), "y": np.zeros_like(t), "heading": np.zeros_like(t),
            "vx": np.asarray(vx, float), "vy": np.zeros_like(t), "yaw_rate": np.zeros_like(t)}
    base.update({k: np.asarray(v, float) for k, v in cols.items()})
    return base


def test_energy_from_nowhere_after_last_contact_fails():
    """A car that slows to 0.1 km/h and then speeds up to 126 km/h without contact (the multibody bug
    of issue 10) is failed, with the vehicle and the energy named."""
    scene = _two_cars()
    t = np.linspace(0, 5, 501)
    v1 = np.where(t < 1.0, 10.0, np.where(t < 2.0, 0.03, kmh_to_ms(126.0)))
    traj = {"V1": _traj(t, v1), "V2": _traj(t, np.zeros_like(t))}

    def make(s):
        return _outcome(s, [[20, 0, 0], [30, 0, math.pi]], trajectories=traj, contact_intervals=[(0.5, 0.6)])

    out = Scripted(make).simulate(scene)
    assert not out.outcome_ok
    assert "energy_outside_contact" in out.violations and "energy_overall" not in out.violations
    assert any("V1 gains" in w for w in out.warnings)


def test_a_models_own_energy_column_is_the_measure():
    """A tumbling 3D car turns roll energy into planar speed: with the model's full mechanical energy
    recorded (trajectory column energy) that is no gain; with the planar measure alone it would be."""
    scene = _two_cars()
    t = np.linspace(0, 2, 201)
    v1 = np.where(t < 1.0, 5.0, 12.0)
    flat = np.full_like(t, 0.5 * 1000 * 12.0 ** 2)
    traj = {"V1": _traj(t, v1, energy=flat), "V2": _traj(t, np.zeros_like(t))}
    out = Scripted(lambda s: _outcome(s, [[20, 0, 0], [30, 0, math.pi]], trajectories=traj)).simulate(scene)
    assert out.outcome_ok, out.warnings
    traj["V1"].pop("energy")
    out = Scripted(lambda s: _outcome(s, [[20, 0, 0], [30, 0, math.pi]], trajectories=traj)).simulate(scene)
    assert out.violations == ["energy_outside_contact"]


def test_a_contact_on_a_sample_boundary_counts_despite_round_off():
    """pymunk reported a contact at 0.24000000000000002 s and its sample at 0.2399999 s already held the
    struck car's new speed: the guard called it a gain without contact before CONTACT_PAD."""
    scene = _two_cars()
    t = np.round(np.arange(0, 100) * 0.01, 12)
    t[24] = 0.2399999
    v2 = np.where(t < 0.235, 0.0, 12.0)
    traj = {"V1": _traj(t, np.full_like(t, 13.0)), "V2": _traj(t, v2)}
    out = Scripted(lambda s: _outcome(s, [[20, 0, 0], [30, 0, math.pi]], trajectories=traj,
                                      contact_intervals=[(0.24000000000000002,) * 2])).simulate(scene)
    assert out.outcome_ok, out.warnings


def test_one_vehicles_contact_does_not_excuse_another():
    """V1 is in contact the whole run, V2 touches nothing and goes from 50 to 100 km/h: the contact is
    V1's (its impact row with the barrier), so V2's gain is caught (the review's p7: it was not)."""
    scene = build_scene([{"x": 0.0, "speed": 50.0}, {"x": 20.0, "y": 10.0, "speed": 50.0}],
                        barriers=[{"x": 3.0, "y": 0.0, "length": 1.0, "width": 4.0}])
    t = np.linspace(0, 5, 501)
    traj = {"V1": _traj(t, np.zeros_like(t)), "V2": _traj(t, np.where(t < 2.0, kmh_to_ms(50.0), kmh_to_ms(100.0)))}
    rows = [{"t": 0.0, "vehicle": "V1", "other": "barrier0", "dvx": 0.0, "dvy": 0.0, "d_yaw_rate": 0.0,
             "energy": 1e3, "kind": "continuous", "point_x": 2.5, "point_y": 0.0, "plane_angle": 0.0,
             "duration": 5.0}]
    out = Scripted(lambda s: _outcome(s, [[0, 0, 0], [30, 10, 0]], trajectories=traj, impact_rows=rows,
                                      contact_intervals=[(0.0, 5.0)])).simulate(scene)
    assert out.violations == ["energy_outside_contact"] and "V2 gains" in out.warnings[-1]


def test_the_energy_tolerance_is_the_vehicles_own():
    """A 3,000 kg car at 200 km/h beside a standing 700 kg car that speeds up to 54 km/h without contact
    (+79 kJ): 2 % of the scene's energy (93 kJ) would hide it, 2 % of the light car's does not."""
    scene = build_scene([{"x": 0.0, "speed": 200.0, "overrides": {"mass": 3000.0, "yaw_inertia": 4500.0,
                                                                    "roll_inertia": 900.0, "pitch_inertia": 4500.0}},
                         {"x": 0.0, "y": 20.0, "overrides": {"mass": 700.0, "yaw_inertia": 1050.0,
                                                              "roll_inertia": 210.0, "pitch_inertia": 1050.0}}])
    t = np.linspace(0, 2, 201)
    traj = {"V1": _traj(t, np.full_like(t, kmh_to_ms(200.0))),
            "V2": _traj(t, np.where(t < 1.0, 0.0, kmh_to_ms(54.0)))}
    out = Scripted(lambda s: _outcome(s, [[100, 0, 0], [10, 20, 0]], [[kmh_to_ms(200.0), 0, 0], [0, 0, 0]],
                                      trajectories=traj)).simulate(scene)
    assert out.violations == ["energy_outside_contact"] and "V2 gains 78.8 kJ" in out.warnings[-1]


def test_energy_change_inside_contact_is_not_a_violation():
    scene = _two_cars()
    t = np.linspace(0, 2, 201)
    v1 = np.where(t < 1.0, 5.0, 12.0)  # a push while in contact: work done by the contact force
    traj = {"V1": _traj(t, v1), "V2": _traj(t, np.zeros_like(t))}
    out = Scripted(lambda s: _outcome(s, [[20, 0, 0], [30, 0, math.pi]], trajectories=traj,
                                      contact_intervals=[(0.95, 1.05)])).simulate(scene)
    assert out.outcome_ok, out.warnings


def test_energy_at_the_end_above_the_start_fails_without_trajectories():
    """Batch runs record no trajectory: the end-to-start balance still catches energy from nowhere."""
    scene = _two_cars()
    fast = [[kmh_to_ms(90.0), 0.0, 0.0], [0.0, 0.0, 0.0]]
    out = Scripted(lambda s: _outcome(s, [[20, 0, 0], [30, 0, math.pi]], fast)).simulate(scene)
    assert out.violations == ["energy_overall"]
    out = Scripted(lambda s: _outcome(s, [[20, 0, 0], [30, 0, math.pi]],
                                      [[kmh_to_ms(49.0), 0, 0], [0, 0, 0]])).simulate(scene)
    assert out.outcome_ok, "less energy than at the start is fine"


def test_impact_creating_energy_fails():
    scene = _two_cars()
    out = Scripted(lambda s: _outcome(s, [[20, 0, 0], [30, 0, math.pi]], impact_energy=[5e3, -58e3])).simulate(scene)
    assert out.violations == ["impact_energy"] and "impact 2 creates 58.0 kJ" in out.warnings[-1]


def test_vehicles_ending_inside_each_other_fail():
    scene = _two_cars()
    out = Scripted(lambda s: _outcome(s, [[20, 0, 0], [22, 0.5, 0.3]])).simulate(scene)
    assert out.violations == ["interpenetration"]
    out = Scripted(lambda s: _outcome(s, [[20, 0, 0], [24.2, 0, 0]])).simulate(scene)  # 4 cm apart: fine
    assert out.outcome_ok, out.warnings


def test_vehicle_inside_a_barrier_fails():
    scene = build_scene([{"speed": 50.0}], barriers=[{"x": 10.0, "y": 0.0, "length": 1.0, "width": 4.0}])
    out = Scripted(lambda s: _outcome(s, [[9.0, 0, 0]])).simulate(scene)
    assert out.violations == ["interpenetration"] and "barrier 0" in out.warnings[-1]


def test_body_below_the_road_fails_and_a_roof_is_reported():
    scene = _two_cars()
    t = np.linspace(0, 1, 11)
    below = {"V1": _traj(t, np.zeros_like(t), z=np.full_like(t, 0.5), z_min=np.linspace(0.1, -0.4, 11)),
             "V2": _traj(t, np.zeros_like(t))}
    out = Scripted(lambda s: _outcome(s, [[20, 0, 0], [30, 0, math.pi]], trajectories=below)).simulate(scene)
    assert out.violations == ["below_road"] and "0.40 m below the road" in out.warnings[-1]
    roof = {"V1": _traj(t, np.zeros_like(t), z=np.full_like(t, 0.5), z_min=np.zeros_like(t),
                        roll=np.linspace(0, math.pi, 11), pitch=np.zeros_like(t)),
            "V2": _traj(t, np.zeros_like(t))}
    out = Scripted(lambda s: _outcome(s, [[20, 0, 0], [30, 0, math.pi]], trajectories=roof)).simulate(scene)
    assert out.outcome_ok and out.rolled_over == ["V1"] and any("V1 rolled over" in w for w in out.warnings)


def test_a_model_may_skip_checks_that_do_not_apply():
    class Soft(Scripted):
        name = "soft"
        guard_skip = frozenset({"interpenetration"})

    scene = _two_cars()
    out = Soft(lambda s: _outcome(s, [[20, 0, 0], [22, 0.5, 0.3]])).simulate(scene)
    assert out.outcome_ok and out.guarded
    with pytest.raises(TypeError, match="unknown guard checks"):
        type("Bad", (CollisionModel,), {"simulate": lambda self, s: None, "guard_skip": frozenset({"nope"})})


def test_a_simulate_from_a_mixin_is_guarded_too():
    class Mixin:
        def simulate(self, scene):
            return _outcome(scene, [[20, 0, 0], [30, 0, math.pi]], [[kmh_to_ms(900.0), 0, 0], [0, 0, 0]])

    class FromMixin(Mixin, CollisionModel):
        name = "from-mixin"

    out = FromMixin().simulate(_two_cars())
    assert out.guarded and out.violations == ["energy_overall"]


def test_a_model_without_final_velocities_reports_no_rest():
    scene = _two_cars()
    out = Outcome(scene.vehicle_names, np.array([[20, 0, 0], [30, 0, math.pi]], float), model="bare")
    assert not out.at_rest_mask.any()
    guard.check(scene, out)
    assert not out.outcome_ok and out.violations == ["non_finite"]


def test_a_plugin_that_is_no_collision_model_is_refused(monkeypatch):
    from crashlab import registry

    class Duck:
        def simulate(self, scene):
            return None

    monkeypatch.setattr(registry, "load", lambda group, name: Duck)
    with pytest.raises(TypeError, match="does not derive from crashlab.CollisionModel"):
        registry.get_model("duck")


def test_batch_is_guarded_like_single_runs():
    scene = _two_cars()
    model = Scripted(lambda s: _outcome(s, [[20, 0, 0], [30, 0, math.pi]],
                                        [[kmh_to_ms(90.0), 0.0, 0.0], [0.0, 0.0, 0.0]]))
    outs = model.simulate_batch([scene, scene])
    assert [o.violations for o in outs] == [["energy_overall"]] * 2


def test_builtin_impulse_results_are_guarded(pc_crash_dir):
    scene = crashlab.load_scene(pc_crash_dir / "side.toml")
    out = crashlab.simulate(scene, model="impulse")
    assert out.guarded and out.outcome_ok and not out.violations
    outs = crashlab.get_model("impulse").simulate_batch([scene, scene])
    assert all(o.guarded and o.outcome_ok for o in outs)


# ------------------------------------------------------------------ rest means rest
def test_moving_vehicle_is_an_end_pose_not_a_rest_pose():
    """A run cut short by its duration: the car still moves, and out.rest says so (speed, at_rest)."""
    scene = build_scene([{"speed": 50.0, "wheels": "locked"}], duration=0.5, road={"friction": 0.8})
    out = crashlab.simulate(scene, model="impulse")
    rest = out.rest
    v_expected = 50.0 - 3.6 * 0.8 * 9.81 * 0.5  # km/h after 0.5 s of locked braking
    assert rest.at["V1", "speed"] == pytest.approx(v_expected, rel=0.02)
    assert not rest.at["V1", "at_rest"]
    assert out.pose_label(0) == f"end pose (moving {rest.at['V1', 'speed']:.1f} km/h)"
    full = crashlab.simulate(scene.replace(duration=5.0), model="impulse")
    assert full.rest.at["V1", "at_rest"] and full.rest.at["V1", "speed"] < 0.36


def _write(tmp_path, text):
    p = tmp_path / "scene.toml"
    p.write_text(text)
    return p


MOVING = """name = "cut short"
duration = 0.5
[[vehicles]]
name = "V1"
vehicle = "clio"
speed = 50.0
wheels = "locked"
"""


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "crashlab.cli", *map(str, args)], capture_output=True, text=True,
                          timeout=300)


def test_cli_says_end_pose_for_a_moving_vehicle(tmp_path):
    res = _cli("simulate", _write(tmp_path, MOVING))
    assert res.returncode == 0, res.stderr
    assert "V1: end pose (moving 35.9 km/h)" in res.stdout


NOT_APPROACHING = """name = "moving apart at the given point of impact"
duration = 2.0
[impact]
point = [2.0, 0.0]
plane_angle = 90.0
[[vehicles]]
name = "V1"
vehicle = "clio"
x = 0.0
heading = 180.0
speed = 20.0
[[vehicles]]
name = "V2"
vehicle = "clio"
x = 4.0
speed = 20.0
"""


def test_cli_failed_simulation_exits_3_with_one_line(tmp_path):
    res = _cli("simulate", _write(tmp_path, NOT_APPROACHING))
    assert res.returncode == 3, (res.returncode, res.stderr)
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("crashlab: simulation failed: ") and "scene.toml" in lines[0]
    assert res.stdout == ""


# ------------------------------------------------------------------ no blind spots (issue 27)
def _checked_then_changed(change):
    """A plugin that runs an inner model (whose Outcome the guard checked) and returns it after `change`."""
    inner = Scripted(lambda s: _outcome(s, [[20, 0, 0], [30, 0, math.pi]]))

    class Reuser(CollisionModel):
        name = "reuser"

        def simulate(self, scene):
            out = inner.simulate(scene)
            assert out.guarded and out.outcome_ok
            change(out)
            return out

    return Reuser()


def test_a_checked_outcome_changed_after_the_check_is_checked_again():
    """An Outcome the guard passed (guarded True), then given NaN rest poses by a plugin: it fails; the
    reused unchanged Outcome passes without a second warning."""
    def nan_rest(out):
        out.rest_si[:] = np.nan

    out = _checked_then_changed(nan_rest).simulate(_two_cars())
    assert not out.outcome_ok and out.violations == ["non_finite"]
    assert out.at_rest_mask.all()  # at rest, NaN poses: what issue 27 saw pass
    out = _checked_then_changed(lambda o: None).simulate(_two_cars())
    assert out.outcome_ok and out.warnings == [] and out.violations == []


def test_a_checked_outcome_given_energy_after_the_check_fails():
    def speed_up(out):
        out.final_si[0] = (kmh_to_ms(120.0), 0.0, 0.0)

    out = _checked_then_changed(speed_up).simulate(_two_cars())
    assert out.violations == ["energy_overall"]


def test_an_instance_level_simulate_is_guarded():
    """A plugin that assigns self.simulate (and simulate_batch, simulate_population) in __init__: what it
    returns passes the guard like a method's result."""
    fast = [[kmh_to_ms(900.0), 0, 0], [0, 0, 0]]

    class Sneaky(CollisionModel):
        name = "sneaky"

        def __init__(self):
            super().__init__()
            self.simulate = self._fast
            self.simulate_batch = lambda scenes: [self._fast(s) for s in scenes]

        def simulate(self, scene):  # never called: the instance's attribute shadows it
            raise AssertionError

        def _fast(self, scene):
            return _outcome(scene, [[20, 0, 0], [30, 0, math.pi]], fast)

    model = Sneaky()
    assert model.simulate(_two_cars()).violations == ["energy_overall"]
    assert [o.violations for o in model.simulate_batch([_two_cars()] * 2)] == [["energy_overall"]] * 2
    pop = model.simulate_population(_two_cars(), ["vehicles.V1.speed"], [[50.0], [60.0]])
    assert not pop.ok.any() and all("energy_overall" in r for r in pop.reason)
    vars(model)["simulate"] = model._fast  # written into the instance's __dict__: guarded too
    assert model.simulate(_two_cars()).violations == ["energy_overall"]


def test_nan_anywhere_in_a_trajectory_fails_with_vehicle_column_and_time():
    scene = _two_cars()
    t = np.linspace(0, 1, 11)
    vx = np.zeros_like(t)
    vx[4] = np.nan
    traj = {"V1": _traj(t, np.zeros_like(t)), "V2": _traj(t, vx)}
    out = Scripted(lambda s: _outcome(s, [[0, 0, 0], [30, 0, 0]], trajectories=traj)).simulate(scene)
    assert out.violations == ["non_finite"]
    assert "V2's trajectory column vx is nan at t = 0.400 s" in out.warnings[-1]
    traj["V2"]["vx"][4] = np.inf
    out = Scripted(lambda s: _outcome(s, [[0, 0, 0], [30, 0, 0]], trajectories=traj)).simulate(scene)
    assert out.violations == ["non_finite"] and "vx is inf" in out.warnings[-1]


@pytest.mark.parametrize("z_min, verdict", [
    ({(30, 33): -0.08}, None),  # a landing: 8 cm for 30 ms, then carried
    ({(30, 30): -0.12}, "reaches 0.12 m below the road at t = 0.30 s"),  # one sample through the road
    ({(30, 50): -0.06}, "is 0.06 m below the road on average over 0.1 s from t = 0.30 s"),  # held below 5 cm
    ({(30, 35): -0.06}, None),  # below 5 cm for 50 ms: a bounce
    ({(80, 100): -0.06}, "is 0.06 m below the road on average over 0.1 s from t = 0.80 s"),  # resting below 5 cm
    # held 7 cm deep for 0.5 s, every fifth sample 4.9 cm (the review: a run of samples was broken by it)
    ({(30, 80): -0.07, **{(k, k): -0.049 for k in range(30, 81, 5)}}, "below the road on average over 0.1 s"),
])
def test_below_road_tells_a_landing_from_a_body_through_the_road(z_min, verdict):
    """docs/physics.md §19: deeper than 0.10 m at any sample, or 0.05 m below the road on average over any 0.1 s,
    fails; a landing bounce off the road contact (brief, less than 10 cm) does not. Samples every 10 ms over 1 s."""
    scene = _two_cars()
    t = np.linspace(0, 1, 101)
    z = np.full_like(t, 0.2)
    for (a, b), depth in z_min.items():
        z[a:b + 1] = depth
    traj = {"V1": _traj(t, np.zeros_like(t), z=np.full_like(t, 0.5), z_min=z), "V2": _traj(t, np.zeros_like(t))}
    out = Scripted(lambda s: _outcome(s, [[20, 0, 0], [30, 0, math.pi]], trajectories=traj)).simulate(scene)
    if verdict is None:
        assert out.outcome_ok, out.warnings
    else:
        assert out.violations == ["below_road"] and verdict in out.warnings[-1], out.warnings


def test_below_road_does_not_depend_on_the_record_interval():
    """A body held 6 cm below the road for 0.3 s fails whether it is recorded every 10 ms or at uneven intervals
    of 5-60 ms; a 40 ms bounce to 8 cm passes either way (the time average of §19, not a count of samples)."""
    scene = _two_cars()
    rng = np.random.default_rng(3)
    for t in (np.linspace(0, 1, 101), np.cumsum(np.r_[0.0, rng.uniform(0.005, 0.06, 40)])):
        for span, depth, fails in (((0.3, 0.6), 0.06, True), ((0.3, 0.34), 0.08, False)):
            z = np.where((t >= span[0]) & (t <= span[1]), -depth, 0.2)
            traj = {"V1": _traj(t, np.zeros_like(t), z=np.full_like(t, 0.5), z_min=z),
                    "V2": _traj(t, np.zeros_like(t))}
            out = Scripted(lambda s, tr=traj: _outcome(s, [[20, 0, 0], [30, 0, math.pi]], trajectories=tr)
                           ).simulate(scene)
            assert (out.violations == ["below_road"]) == fails, (len(t), span, out.warnings)


def test_one_nan_z_min_sample_does_not_hide_a_car_below_the_road():
    scene = _two_cars()
    t = np.linspace(0, 1, 11)
    z_min = np.full_like(t, -0.5)
    z_min[3] = np.nan
    traj = {"V1": _traj(t, np.zeros_like(t), z=np.full_like(t, 0.5), z_min=z_min), "V2": _traj(t, np.zeros_like(t))}
    out = Scripted(lambda s: _outcome(s, [[0, 0, 0], [30, 0, 0]], trajectories=traj)).simulate(scene)
    assert out.violations == ["non_finite", "below_road"] and "0.50 m below the road" in out.warnings[-1]


def test_final_velocities_that_contradict_the_trajectorys_end_fail():
    """Rest speed 51 km/h while the recorded trajectory ends at 0: end_state; the trajectory's last sample
    itself, or within the tolerance of one record interval, passes."""
    scene = _two_cars()
    t = np.linspace(0, 1, 11)
    traj = {"V1": _traj(t, np.zeros_like(t)), "V2": _traj(t, np.zeros_like(t), x=np.full_like(t, 30.0))}
    out = Scripted(lambda s: _outcome(s, [[0, 0, 0], [30, 0, 0]], [[kmh_to_ms(51.0), 0, 0], [0, 0, 0]], raw=True,
                                      trajectories=traj)).simulate(scene)
    assert "end_state" in out.violations
    assert "V1's vx [m/s] at the end is 14.2, its trajectory ends at 0" in out.warnings[out.violations.index(
        "end_state")]
    out = Scripted(lambda s: _outcome(s, [[0, 0, 0], [30, 0, 0]], [[0.5, 0, 0], [0, 0, 0]], raw=True,
                                      trajectories=traj)).simulate(scene)
    assert out.outcome_ok, out.warnings
    out = Scripted(lambda s: _outcome(s, [[0, 0, 0], [35.0, 0, 0]], raw=True, trajectories=traj)).simulate(scene)
    assert out.violations == ["end_state"] and "V2's x [m] at the end is 35" in out.warnings[-1]


def test_monte_carlo_and_compare_do_not_report_a_changed_checked_outcome_as_ok(pc_crash_dir):
    """Issue 27: a plugin that gave a checked Outcome NaN rest poses had the Monte Carlo report "failed
    draws: 0" with NaN medians and `compare` show it as ok."""
    from crashlab.reconstruction import montecarlo
    from crashlab.tools.compare import comparison_table

    def nan_rest(out):
        out.rest_si[:] = np.nan

    scene = crashlab.load_scene(pc_crash_dir.parent / "montecarlo" / "side.toml")
    model = _checked_then_changed(nan_rest)
    result = montecarlo.run(scene, model, 5, seed=1)
    assert len(result.failed) == 5 and all("non_finite" in r for r in result.failed["reason"])
    assert (result.summary()["draws"] == 0).all()
    table = comparison_table(scene, {"reuser": model.simulate(scene)})
    assert not table[table.source == "reuser"]["ok"].any()


def test_nan_in_an_impact_row_fails():
    scene = _two_cars()
    row = {"t": 0.1, "vehicle": "V1", "other": "V2", "dvx": math.nan, "dvy": 0.0, "d_yaw_rate": 0.0, "energy": 1e3,
           "kind": "full", "point_x": 0.0, "point_y": 0.0, "plane_angle": 0.0}
    out = Scripted(lambda s: _outcome(s, [[20, 0, 0], [30, 0, math.pi]], impact_rows=[row])).simulate(scene)
    assert out.violations == ["non_finite"] and "impact row 1 (V1 with V2): column dvx is nan" in out.warnings[-1]
