"""Tests of the example model: crashlab's conformance check, then physics against analytic results.

Run after `pip install -e examples/plugin`: `python -m pytest -q examples/plugin/tests` (about 3 s).
"""
import math

import numpy as np
import pytest
from crashlab_example import ExampleModel

import crashlab
from crashlab.scene_file import scene_from_dict
from crashlab.testing import check_collision_model
from crashlab.units import G, kmh_to_ms


def scene(vehicles, **keys):
    """A scene from a dict in file units (m, deg, km/h), as a scene file would give it."""
    return scene_from_dict({"name": "example test", "duration": 10.0, **keys, "vehicles": vehicles})


def test_found_by_its_entry_point():
    assert "example" in crashlab.available_models()
    assert isinstance(crashlab.get_model("example"), ExampleModel)


def test_conforms_to_the_interface():
    check_collision_model(ExampleModel())


def test_head_on_impact_conserves_momentum_and_gives_newtons_restitution():
    """A central head-on impact of a 980 kg Clio at 60 km/h and a 1,730 kg Caravan at 30 km/h, wheels
    rolling without rolling resistance (no road force along the line), e = 0.3: after the impact
    v1' = v1 - (1 + e) m2 / (m1 + m2) (v1 - v2), v2' = v2 + (1 + e) m1 / (m1 + m2) (v1 - v2), and the
    dissipated energy is (1 - e^2) / 2 m1 m2 / (m1 + m2) (v1 - v2)^2. The impulse is exact: tolerance
    1e-9 relative (round-off)."""
    e = 0.3
    s = scene([{"name": "A", "vehicle": "clio", "x": 0.0, "y": 0.0, "heading": 0.0, "speed": 60.0,
                "overrides": {"rolling_resistance": 0.0}},
               {"name": "B", "vehicle": "caravan_1998", "x": 10.0, "y": 0.0, "heading": 180.0, "speed": 30.0,
                "overrides": {"rolling_resistance": 0.0}}],
              duration=1.0, stop_at_rest=False, impact={"restitution": e})
    out = crashlab.get_model("example").simulate(s)
    assert out.outcome_ok, out.warnings
    m1, m2 = (v.spec.mass for v in s.vehicles)
    v1, v2 = kmh_to_ms(60.0), -kmh_to_ms(30.0)
    rel = v1 - v2
    assert out.final_si[0, 0] == pytest.approx(v1 - (1 + e) * m2 / (m1 + m2) * rel, rel=1e-9)
    assert out.final_si[1, 0] == pytest.approx(v2 + (1 + e) * m1 / (m1 + m2) * rel, rel=1e-9)
    assert m1 * out.final_si[0, 0] + m2 * out.final_si[1, 0] == pytest.approx(m1 * v1 + m2 * v2, rel=1e-9)
    assert np.all(np.abs(out.final_si[:, 1:]) < 1e-9)  # nothing sideways (round-off of cos 180 deg), no turn
    dissipated = 0.5 * (1 - e * e) * m1 * m2 / (m1 + m2) * rel ** 2
    assert out.impact_energy.sum() == pytest.approx(dissipated, rel=1e-9)
    rows = out.impacts
    assert len(rows) == 2 and set(rows.vehicle) == {"A", "B"}


def test_locked_wheels_stop_in_the_coulomb_distance():
    """Locked wheels at 50 km/h on mu = 0.8: the car stops after v^2 / (2 mu g) (exact integration of the
    constant deceleration: 1e-9 relative) within one step of v / (mu g)."""
    dt = ExampleModel().options.dt
    out = ExampleModel().simulate(scene([{"name": "A", "vehicle": "clio", "speed": 50.0, "wheels": "locked"}],
                                        road={"friction": 0.8}))
    v = kmh_to_ms(50.0)
    assert out.outcome_ok and out.rest.at_rest.all()
    assert out.rest_si[0, 0] == pytest.approx(v * v / (2 * 0.8 * G), rel=1e-9)
    assert abs(out.diagnostics["t_end"] - v / (0.8 * G)) <= dt


