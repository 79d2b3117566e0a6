"""The vehicle library (framework/vehicles/): every file loads, its numbers relate plausibly, each number has a
source, estimates are marked and reproduce their formula, derived numbers reproduce from the measured ones,
and each vehicle collides and brakes by the laws with the impulse model.

* Classes: at least 20 vehicles covering small, compact, mid-size, large, SUV, pickup, van and heavy.
* Relations: wheelbase < length, track <= width, the CG between the axles (0 < a < wheelbase), CG height
  below the height.
* Yaw inertia band, against both estimate rules a file may use: 0.7-1.05 x the uniform box of the outline,
  m (L^2 + W^2) / 12 (the library's NHTSA LVIPD vehicles measure 0.76-0.97 x, the Clio 0.80, the m a b
  estimates 0.87, the bus's box estimate 1.0), and 0.7-1.6 x m a b (yaw dynamic index k^2 / (a b),
  Garrott et al. SAE 881767: the 204 LVIPD entries span 0.84-1.24, the Clio 0.74, the bus's box estimate
  1.55: its overhangs are long).
* Sources: every number at the top level and every table (e.g. [multibody]) has an entry in [sources];
  a number whose line comment says "estimate" has an entry starting with 'estimate:', and every such
  entry states its formula or basis (at least a number: the formula's constants or the range it takes
  the value from); an estimated yaw inertia equals the formula its entry names (m a b,
  or m (L^2 + W^2) / 12) within 1 %.
* LVIPD files: the measured numbers are labelled measured; the derived track (2 h SSF) and CG position
  (from the yaw dynamic index and the wheelbase) reproduce from the numbers their entries quote, within
  the rounding of those numbers (0.5 mm plus its first-order effect): an edited wheelbase without a new
  cg_to_front_axle fails here.
* Collision: each vehicle runs into the back of the saloon on one line through both CGs (rolling wheels, no
  rolling resistance): the impulse model's impact conserves momentum (m1 dv1 + m2 dv2 = 0) and gives the
  central-impact velocity changes dv2 = (1 + e) m1 / (m1 + m2) (v1 - v2), dv1 = -m2 / m1 dv2 (docs/physics.md
  §3), within 1e-6 relative; from the 880 kg Metro to the 18 t bus.
* Locked-wheel straight braking with the impulse model stops within 1 % of v^2 / (2 mu g)
  (docs/physics.md §2a; the same check as tests/test_pymunk_model.py for the Clio).
"""
from __future__ import annotations

import math
import re
import tomllib
from importlib import resources

import pytest

import crashlab
from crashlab.cli.vehicles import format_library_table, library_table
from crashlab.errors import InputError
from crashlab.scene_file import scene_from_dict
from crashlab.units import KMH, G
from crashlab.vehicle import METADATA_KEYS, VEHICLE_CLASSES, library, load_vehicle


def _text(ref):
    return resources.files("crashlab").joinpath("vehicles", ref + ".toml").read_text()


def _data(ref):
    return tomllib.loads(_text(ref))


VEHICLES = library()
# the files whose inertias are NHTSA LVIPD measurements
LVIPD = [r for r in VEHICLES if "Light Vehicle Inertial Parameter Database" in
         (_data(r).get("sources") or {}).get("yaw_inertia", "")]


def test_the_library_spans_the_classes():
    classes = {_data(r).get("class") for r in VEHICLES}
    assert len(VEHICLES) >= 20
    assert classes == set(VEHICLE_CLASSES), set(VEHICLE_CLASSES) - classes
    assert len(LVIPD) >= 15, "most vehicles carry measured inertias"


@pytest.mark.parametrize("ref", VEHICLES)
def test_vehicle_loads_and_relations_are_plausible(ref):
    v = load_vehicle(ref)
    assert v.wheelbase < v.length
    assert v.track <= v.width
    assert 0 < v.cg_to_front_axle < v.wheelbase
    assert 0 < v.cg_height < v.height
    box = v.mass * (v.length ** 2 + v.width ** 2) / 12
    assert 0.7 <= v.yaw_inertia / box <= 1.05, (ref, v.yaw_inertia / box)
    mab = v.mass * v.cg_to_front_axle * v.cg_to_rear_axle
    assert 0.7 <= v.yaw_inertia / mab <= 1.6, (ref, v.yaw_inertia / mab)
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


