"""Vehicle contact of the multibody model (issue 5): first-contact control, effective restitution of the
validation cases (rigid wall 64 km/h, head-on 50/50 km/h), momentum conservation, impact bookkeeping,
locked-after-impact wheels, no NaN over a sweep of impact speeds and angles (slow).

Effective restitution = relative normal velocity after / before the contact episode: for the collinear
validation cases from the vehicles' CG velocities at the start and end of the episode (impact rows dvx),
and from the contact-point normal velocities (row key "restitution")."""
from pathlib import Path

import numpy as np
import pytest
from geometry_3d import nose_barrier_crush  # noqa: E402

import crashlab
from crashlab.models.multibody import MultibodyModel
from crashlab.scene_file import scene_from_dict
from crashlab.units import kmh_to_ms

ROOT = Path(__file__).resolve().parents[1]
VALID = ROOT / "studies" / "validation"
PC = ROOT / "studies" / "pc_crash"


@pytest.fixture(scope="module")
def model():
    return MultibodyModel()


def _rows(out, vehicle):
    return [r for r in out.impact_rows if r["vehicle"] == vehicle]


def test_rigid_wall_64_effective_restitution(model):
    sc = crashlab.load_scene(VALID / "rigid_wall.toml")
    out = model.simulate(sc)
    assert out.outcome_ok, out.warnings
    (r,) = _rows(out, "V1")
    v0 = kmh_to_ms(64.0)
    e_cg = -(v0 + r["dvx"]) / v0
    assert e_cg == pytest.approx(0.10, abs=0.02)
    assert r["restitution"] == pytest.approx(0.10, abs=0.02)
    assert r["approach_speed"] == pytest.approx(v0, rel=0.01)
    # first-contact control: the contact started with at most onset_tol of penetration
    assert 0.0 < out.diagnostics["max_onset_penetration"] <= model.get_options()["onset_tol"]
    # bookkeeping: horizontal impulse = m dv up to the road's reaction on the spinning wheels (their spin
    # angular momentum 4 I w / R ~ 340 N s comes out through the road as a forward force, 2 %),
    # energy dissipated = kinetic energy lost, a plausible crush and crash pulse
    m = 980.0
    assert r["impulse_x"] == pytest.approx(m * r["dvx"], rel=0.03)
    assert abs(r["impulse_x"]) > abs(m * r["dvx"])
    ke_lost = 0.5 * m * (v0 ** 2 - (v0 + r["dvx"]) ** 2)
    assert r["energy"] == pytest.approx(ke_lost, rel=0.03)
    assert 0.1 < r["max_penetration"] < 0.8
    # the crush structure (docs/physics.md §13a): the largest crush from the energy balance against a rigid
    # barrier over the nose's crush profile, 1/2 m v^2 = B/2 int (C - s(y))+^2 dy (the CRASH3 line through zero
    # force on each line across the rounded nose, its front B: crashlab.structure; 0.763 m, the flat face's
    # sqrt(m v^2 / (w B)) 0.663 m); the 3D car crushes ~1 % deeper (its wheels' spin energy and pitch are not in it)
    spec = sc.vehicles[0].spec
    front = spec.structure["front"]
    c_ref = nose_barrier_crush(0.5 * m * v0 ** 2, front.B, spec.length / 2, spec.width / 2, width=front.width)
    assert r["max_penetration"] == pytest.approx(c_ref, rel=0.03)
    assert 0.05 < r["duration"] < 0.4
    assert r["peak_force"] > r["impulse"] / r["duration"]
    assert r["kind"] == "continuous" and r["other"] == "barrier0"
    assert not r["open"]
    # after the impact the car rolls back from the wall
    assert out.final_si[0, 0] < 0.0


