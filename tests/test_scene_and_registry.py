"""Scene files, vehicle overrides, validation errors, the plugin registry (the contracts in README.md)."""
from __future__ import annotations

import dataclasses
import subprocess
import sys

import pytest

import crashlab
from crashlab.registry import UnknownPluginError
from crashlab.units import kmh_to_ms


def write(tmp_path, text, name="scene.toml"):
    p = tmp_path / name
    p.write_text(text)
    return p


BASE = """
name = "t"
duration = 2.0
[[vehicles]]
name = "V1"
vehicle = "{vehicle}"
x = 0.0
speed = 50.0
{extra}
"""


def test_load_scene_converts_to_si(pc_crash_dir):
    s = crashlab.load_scene(pc_crash_dir / "side.toml")
    v2 = s.vehicle("V2")
    assert v2.heading == pytest.approx(1.5707963267948966, rel=1e-15)
    assert v2.speed == pytest.approx(kmh_to_ms(30.0), rel=1e-15)
    assert v2.wheels == "locked_after_impact" and v2.spec.rolling_resistance == 0.0
    assert s.references["pc_crash"]["V1"]["x"] == 6.66
    assert s.source.endswith("side.toml")


def test_override_changes_the_vehicle(make_scene):
    plain = make_scene([{}]).vehicles[0].spec
    heavy = make_scene([{"overrides": {"mass": 1500.0, "yaw_inertia": 2000.0}}]).vehicles[0].spec
    assert plain.mass == 980.0 and heavy.mass == 1500.0 and heavy.yaw_inertia == 2000.0
    assert heavy.length == plain.length, "the other properties stay"


def test_override_changes_the_physics(make_scene):
    """A heavier striking car pushes the stopped one faster: v2' = (1+e) m1 v / (m1 + m2)."""
    model = crashlab.get_model("impulse")
    outs = []
    for m1 in (980.0, 1960.0):
        s = make_scene([{"speed": 50.0, "overrides": {"mass": m1, "rolling_resistance": 0.0}},
                        {"x": 5.0, "heading": 180.0, "overrides": {"rolling_resistance": 0.0}}],
                       impact={"restitution": 0.1}, duration=1.0)
        outs.append(model.simulate(s).final.at["V2", "vx"])
    assert outs[0] == pytest.approx(1.1 * 50.0 * 980 / 1960, rel=1e-6)
    assert outs[1] == pytest.approx(1.1 * 50.0 * 1960 / 2940, rel=1e-6)


def test_negative_mass_names_file_and_key(tmp_path):
    p = write(tmp_path, BASE.format(vehicle="clio", extra="[vehicles.overrides]\nmass = -5.0\n"))
    with pytest.raises(crashlab.InputError) as err:
        crashlab.load_scene(p)
    msg = str(err.value)
    assert str(p) in msg and "vehicles.V1.overrides.mass" in msg
    assert err.value.key == "vehicles.V1.overrides.mass"


def test_unknown_vehicle_did_you_mean(tmp_path):
    p = write(tmp_path, BASE.format(vehicle="cleo", extra=""))
    with pytest.raises(crashlab.InputError, match="did you mean 'clio'") as err:
        crashlab.load_scene(p)
    assert str(p) in str(err.value) and err.value.key == "vehicles.V1"


@pytest.mark.parametrize("extra, key", [("sped = 50.0", "vehicles.V1.sped"),
                                        ("wheels = \"blocked\"", "vehicles.V1.wheels"),
                                        ("speed = -3.0", "vehicles.V1.speed")])
def test_bad_keys_named(tmp_path, extra, key):
    text = BASE.format(vehicle="clio", extra=extra).replace("speed = 50.0\n", "")
    with pytest.raises(crashlab.InputError) as err:
        crashlab.load_scene(write(tmp_path, text))
    assert err.value.key == key