# `key = number  # comment` at the top level of a vehicle file (tables start at the first [header])
_LINE = re.compile(r"^(\w+)\s*=\s*[-+0-9.eE]+\s*#(.*)$")


@pytest.mark.parametrize("ref", VEHICLES)
def test_estimates_are_marked_with_their_formula(ref):
    src = _data(ref).get("sources") or {}
    top = _text(ref).split("\n[", 1)[0]
    for line in top.splitlines():
        m = _LINE.match(line.strip())
        if m and "estimate" in m.group(2).lower():
            assert src[m.group(1)].startswith("estimate:"), f"{ref}: {m.group(1)} is commented as an estimate"
    for key, text in src.items():
        if text.lower().startswith("estimate"):
            assert text.startswith("estimate:"), f"{ref}: [sources] {key} must start with 'estimate:'"
            assert re.search(r"\d", text), f"{ref}: the estimate of {key} states no formula or basis: {text!r}"


@pytest.mark.parametrize("ref", VEHICLES)
def test_an_estimated_yaw_inertia_is_its_formula(ref):
    text = (_data(ref).get("sources") or {}).get("yaw_inertia", "")
    if not text.startswith("estimate:"):
        pytest.skip("measured or published")
    v = load_vehicle(ref)
    if "I = m a b" in text:
        expected = v.mass * v.cg_to_front_axle * v.cg_to_rear_axle
    elif "I = m (L^2 + W^2) / 12" in text:
        expected = v.mass * (v.length ** 2 + v.width ** 2) / 12
    else:
        pytest.fail(f"{ref}: the estimated yaw inertia names no formula this test knows: {text!r}")
    assert v.yaw_inertia == pytest.approx(expected, rel=0.01)


@pytest.mark.parametrize("ref", LVIPD)
def test_lvipd_numbers_are_measured_and_the_derived_ones_reproduce(ref):
    data, v = _data(ref), load_vehicle(ref)
    src = data["sources"]
    for key in ("mass", "yaw_inertia", "roll_inertia", "pitch_inertia", "cg_height"):
        assert src[key].startswith("measured: NHTSA Light Vehicle Inertial Parameter Database"), (ref, key)
    h, ssf = map(float, re.search(r"2 h SSF = 2 x ([0-9.]+) m x ([0-9.]+)", src["track"]).groups())
    # the file rounds to 1 mm what its entry quotes to 0.1 mm (h) and 1e-4 (SSF)
    assert v.track == pytest.approx(2 * h * ssf, abs=5e-4 + 2 * 5e-5 * (h + ssf))
    assert v.cg_height == pytest.approx(h, abs=5.5e-4)
    di = float(re.search(r"DI = k\^2/\(a b\) = ([0-9.]+)", src["cg_to_front_axle"]).group(1))
    L, ab = v.wheelbase, v.yaw_inertia / v.mass / di
    root = math.sqrt(L * L / 4 - ab)
    # the quoted numbers are rounded (DI to 1e-4, L and a to 1 mm, I and m to 0.1): first-order spread of a
    da_dab, da_dL = 1 / (2 * root), 0.5 - L / (4 * root)
    tol = 5e-4 + abs(da_dL) * 5e-4 + abs(da_dab) * ab * (5e-5 / di + 0.05 / v.yaw_inertia + 0.05 / v.mass)
    assert v.cg_to_front_axle == pytest.approx(L / 2 - root, abs=tol)


@pytest.mark.parametrize("ref", VEHICLES)
def test_a_central_rear_end_impact_conserves_momentum(ref):
    e, v1, v2 = 0.1, 40.0, 10.0
    rolling = {"rolling_resistance": 0.0}
    gap = load_vehicle(ref).cg_to_front + 3.0 + load_vehicle("saloon").cg_to_rear  # 3 m between the bumpers
    scene = scene_from_dict({
        "duration": 1.0, "road": {"friction": 0.8}, "impact": {"restitution": e, "friction": 0.3},
        "vehicles": [{"name": "V1", "vehicle": ref, "speed": v1, "wheels": "rolling", "overrides": rolling},
                     {"name": "V2", "vehicle": "saloon", "speed": v2, "x": gap,
                      "wheels": "rolling", "overrides": rolling}]})
    out = crashlab.get_model("impulse").simulate(scene)
    assert out.outcome_ok
    imp = out.impacts
    assert len(imp) == 2, imp
    r1, r2 = imp.set_index("vehicle").loc["V1"], imp.set_index("vehicle").loc["V2"]
    m1, m2 = (s.spec.mass for s in scene.vehicles)
    assert abs(m1 * r1.dvx + m2 * r2.dvx) <= 1e-9 * m2 * r2.dvx
    assert abs(r1.dvy) + abs(r2.dvy) <= 1e-9 * r2.dvx
    dv2 = (1 + e) * m1 / (m1 + m2) * (v1 - v2)  # km/h, the impact table's unit
    assert r2.dvx == pytest.approx(dv2, rel=1e-6)
    assert r1.dvx == pytest.approx(-m2 / m1 * dv2, rel=1e-6)
    assert out.trajectories["V2"]["vx"][-1] == pytest.approx((v2 + dv2) * KMH, rel=1e-6)


