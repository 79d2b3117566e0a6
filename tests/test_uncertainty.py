"""Scene fields (crashlab.fields) and uncertain parameters (crashlab.uncertainty), docs/physics.md
(uncertain parameters and Monte Carlo): every path form set and read back in file units with the SI value
in the scene; a mass set as a vehicle file's override sets it; the reconstruction's free fields are the
same quantities; sampling statistics of the three distributions; bad [[uncertain]] input is one line
naming the file and the key, exit 2."""
from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
from conftest import REPO, build_scene
from scipy import stats

from crashlab import fields, uncertainty
from crashlab.cli import main
from crashlab.errors import InputError
from crashlab.scene_file import load_scene
from crashlab.units import deg_to_rad, kmh_to_ms
from crashlab.vehicle import load_vehicle

SIDE = REPO / "studies" / "montecarlo" / "side.toml"


def _scene():
    """Two cars, a friction zone, V1 with two actions (brake ramp, then steer)."""
    return build_scene(
        [{"x": -20.0, "speed": 60.0, "actions": [{"t": 0.5, "brake": 0.6, "ramp": 0.2, "steer": 2.0},
                                                 {"t": 1.5, "wheels": "locked", "steer": -3.0}]},
         {"x": 5.0, "y": 3.0, "heading": 90.0, "speed": 20.0, "yaw_rate": 5.0, "steer": 1.0}],
        road={"friction": 0.8, "zones": [{"friction": 0.4, "polygon": [[-10, -3], [-5, -3], [-5, 3], [-10, 3]]}]},
        impact={"restitution": 0.1, "friction": 0.3}, duration=5.0)


# path, new value (file units), where the SI value sits, the SI value
def _owner_cases(s):
    v1, v2 = "vehicles.V1.", "vehicles.V2."
    return [
        ("road.friction", 0.65, lambda t: t.road.friction, 0.65),
        ("road.zones.0.friction", 0.3, lambda t: t.road.zones[0].friction, 0.3),
        ("impact.restitution", 0.2, lambda t: t.impact.restitution, 0.2),
        ("impact.friction", 0.45, lambda t: t.impact.friction, 0.45),
        (v2 + "x", 5.5, lambda t: t.vehicle("V2").x, 5.5),
        (v2 + "y", 2.5, lambda t: t.vehicle("V2").y, 2.5),
        (v2 + "heading", 80.0, lambda t: t.vehicle("V2").heading, deg_to_rad(80.0)),
        (v1 + "speed", 72.0, lambda t: t.vehicle("V1").speed, kmh_to_ms(72.0)),
        (v2 + "yaw_rate", -10.0, lambda t: t.vehicle("V2").yaw_rate, deg_to_rad(-10.0)),
        (v2 + "steer", 3.0, lambda t: t.vehicle("V2").steer, deg_to_rad(3.0)),
        (v1 + "actions.0.t", 0.7, lambda t: t.vehicle("V1").actions[0].t, 0.7),
        (v1 + "actions.0.brake", 0.9, lambda t: t.vehicle("V1").actions[0].brake, 0.9),
        (v1 + "actions.0.steer", -4.0, lambda t: t.vehicle("V1").actions[0].steer, deg_to_rad(-4.0)),
        (v1 + "actions.0.ramp", 0.4, lambda t: t.vehicle("V1").actions[0].ramp, 0.4),
        (v1 + "actions.1.steer", 6.0, lambda t: t.vehicle("V1").actions[1].steer, deg_to_rad(6.0)),
        (v1 + "mass", 1100.0, lambda t: t.vehicle("V1").spec.mass, 1100.0),
        (v1 + "yaw_inertia", 1500.0, lambda t: t.vehicle("V1").spec.yaw_inertia, 1500.0),
    ]