def test_point_without_plane_angle_rejected(make_scene):
    with pytest.raises(crashlab.InputError) as err:
        make_scene([{}], impact={"point": [1.0, 0.0]})
    assert err.value.key == "impact.plane_angle"


def test_scene_is_immutable(pc_crash_dir):
    s = crashlab.load_scene(pc_crash_dir / "side.toml")
    with pytest.raises(dataclasses.FrozenInstanceError):
        s.name = "other"
    with pytest.raises(dataclasses.FrozenInstanceError):
        s.vehicles[0].speed = 1.0
    with pytest.raises(dataclasses.FrozenInstanceError):
        s.vehicles[0].spec.mass = 1.0
    with pytest.raises(dataclasses.FrozenInstanceError):
        s.impact.restitution = 0.5


def test_with_vehicle_makes_a_copy(pc_crash_dir):
    s = crashlab.load_scene(pc_crash_dir / "side.toml")
    v = s.with_vehicle("V1", speed=20.0)
    assert v.vehicle("V1").speed == 20.0 and s.vehicle("V1").speed == pytest.approx(kmh_to_ms(50.0))
    assert v.vehicle("V2") is s.vehicle("V2")
    assert s.replace(duration=1.0).duration == 1.0 and s.duration == 10.0
    with pytest.raises(KeyError):
        s.with_vehicle("V9", speed=1.0)


def test_available_models_lists_impulse():
    assert "impulse" in crashlab.available_models()


def test_unknown_model_did_you_mean():
    with pytest.raises(UnknownPluginError, match="did you mean 'impulse'"):
        crashlab.get_model("impuls")
    with pytest.raises(KeyError):
        crashlab.get_model("no-such-model-at-all")


def test_model_options_validated():
    assert crashlab.get_model("impulse", dt=0.001).get_options()["dt"] == 0.001
    with pytest.raises(TypeError):
        crashlab.get_model("impulse", no_such_option=1)
    with pytest.raises(ValueError):
        crashlab.get_model("impulse", dt=-1.0)


def test_listing_models_imports_nothing_heavy():
    code = ("import sys, crashlab; names = crashlab.available_models(); "
            "assert 'impulse' in names, names; "
            "heavy = [m for m in ('crashlab.models.impulse.kernel', 'crashlab.models.impulse', 'numba', "
            "'pymunk', 'exudyn') if m in sys.modules]; print(heavy)")
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr
    assert res.stdout.strip() == "[]", f"imported by listing: {res.stdout}"


# ---------------------------------------------------------------- bounds (scene.py, vehicle.py)
def test_library_vehicles_are_ordinary_cars():
    """The shipped vehicles pass every bound, their radii of gyration lie at 0.2-0.35 x the diagonal (the
    road-vehicle band the bound's documentation quotes), and their multibody sections stay as written."""
    import math

    from crashlab.vehicle import library, load_vehicle
    for name in library():
        s = load_vehicle(name)
        for inertia, a, b in ((s.yaw_inertia, s.length, s.width), (s.roll_inertia, s.width, s.height),
                              (s.pitch_inertia, s.length, s.height)):
            assert 0.2 <= math.sqrt(inertia / s.mass) / math.hypot(a, b) <= 0.35, name
        for part in s.sections.get("multibody", {}).values():
            assert None not in part.values(), "a section is the file's table, not the schema's dump"
    clio = load_vehicle("clio").sections["multibody"]
    assert clio["chassis"]["mass"] == 940.0 and "semi_axes" not in clio["knuckle"]


def test_zero_friction_and_ints_accepted(make_scene):
    """Road and impact friction 0 (ice; an impact isolated from the road); an int is a number."""
    s = make_scene([{"speed": 50, "x": -3, "overrides": {"mass": 1200}}], road={"friction": 0},
                   impact={"friction": 0})
    v = s.vehicles[0]
    assert s.road.friction == 0.0 and s.impact.friction == 0.0
    assert v.speed == pytest.approx(kmh_to_ms(50.0)) and v.x == -3.0 and v.spec.mass == 1200.0
    assert isinstance(v.spec.mass, float)