def test_refining_the_step_converges_the_side_collision():
    """The accuracy knob does what its schema says: halving dt moves the rest poses less each time."""
    s = scene([{"name": "V1", "vehicle": "clio", "speed": 50.0, "wheels": "locked_after_impact"},
               {"name": "V2", "vehicle": "clio", "x": 3.5, "heading": 90.0, "speed": 30.0,
                "wheels": "locked_after_impact"}])
    rest = [ExampleModel(dt=dt).simulate(s).rest_si[:, :2] for dt in (0.004, 0.002, 0.001, 0.0005)]
    steps = [np.abs(b - a).max() for a, b in zip(rest, rest[1:])]
    assert steps[-1] < steps[0]


def test_a_turning_start_fails_with_the_reason():
    """The boxes cannot turn: a vehicle that starts yawing is a failed run that says why, not a wrong one."""
    out = ExampleModel().simulate(scene([{"name": "A", "vehicle": "clio", "speed": 30.0, "yaw_rate": 20.0}]))
    assert not out.outcome_ok and "cannot turn" in out.warnings[0]
    assert np.isnan(out.rest_si).all()


def test_driver_actions_are_refused_not_ignored():
    """driver_inputs is False: crashlab refuses a scene with driver actions (InputError naming the key)."""
    s = scene([{"name": "A", "vehicle": "clio", "speed": 30.0, "actions": [{"t": 1.0, "wheels": "locked"}]}])
    with pytest.raises(crashlab.InputError, match="actions"):
        ExampleModel().simulate(s)


def test_barrier_impact_reverses_the_normal_velocity_times_e():
    """A Clio at 64 km/h on ice (mu = 0: no road force) into a rigid barrier turned to 60 deg, e = 0.4: the
    barrier's face normal n is at -30 deg and the velocity after is v - (1 + e) (v . n) n (tolerance 1e-9
    relative); the energy lost is the barrier row's energy."""
    e = 0.4
    s = scene([{"name": "A", "vehicle": "clio", "speed": 64.0, "overrides": {"rolling_resistance": 0.0}}],
              road={"friction": 0.0}, impact={"restitution": e}, duration=1.0, stop_at_rest=False,
              barriers=[{"x": 6.0, "y": 0.0, "heading": 60.0, "length": 8.0, "width": 1.0}])
    out = ExampleModel().simulate(s)
    assert out.outcome_ok, out.warnings
    v = np.array([kmh_to_ms(64.0), 0.0])
    n = np.array([math.cos(math.radians(-30.0)), math.sin(math.radians(-30.0))])
    assert out.final_si[0, :2] == pytest.approx(v - (1 + e) * (v @ n) * n, rel=1e-9)
    m = s.vehicles[0].spec.mass
    lost = 0.5 * m * (v @ v - out.final_si[0, :2] @ out.final_si[0, :2])
    assert out.impacts.other.tolist() == ["barrier0"] and out.impact_energy[0] == pytest.approx(lost, rel=1e-9)


@pytest.mark.parametrize("heading", [0.0, 10.0, -10.0])
def test_a_front_into_a_side_names_the_sides_and_shares_the_energy_by_their_structures(heading):
    """A's front into B's left side, square on or turned (its corner strikes first): the rows name the struck
    sides, and the energy is shared as the compliance 1/B of those sides (the same force on both structures)."""
    s = scene([{"name": "A", "vehicle": "clio", "x": 0.0, "y": 0.0, "heading": heading, "speed": 50.0},
               {"name": "B", "vehicle": "clio", "x": 3.5, "y": 0.0, "heading": 90.0, "speed": 30.0}])
    out = crashlab.get_model("example").simulate(s)
    first = [r for r in out.impact_rows if r["t"] == min(x["t"] for x in out.impact_rows)]
    assert {r["vehicle"]: r["side"] for r in first} == {"A": "front", "B": "left"}
    c = {"A": 1.0 / s.vehicles[0].spec.structure["front"].B, "B": 1.0 / s.vehicles[1].spec.structure["side"].B}
    for r in first:
        assert r["crush_energy"] == pytest.approx(r["energy"] * c[r["vehicle"]] / (c["A"] + c["B"]), rel=1e-9)