@pytest.mark.parametrize("k", range(17))
def test_set_then_get_every_path_form(k):
    s = _scene()
    path, value, where, si = _owner_cases(s)[k]
    before = fields.get(s, path)
    t = fields.set_field(s, path, value)
    assert fields.get(t, path) == pytest.approx(value, rel=1e-12, abs=1e-12)
    assert where(t) == pytest.approx(si, rel=1e-12, abs=1e-15)
    assert fields.get(s, path) == before  # the original scene is untouched
    others = [c[0] for c in _owner_cases(s) if c[0] != path]
    assert [fields.get(t, p) for p in others] == pytest.approx([fields.get(s, p) for p in others], rel=1e-12)
    assert fields.parse(path).path == path


def test_set_several_at_once_and_alias():
    s = _scene()
    paths = [c[0] for c in _owner_cases(s)]
    values = [c[1] for c in _owner_cases(s)]
    t = fields.set_fields(s, paths, values)
    assert [fields.get(t, p) for p in paths] == pytest.approx(values, rel=1e-12)
    assert fields.parse("zones.0.friction").path == "road.zones.0.friction"
    assert fields.get(s, "zones.0.friction") == fields.get(s, "road.zones.0.friction") == 0.4
    # dataclass copies: the unchanged parts are shared, the scene compares equal to one made from the file
    u = fields.set_field(s, "vehicles.V2.speed", 20.0)
    assert u.vehicle("V1") is s.vehicle("V1") and u.road is s.road and u == s


def test_mass_set_as_a_vehicle_file_override_sets_it():
    """vehicles.V1.mass replaces the total mass and keeps inertias and per-model sections, exactly as
    `overrides.mass` in a scene does (crashlab.vehicle.load_vehicle)."""
    s = _scene()
    t = fields.set_field(s, "vehicles.V1.mass", 1234.0)
    over = load_vehicle("clio", overrides={"mass": 1234.0})
    got = t.vehicle("V1").spec
    assert got == over and got.sections == over.sections
    assert dataclasses.asdict(got) == dataclasses.asdict(over)
    # and a scene written with that override is the same scene
    written = build_scene([{"x": -20.0, "speed": 60.0, "overrides": {"mass": 1234.0}}])
    assert fields.set_field(build_scene([{"x": -20.0, "speed": 60.0}]), "vehicles.V1.mass", 1234.0) == written


def test_mass_outside_the_vehicle_checks_is_refused_as_an_override_is():
    s = _scene()
    lo, hi = fields.field_range(s, "vehicles.V1.mass")
    assert 50.0 <= lo < 980.0 < hi <= 60000.0
    with pytest.raises(ValueError, match="outside"):
        fields.set_field(s, "vehicles.V1.mass", hi * 1.5)
    with pytest.raises(ValueError, match="radius of gyration"):  # the range is the vehicle's own check
        fields.with_spec(s.vehicle("V1").spec, mass=hi * 1.001)
    with pytest.raises(InputError, match="radius of gyration"):  # the same bound for the override
        load_vehicle("clio", overrides={"mass": hi * 1.5})
    fields.set_field(s, "vehicles.V1.mass", hi * 0.999)  # inside: accepted
    load_vehicle("clio", overrides={"mass": hi * 0.999})


@pytest.mark.parametrize("path, match", [
    ("vehicles.V1.colour", "valid: road.friction"), ("road.mu", "valid:"), ("impact.law", "valid:"),
    ("vehicles.V9.speed", "no vehicle 'V9'"), ("road.zones.3.friction", "1 friction zone"),
    ("vehicles.V1.actions.2.t", "2 action"), ("vehicles.V1.actions.1.brake", "sets no brake")])
def test_unknown_or_missing_field(path, match):
    with pytest.raises(ValueError, match=match):
        fields.get(_scene(), path)


def test_values_outside_the_range_and_actions_out_of_order():
    s = _scene()
    with pytest.raises(ValueError, match=r"impact.restitution = 1.2 is outside \[0, 1\]"):
        fields.set_field(s, "impact.restitution", 1.2)
    assert fields.field_range(s, "vehicles.V1.actions.0.t") == (0.0, pytest.approx(1.3))  # next at 1.5, ramp 0.2
    with pytest.raises(ValueError, match="outside"):
        fields.set_field(s, "vehicles.V1.actions.0.t", 1.4)
    with pytest.raises(ValueError, match="not after action 0"):  # both moved: the order check itself
        fields.set_fields(s, ["vehicles.V1.actions.0.t", "vehicles.V1.actions.0.ramp", "vehicles.V1.actions.1.t"],
                          [1.0, 0.0, 0.9])
    with pytest.raises(ValueError, match="ramp .* reaches past action 1"):
        fields.set_fields(s, ["vehicles.V1.actions.0.t", "vehicles.V1.actions.1.t"], [1.0, 1.1])
    with pytest.raises(ValueError, match="given twice"):
        fields.setter(s, ["zones.0.friction", "road.zones.0.friction"])