@pytest.mark.parametrize("vehicle, key", [
    ({"x": 1e5 + 1}, "vehicles.V1.x"), ({"y": -1e5 - 1}, "vehicles.V1.y"),
    ({"heading": 3601.0}, "vehicles.V1.heading"), ({"yaw_rate": -721.0}, "vehicles.V1.yaw_rate"),
    ({"speed": 401.0}, "vehicles.V1.speed"), ({"steer": 46.0}, "vehicles.V1.steer"),
    ({"overrides": {"mass": 49.0}}, "vehicles.V1.overrides.mass"),
    ({"overrides": {"mass": 60001.0}}, "vehicles.V1.overrides.mass"),
    ({"overrides": {"length": 31.0}}, "vehicles.V1.overrides.length"),
    ({"overrides": {"cg_to_front_axle": 1.9}}, "vehicles.V1.overrides.cg_to_front_axle"),  # axle outside
    ({"overrides": {"multibody": {"chassis": {"shape_exponents": [1.0, 4.0]}}}},
     "vehicles.V1.overrides.multibody.chassis.shape_exponents.0"),
    ({"overrides": {"multibody": {"suspension": {"stiffness": "stiff"}}}},
     "vehicles.V1.overrides.multibody.suspension.stiffness"),
])
def test_documented_bounds(make_scene, vehicle, key):
    """Each bound of the Field descriptions, just outside it."""
    with pytest.raises(crashlab.InputError) as err:
        make_scene([vehicle])
    assert err.value.key == key


@pytest.mark.parametrize("kw, key", [({"duration": 121.0}, "duration"), ({"road": {"friction": 2.1}}, "road.friction"),
                                     ({"impact": {"friction": -0.1}}, "impact.friction"),
                                     ({"barriers": [{"x": 50.0, "y": 0.0, "length": 0.01, "width": 1.0}]},
                                      "barriers.0.length"),
                                     ({"impact": {"point": [2e5, 0.0], "plane_angle": 0.0}}, "impact.point.0")])
def test_documented_scene_bounds(make_scene, kw, key):
    with pytest.raises(crashlab.InputError) as err:
        make_scene([{}], **kw)
    assert err.value.key == key


def test_bounds_are_documented():
    """Every bounded number of the scene and vehicle schemas states its range in its description."""
    from crashlab.scene_file import BarrierFile, ImpactFile, RoadFile, SceneFile, VehicleEntryFile
    from crashlab.vehicle import VehicleFile
    for model in (SceneFile, RoadFile, ImpactFile, VehicleEntryFile, BarrierFile, VehicleFile):
        for name, field in model.model_fields.items():
            if any(hasattr(m, a) for m in field.metadata for a in ("gt", "ge", "lt", "le")):
                assert field.description, f"{model.__name__}.{name}"


@pytest.mark.parametrize("name, problem", [("", "at least 1 character"), ("V\n1", "no control characters"),
                                           ("x" * 65, "at most 64")])
def test_vehicle_names_label_tables(make_scene, name, problem):
    with pytest.raises(crashlab.InputError, match=problem) as err:
        make_scene([{"name": name}])
    assert err.value.key == "vehicles.0.name" and "\n" not in str(err.value)


def test_entry_points_are_read_once_per_process(monkeypatch):
    """crashlab.simulate used to re-read package metadata on every call (about 2 ms, four times an impulse
    simulation): the registry reads each group once, and refresh() forgets it."""
    from crashlab import registry
    calls = []
    real = registry.entry_points

    def counting(**kw):
        calls.append(kw)
        return real(**kw)

    monkeypatch.setattr(registry, "entry_points", counting)
    registry.refresh()
    for _ in range(3):
        registry.get_model("impulse")
    assert len(calls) == 1
    registry.refresh()
    registry.get_model("impulse")
    assert len(calls) == 2
