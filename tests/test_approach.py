"""A collision position ([impact] point, outlines overlapping) in the models that find their own contacts: they run
it from its approach (docs/physics.md §4 "Approach"; crashlab.scene.approach_scene, crashlab.model._as_run). Until
2026-11-28 multibody and exudyn started inside it, the overlap bearing as crush from t = 0 (NHTSA 4474's collision
position passed in multibody and failed in exudyn)."""
from __future__ import annotations

import math
import re

import numpy as np
import pytest

import crashlab
from crashlab.errors import InputError
from crashlab.registry import get_model
from crashlab.scene import approach_scene, start_overlaps
from crashlab.scene_file import scene_from_dict

# two saloons at 40 / 20 km/h, the collision position of a T-bone: V1's front 0.3 m into V2's left side
SCENE = {"duration": 1.0, "stop_at_rest": True, "impact": {"point": [2.15, 0.0], "plane_angle": 90.0},
         "vehicles": [{"name": "V1", "vehicle": "saloon", "speed": 40.0},
                      {"name": "V2", "vehicle": "saloon", "x": 2.15 + 0.6, "y": 0.0, "heading": 90.0,
                       "speed": 20.0}]}


def _start(out, scene):
    """The vehicles' first recorded poses (x [m], y [m], heading [rad]) in scene order."""
    return [(tr.x.iloc[0], tr.y.iloc[0], math.radians(tr.heading.iloc[0]))
            for tr in (out.trajectory(v.name) for v in scene.vehicles)]


@pytest.mark.parametrize("model", ["multibody", "exudyn", "pymunk"])
def test_a_model_that_finds_its_contacts_starts_before_the_collision_position(model):
    if model in ("exudyn", "pymunk"):
        pytest.importorskip(model)
    scene = scene_from_dict(SCENE)
    assert start_overlaps(scene)  # the collision position: the outlines overlap by design
    out = crashlab.simulate(scene, model=model)
    assert out.outcome_ok, out.warnings
    said = [w for w in out.warnings if "collision position" in w]
    assert len(said) == 1 and said[0].startswith(model)
    t_back = float(re.search(r"from ([\d.]+) s before it", said[0]).group(1))
    start = _start(out, scene)
    moved = scene
    for v, (x, y, h) in zip(scene.vehicles, start):
        moved = moved.with_vehicle(v.name, x=x, y=y, heading=h)
    assert not start_overlaps(moved)  # failed before: the run started at the overlapping poses
    for v, (x, y, _) in zip(scene.vehicles, start):
        # back along its own velocity by the time the warning gives (printed to 1 ms; the pose at 1e-9 m)
        dx, dy = v.x - x, v.y - y
        assert math.isclose(dx * math.sin(v.heading) - dy * math.cos(v.heading), 0.0, abs_tol=1e-6)
        assert math.isclose(math.hypot(dx, dy), v.speed * t_back, abs_tol=v.speed * 5e-4 + 1e-9)
    # the run is the approach scene's own, to the last digit (the warning aside)
    same = crashlab.simulate(approach_scene(scene), model=model)
    assert np.array_equal(out.rest_si, same.rest_si)
    assert [w for w in out.warnings if w not in said] == same.warnings


def test_the_impulse_model_resolves_the_collision_position_itself():
    scene = scene_from_dict(SCENE)
    out = crashlab.simulate(scene, model="impulse")
    assert not any("collision position" in w for w in out.warnings)
    assert min(r["t"] for r in out.impact_rows) == 0.0
    assert _start(out, scene)[0][:2] == (scene.vehicles[0].x, scene.vehicles[0].y)


def test_vehicles_that_do_not_part_are_bad_input():
    d = {**SCENE, "vehicles": [{**v, "speed": 0.0} for v in SCENE["vehicles"]]}
    with pytest.raises(InputError) as err:
        crashlab.simulate(scene_from_dict(d), model="multibody")
    assert err.value.key == "impact.point" and "do not part" in err.value.problem


def test_a_population_runs_each_rows_own_approach():
    pytest.importorskip("pymunk")
    scene = scene_from_dict(SCENE)
    model = get_model("pymunk")
    pop = model.simulate_population(scene, ["vehicles.V1.speed"], [[40.0], [60.0]])
    for k, speed in enumerate((40.0, 60.0)):
        one = model.simulate(scene.with_vehicle("V1", speed=speed / 3.6))
        assert np.array_equal(pop.rest[k], one.rest_si)
        assert "collision position" in pop.warnings[k]


def test_the_engagement_point_is_said_to_be_ignored():
    pytest.importorskip("pymunk")
    d = {**SCENE, "impact": {"point": "engagement"},
         "vehicles": [SCENE["vehicles"][0], {**SCENE["vehicles"][1], "x": 5.0, "y": -3.0}]}
    out = crashlab.simulate(scene_from_dict(d), model="pymunk")
    assert any(w.startswith('pymunk ignores [impact] point = "engagement"') for w in out.warnings)
    assert not any("collision position" in w for w in out.warnings)