# ---------------------------------------------------------------- distributions
def _entries(raw, scene=None):
    return uncertainty.parse(raw, scene or _scene(), "<test>")


def test_normal_sampling_statistics():
    (e,) = _entries([{"field": "road.friction", "distribution": "normal", "mean": 0.8, "sd": 0.05}])
    x = uncertainty.sample([e], 20000, np.random.default_rng(3))[:, 0]
    # the truncation at [0, 2] is 16 sd away: the draws are those of the normal; mean within 4 standard
    # errors, sd within 4 % (its standard error is 0.5 %)
    assert abs(x.mean() - 0.8) < 4 * 0.05 / math.sqrt(20000)
    assert x.std(ddof=1) == pytest.approx(0.05, rel=0.04)
    assert uncertainty.logpdf([e], [0.83]) == pytest.approx(stats.norm(0.8, 0.05).logpdf(0.83), rel=1e-9)
    assert e.interval(0.9) == pytest.approx((0.8 - 1.644854 * 0.05, 0.8 + 1.644854 * 0.05), rel=1e-6)


def test_truncated_normal_stays_in_range():
    (e,) = _entries([{"field": "impact.restitution", "distribution": "normal", "mean": 0.05, "sd": 0.1}])
    assert (e.lower, e.upper) == (0.0, 1.0)  # the restitution's range
    x = e.sample(20000, np.random.default_rng(1))
    assert x.min() >= 0.0 and x.max() <= 1.0
    assert uncertainty.logpdf([e], [-0.01]) == -np.inf
    # normalised on its support: the density integrates to 1 (trapezoid on a fine grid)
    g = np.linspace(0, 1, 20001)
    assert np.trapezoid(np.exp(e.logpdf(g)), g) == pytest.approx(1.0, abs=1e-6)


def test_uniform_bounds_and_density():
    (e,) = _entries([{"field": "vehicles.V1.speed", "distribution": "uniform", "lower": 40, "upper": 60}])
    x = e.sample(20000, np.random.default_rng(2))
    assert 40.0 <= x.min() < 40.1 and 59.9 < x.max() <= 60.0
    assert abs(x.mean() - 50.0) < 4 * (20 / math.sqrt(12)) / math.sqrt(20000)
    assert uncertainty.logpdf([e], [55.0]) == pytest.approx(-math.log(20.0))
    assert uncertainty.logpdf([e], [61.0]) == -np.inf


def test_triangular_mode_and_mean():
    (e,) = _entries([{"field": "impact.friction", "distribution": "triangular", "lower": 0.2, "mode": 0.3,
                      "upper": 0.6}])
    x = e.sample(20000, np.random.default_rng(4))
    assert x.min() >= 0.2 and x.max() <= 0.6
    counts, edges = np.histogram(x, bins=20, range=(0.2, 0.6))
    peak = 0.5 * (edges[counts.argmax()] + edges[counts.argmax() + 1])
    assert abs(peak - 0.3) <= 0.02 + 1e-12  # the fullest bin holds the mode (bins 0.02 wide)
    sd = math.sqrt((0.2**2 + 0.3**2 + 0.6**2 - 0.2 * 0.3 - 0.2 * 0.6 - 0.3 * 0.6) / 18)
    assert abs(x.mean() - (0.2 + 0.3 + 0.6) / 3) < 4 * sd / math.sqrt(20000)
    assert np.exp(e.logpdf(0.3)) == pytest.approx(2 / (0.6 - 0.2))  # the peak density