@pytest.mark.slow  # the 3D models compile for a minute or two on first use
@pytest.mark.parametrize("model", ["impulse", "pymunk", "multibody", "exudyn"])
def test_every_model_runs_the_bus_into_a_car(model):
    """The heavy vehicle in every model: the 18 t bus at 40 km/h runs into the back of the saloon at 10 km/h
    (rolling wheels, no rolling resistance). The pair's momentum after the impact is the momentum before
    within 1 % (the 3D models' tyres act during their contact; measured about 0.1 %) and each speed is
    the central-impact value (docs/physics.md §3, e = 0.1) within 1.5 km/h (measured: impulse and pymunk
    exact; multibody and exudyn about 0.03 km/h off for the bus, 0.7 km/h for the car: the restitution
    of their contact force)."""
    e, v1, v2 = 0.1, 40.0, 10.0
    rolling = {"rolling_resistance": 0.0}
    gap = load_vehicle("citaro_bus").cg_to_front + 3.0 + load_vehicle("saloon").cg_to_rear
    scene = scene_from_dict({
        "duration": 1.5, "road": {"friction": 0.8}, "impact": {"restitution": e, "friction": 0.3},
        "vehicles": [{"name": "V1", "vehicle": "citaro_bus", "speed": v1, "wheels": "rolling", "overrides": rolling},
                     {"name": "V2", "vehicle": "saloon", "speed": v2, "x": gap, "wheels": "rolling",
                      "overrides": rolling}]})
    out = crashlab.get_model(model).simulate(scene)
    assert out.outcome_ok
    m1, m2 = (s.spec.mass for s in scene.vehicles)
    u1, u2 = (out.trajectories[n]["vx"][-1] / KMH for n in ("V1", "V2"))
    assert m1 * u1 + m2 * u2 == pytest.approx(m1 * v1 + m2 * v2, rel=0.01)
    dv2 = (1 + e) * m1 / (m1 + m2) * (v1 - v2)
    assert u2 == pytest.approx(v2 + dv2, abs=1.5)
    assert u1 == pytest.approx(v1 - m2 / m1 * dv2, abs=1.5)


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
    assert sorted(r["vehicle"] for r in rows) == sorted(VEHICLES)
    by = {r["vehicle"]: r for r in rows}
    clio = load_vehicle("clio")
    assert by["clio"]["mass"] == clio.mass and by["clio"]["yaw_inertia"] == clio.yaw_inertia
    assert by["saloon"]["yaw_inertia_kind"] == "estimate"
    assert by["citaro_bus"]["yaw_inertia_kind"] == "estimate"
    assert by["crv_1998"]["yaw_inertia_kind"] == "measured"
    assert {r["class"] for r in rows} == set(VEHICLE_CLASSES)
    front = by["clio"]["structure"]["front"]
    assert front["A"] == clio.structure["front"].A and front["kind"] == "estimate"
    text = format_library_table(rows)
    assert "[kg m^2]" in text and "A [kN/m]" in text and "B [kN/m^2]" in text
    # a vehicle without [structure.front] shows its class default, said so
    row = dict(by["clio"], structure=dict(by["clio"]["structure"], front=dict(front, kind="class default")))
    assert "class default" in format_library_table([row])
    assert all(r["vehicle"] in text for r in rows)


def test_a_bad_class_is_one_line_naming_the_key(tmp_path):
    f = tmp_path / "v.toml"
    data = (resources.files("crashlab").joinpath("vehicles", "clio.toml")).read_text()
    f.write_text(data.replace('class = "small"', 'class = "tank"'))
    with pytest.raises(InputError, match="class"):
        load_vehicle(str(f.name), base_dir=tmp_path)