def test_a_barrier_collision_position_starts_its_gap_away():
    # a saloon (front 2.072 m ahead of its CG) 0.3 m into a wall whose face stands at x = 5 (the wall 1 m thick)
    d = {"duration": 0.5, "impact": {"point": [5.0, 0.0], "plane_angle": 90.0},
         "barriers": [{"x": 5.5, "y": 0.0, "heading": 90.0, "length": 10.0, "width": 1.0}],
         "vehicles": [{"name": "V1", "vehicle": "saloon", "x": 5.0 + 0.3 - 2.072, "speed": 50.0}]}
    scene = scene_from_dict(d)
    app = approach_scene(scene)
    # moved back along x until its front is the gap (0.1 m) short of the face (failed before: no gap to a barrier)
    assert math.isclose(app.vehicles[0].x + 2.072, 5.0 - 0.1, abs_tol=1e-9)
    assert app.vehicles[0].y == 0.0 and app.impact.point is None


def test_the_duration_and_driver_actions_keep_their_time_after_the_collision_position():
    d = {**SCENE, "vehicles": [{**SCENE["vehicles"][0], "actions": [{"t": 0.2, "brake": 1.0}]},
                               {**SCENE["vehicles"][1], "yaw_rate": 30.0}]}
    scene = scene_from_dict(d)
    app = approach_scene(scene)
    v, a = scene.vehicles[0], app.vehicles[0]
    t_back = (v.x - a.x) / v.speed  # V1 drives along +x
    assert t_back > 0
    assert math.isclose(app.vehicles[0].actions[0].t, 0.2 + t_back, rel_tol=1e-12)
    assert math.isclose(app.duration, scene.duration + t_back, rel_tol=1e-12)
    out = crashlab.simulate(scene, model="multibody")
    turned = [w for w in out.warnings if w.startswith("V2's start yaw rate turns it by")]
    assert len(turned) == 1 and math.isclose(float(re.search(r"by ([\d.]+) deg", turned[0]).group(1)),
                                             30.0 * t_back, abs_tol=0.051)


def test_a_batch_says_it_once_and_after_a_failed_runs_reason():
    """simulate_batch's default runs simulate, wrapped too: each note once; the notes after the model's own
    warnings (a population's reason for a failed run is its warnings' first 300 characters: a note first hid it)."""
    pytest.importorskip("pymunk")
    d = {**SCENE, "impact": {"point": "engagement"},
         "vehicles": [SCENE["vehicles"][0], {**SCENE["vehicles"][1], "x": 5.0, "y": -3.0}]}
    out = get_model("pymunk").simulate_batch([scene_from_dict(d)])[0]
    assert sum(w.startswith('pymunk ignores [impact] point = "engagement"') for w in out.warnings) == 1

    class Failing(crashlab.CollisionModel):
        name = "failing"

        def simulate(self, scene):
            return crashlab.Outcome.failed(scene.vehicle_names, "the model's own reason")

    pop = Failing().simulate_population(scene_from_dict(SCENE), ["vehicles.V1.speed"], [[40.0]])
    assert pop.reason[0].startswith("the model's own reason")


def test_a_point_whose_outlines_do_not_overlap_is_dropped_without_moving():
    d = {**SCENE, "vehicles": [SCENE["vehicles"][0], {**SCENE["vehicles"][1], "x": 2.072 + 0.92 + 0.05}]}
    scene = scene_from_dict(d)
    assert not start_overlaps(scene)
    app = approach_scene(scene)
    assert app.impact.point is None and app.vehicles == scene.vehicles and app.duration == scene.duration
    out = crashlab.simulate(scene, model="multibody")
    assert any("ignores the given [impact] point" in w for w in out.warnings)


def test_the_gap_is_the_colliding_pairs_with_a_barrier_beside_them():
    # a rear-end's collision position (saloons at 50 / 30 km/h, V1's front 0.3 m into V2's rear; a saloon's front
    # 2.072 m and rear 2.695 m from its CG) with a wall beside the road: the gap is 0.1 m between the two cars
    # (failed before: the wall's closing speed, V1's 50 km/h, made it 0.04 m)
    d = {"duration": 1.0, "impact": {"point": [2.0, 0.0], "plane_angle": 90.0},
         "barriers": [{"x": 0.0, "y": 6.0, "heading": 0.0, "length": 20.0, "width": 0.5}],
         "vehicles": [{"name": "V1", "vehicle": "saloon", "speed": 50.0},
                      {"name": "V2", "vehicle": "saloon", "x": 2.072 - 0.3 + 2.695, "speed": 30.0}]}
    app = approach_scene(scene_from_dict(d))
    v1, v2 = app.vehicles
    assert math.isclose((v2.x - 2.695) - (v1.x + 2.072), 0.1, abs_tol=1e-9)
