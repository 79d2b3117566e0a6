"""The vehicle library (framework/vehicles/): every file loads, its numbers relate plausibly, each has a
source, and each vehicle brakes to rest in the Coulomb distance with the impulse model.

* Relations: wheelbase < length, track <= width, the CG between the axles (0 < a < wheelbase), CG height
  below the height, and the yaw inertia within 0.5-2 x m (L^2 + W^2) / 12 (a uniform box of the outline:
  road vehicles measure 0.8-1.0 x, NHTSA LVIPD entries of the library 0.82-0.93 x).
* Sources: every number at the top level and every table (e.g. [multibody]) has an entry in [sources];
  an estimated yaw inertia's entry starts with 'estimate:'.
* Locked-wheel straight braking with the impulse model stops within 1 % of v^2 / (2 mu g)
  (docs/physics.md §2a; the same check as tests/test_pymunk_model.py for the Clio).
"""
from __future__ import annotations

import tomllib
from importlib import resources

import pytest

import crashlab
from crashlab.errors import InputError
from crashlab.scene import scene_from_dict
from crashlab.units import G
from crashlab.vehicle import METADATA_KEYS, VEHICLE_CLASSES, format_library_table, library, library_table, load_vehicle

VEHICLES = library()


def _data(ref):
    with open(str(resources.files("crashlab").joinpath("vehicles", ref + ".toml")), "rb") as fh:
        return tomllib.load(fh)


def test_the_library_spans_the_classes():
    classes = {_data(r).get("class") for r in VEHICLES}
    assert len(VEHICLES) >= 10
    assert {"small", "compact", "mid-size", "SUV", "pickup", "van"} <= classes
    assert classes <= set(VEHICLE_CLASSES)


@pytest.mark.parametrize("ref", VEHICLES)
def test_vehicle_loads_and_relations_are_plausible(ref):
    v = load_vehicle(ref)
    assert v.wheelbase < v.length
    assert v.track <= v.width
    assert 0 < v.cg_to_front_axle < v.wheelbase
    assert 0 < v.cg_height < v.height
    box = v.mass * (v.length ** 2 + v.width ** 2) / 12
    assert 0.5 * box <= v.yaw_inertia <= 2.0 * box, (ref, v.yaw_inertia / box)
    assert "class" not in v.sections and "sources" not in v.sections  # metadata reaches no model


@pytest.mark.parametrize("ref", VEHICLES)
def test_every_number_has_a_source(ref):
    data = _data(ref)
    src = data.get("sources") or {}
    keys = [k for k, x in data.items() if k not in METADATA_KEYS and k != "name"
            and (isinstance(x, (int, float, dict)) and not isinstance(x, bool))]
    missing = [k for k in keys if not src.get(k, "").strip()]
    assert not missing, f"{ref}: no [sources] entry for {missing}"
    assert data.get("class") in VEHICLE_CLASSES


# one vehicle in the default run, every vehicle in the slow run (each run is several seconds)
@pytest.mark.parametrize("ref", [r if r == "metro_1998" else pytest.param(r, marks=pytest.mark.slow)
                                 for r in VEHICLES])
def test_locked_wheels_stop_in_the_coulomb_distance(ref):
    mu, v0 = 0.8, 50.0 / 3.6
    scene = scene_from_dict({
        "duration": 5.0, "road": {"friction": mu},
        "vehicles": [{"name": "V1", "vehicle": ref, "speed": 50.0, "wheels": "locked",
                      "overrides": {"rolling_resistance": 0.0}}]})
    out = crashlab.get_model("impulse").simulate(scene)
    assert out.rest.at["V1", "x"] == pytest.approx(v0 ** 2 / (2 * mu * G), rel=0.01)


def test_library_table_lists_every_vehicle_with_its_key_numbers():
    rows = library_table()
    assert sorted(r["file"] for r in rows) == sorted(VEHICLES)
    by = {r["file"]: r for r in rows}
    clio = load_vehicle("clio")
    assert by["clio"]["mass"] == clio.mass and by["clio"]["yaw_inertia"] == clio.yaw_inertia
    assert by["saloon"]["yaw_inertia_source"] == "estimate"
    assert by["crv_1998"]["yaw_inertia_source"] == "measured"
    text = format_library_table(rows)
    assert "mass [kg]" in text and "yaw inertia [kg m^2]" in text and len(text.splitlines()) == len(rows) + 1


def test_a_bad_class_is_one_line_naming_the_key(tmp_path):
    f = tmp_path / "v.toml"
    data = (resources.files("crashlab").joinpath("vehicles", "clio.toml")).read_text()
    f.write_text(data.replace('class = "small"', 'class = "tank"'))
    with pytest.raises(InputError, match="class"):
        load_vehicle(str(f.name), base_dir=tmp_path)