def test_sampling_is_seeded_and_apply_sets_the_row():
    s = load_scene(SIDE)
    a = uncertainty.sample(s.uncertain, 50, 7)
    assert np.array_equal(a, uncertainty.sample(s.uncertain, 50, np.random.default_rng(7)))
    t = uncertainty.apply(s, s.uncertain, a[0])
    assert [fields.get(t, e.field) for e in s.uncertain] == pytest.approx(list(a[0]), rel=1e-12)
    u = uncertainty.ppf(s.uncertain, np.full((1, len(s.uncertain)), 0.5))[0]
    assert u[0] == pytest.approx(0.8) and u[3] == pytest.approx(50.0)  # medians of the normals


# ---------------------------------------------------------------- bad input
def _write(tmp_path: Path, entries: str) -> Path:
    base = SIDE.read_text().split("[[uncertain]]")[0]
    p = tmp_path / "mc.toml"
    p.write_text(base + entries)
    return p


@pytest.mark.parametrize("entry, key, problem", [
    ('field = "road.friction"\ndistribution = "normal"\nmean = 0.8\nsd = 0.0', "uncertain.0.sd", "greater than 0"),
    ('field = "road.friction"\ndistribution = "normal"\nmean = 0.8\nsd = -0.1', "uncertain.0.sd", "greater than 0"),
    ('field = "road.mu"\ndistribution = "uniform"\nlower = 0.5\nupper = 0.9', "uncertain.0.field", "unknown field"),
    ('field = "vehicles.V3.speed"\ndistribution = "uniform"\nlower = 40\nupper = 60', "uncertain.0.field",
     "no vehicle 'V3'"),
    ('field = "vehicles.V1.actions.0.t"\ndistribution = "uniform"\nlower = 0\nupper = 1', "uncertain.0.field",
     "0 action"),
    ('field = "road.zones.0.friction"\ndistribution = "uniform"\nlower = 0.1\nupper = 0.5', "uncertain.0.field",
     "0 friction zone"),
    ('field = "road.friction"\ndistribution = "uniform"\nlower = 0.9\nupper = 0.5', "uncertain.0.upper",
     "must be above lower"),
    ('field = "impact.restitution"\ndistribution = "uniform"\nlower = 0.1\nupper = 1.5', "uncertain.0.upper",
     "outside the range"),
    ('field = "impact.friction"\ndistribution = "triangular"\nlower = 0.2\nmode = 0.7\nupper = 0.5',
     "uncertain.0.mode", "outside [lower, upper]"),
    ('field = "road.friction"\ndistribution = "normal"\nmean = 2.5\nsd = 0.1', "uncertain.0.mean", "outside"),
    ('field = "road.friction"\ndistribution = "uniform"\nlower = 0.5\nupper = 0.9\nsd = 0.1', "uncertain.0.sd",
     "not a parameter of a uniform"),
    ('field = "road.friction"\ndistribution = "triangular"\nlower = 0.5\nupper = 0.9', "uncertain.0.mode",
     "missing key"),
    ('field = "road.friction"\ndistribution = "lognormal"\nmean = 0.5\nsd = 0.1', "uncertain.0.distribution",
     "uniform"),
    ('field = "road.friction"\ndistribution = "uniform"\nlower = 0.5\nupper = "0.9"', "uncertain.0.upper",
     "got '0.9'"),
    ('field = "road.friction"\ndistribution = "uniform"\nlower = 0.5\nupper = 0.9\n[[uncertain]]\n'
     'field = "road.friction"\ndistribution = "uniform"\nlower = 0.6\nupper = 0.7', "uncertain.1.field",
     "already uncertain"),
    ('field = "vehicles.V1.mass"\ndistribution = "uniform"\nlower = 900\nupper = 9000', "uncertain.0.upper",
     "outside the range of vehicles.V1.mass"),
])
def test_bad_uncertain_input_is_one_line_exit_2(tmp_path, capsys, entry, key, problem):
    path = _write(tmp_path, "[[uncertain]]\n" + entry + "\n")
    assert main(["simulate", str(path), "--monte-carlo", "10"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    assert err.startswith(f"crashlab: error: {path}: {key}: "), err
    assert problem in err, err