def test_head_on_equal_effective_restitution(model):
    sc = crashlab.load_scene(VALID / "head_on_equal.toml")
    out = model.simulate(sc)
    assert out.outcome_ok, out.warnings
    (r1,), (r2,) = _rows(out, "V1"), _rows(out, "V2")
    v0 = kmh_to_ms(50.0)
    v1_post, v2_post = v0 + r1["dvx"], -v0 + r2["dvx"]
    e_cg = (v2_post - v1_post) / (2 * v0)
    assert e_cg == pytest.approx(0.10, abs=0.02)
    assert r1["restitution"] == pytest.approx(0.10, abs=0.02)
    # symmetric and momentum-conserving impulses
    assert r1["dvx"] == pytest.approx(-r2["dvx"], rel=1e-3)
    assert abs(r1["dvy"]) < 1e-3 and abs(r1["d_yaw_rate"]) < 1e-3
    mu = 490.0
    assert r1["energy"] == pytest.approx(0.5 * mu * (2 * v0) ** 2 * (1 - e_cg ** 2), rel=0.03)


def test_car_to_car_conserves_linear_momentum():
    """Oblique impact with the tyres' in-plane forces off: the contact forces are the only horizontal
    loads, so the total linear momentum is conserved (issue: within 0.5 %)."""
    model = MultibodyModel(friction=False)
    sc = scene_from_dict({"duration": 0.6, "stop_at_rest": False,
                          "impact": {"restitution": 0.1, "friction": 0.3, "force_law": "exact-restitution"},
                          "vehicles": [
                              {"name": "V1", "vehicle": "clio", "x": 0.0, "speed": 50.0, "wheels": "rolling"},
                              {"name": "V2", "vehicle": "saloon", "x": 3.8, "y": -0.3, "heading": 90.0,
                               "speed": 30.0, "wheels": "rolling"}]})
    out = model.simulate(sc)
    assert out.outcome_ok, out.warnings
    assert len(out.impact_rows) == 2 and not out.impact_rows[0]["open"]
    masses = np.array([sc.vehicles[0].spec.mass, sc.vehicles[1].spec.mass])
    p0 = masses[0] * np.array([kmh_to_ms(50.0), 0.0]) + masses[1] * np.array([0.0, kmh_to_ms(30.0)])
    p1 = (masses[:, None] * out.final_si[:, :2]).sum(0)
    assert np.linalg.norm(p1 - p0) / np.linalg.norm(p0) < 0.005
    # and the impact really changed the velocities (oblique: both components, and yaw)
    r1 = out.impact_rows[0]
    assert abs(r1["dvx"]) > 2.0 and abs(r1["d_yaw_rate"]) > 0.1
    # the impulse on each vehicle is m dv of its CG
    for r, m in zip(out.impact_rows, masses):
        assert r["impulse_x"] == pytest.approx(m * r["dvx"], rel=0.01, abs=5.0)
        assert r["impulse_y"] == pytest.approx(m * r["dvy"], rel=0.01, abs=5.0)


def test_locked_after_impact_locks_wheels(model):
    """locked_after_impact: the wheels lock at the first contact, so the cars then skid to rest
    (a free-rolling car would coast for the whole run)."""
    sc = crashlab.load_scene(PC / "side.toml")
    out = model.simulate(sc)
    assert out.outcome_ok, out.warnings
    assert out.diagnostics["t_end"] < 4.0            # everything at rest long before duration = 10 s
    assert np.all(np.abs(out.final_si) < 0.05)
    assert np.all(np.isfinite(out.rest_si))
    assert out.contact_time == pytest.approx(0.83 / kmh_to_ms(50.0), abs=0.01)
    # the broad phase accounts for every pair evaluation, and its cheap stages do remove pairs
    bp = out.diagnostics["broad_phase"]
    assert bp["pair_evaluations"] == (bp["removed_by_circle"] + bp["removed_by_height"] + bp["removed_by_obb"]
                                      + bp["narrow_phase"])
    assert bp["removed_by_circle"] > 0 and bp["removed_by_obb"] > 0 and bp["narrow_phase"] > 0


@pytest.mark.slow
@pytest.mark.parametrize("speed", [5.0, 30.0, 60.0, 100.0, 150.0])
def test_no_nan_over_speeds_and_angles(model, speed, stress_sweep):
    stress_sweep(model, speed)


def test_check_collision_model(model):
    """The plugin conformance check (crashlab.testing) on the multibody model."""
    from crashlab.testing import check_collision_model
    check_collision_model(model)
