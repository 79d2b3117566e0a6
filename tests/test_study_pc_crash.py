"""crashlab study pc_crash (comparison/pc_crash.py) on its quick configuration, impulse model only: a row per
(case, law, placement, vehicle) with every law of issue 23 in it; momentum holds in every run (the two
cars' delta-V in the inverse ratio of their masses and opposite, within 1e-9); case 1's delta-V is the
analytic (1 + e) v / 2 of a collinear impact of equal cars (PC-Crash's post speeds 22.50 / 27.50 km/h give
27.50 km/h); the distance to PC-Crash is read against the thesis's rest positions written here; an impact
whose slip stops and reverses reads slip_reversed True, one that sticks False."""
from __future__ import annotations

import csv
import itertools
import math

import pytest

from crashlab.comparison import pc_crash
from crashlab.scene_file import load_scene

LAWS = {"kudlich-slibar", "brach", "routh"}  # issue 23: every law side by side
# PC-Crash rest positions (thesis Tables 3.10, 3.12, 3.14): x, y [m]
PC_CRASH_REST = {("head_on", "V1"): (32.14, 0.0), ("head_on", "V2"): (42.24, 0.0),
                 ("offset", "V1"): (-2.66, 0.35), ("offset", "V2"): (7.66, -0.85),
                 ("side", "V1"): (6.66, 1.64), ("side", "V2"): (8.04, 5.97)}


@pytest.fixture(scope="module")
def rows(tmp_path_factory):
    out = tmp_path_factory.mktemp("pc_crash")
    path = pc_crash.run(["impulse"], out, quick=True)
    assert (out / "pc_crash.md").is_file()
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def test_a_row_per_case_law_placement_and_vehicle(rows):
    got = [(r["case"], r["law"], r["contact"], r["engagement_depth"], r["vehicle"]) for r in rows]
    want = [(c, law, contact, depth, v) for c, law, (contact, depth), v in itertools.product(
        ("head_on", "offset", "side"), LAWS, (("found", "nan"), ("engagement", "0.5")), ("V1", "V2"))]
    assert sorted(got) == sorted(want)
    assert all(r["ok"] == "True" and r["model"] == "impulse" for r in rows)
    for r in rows:
        x0, y0 = PC_CRASH_REST[(r["case"], r["vehicle"])]
        assert math.isclose(float(r["d_pc_crash_m"]), math.hypot(float(r["x"]) - x0, float(r["y"]) - y0),
                            abs_tol=1e-9)
        assert r["slip_reversed"] in ("True", "False") and int(r["impacts"]) >= 1


def test_momentum_and_the_collinear_delta_v(rows):
    runs = {}
    for r in rows:
        runs.setdefault((r["case"], r["law"], r["contact"]), {})[r["vehicle"]] = r
    for (case, law, contact), pair in runs.items():
        m1, m2 = (v.spec.mass for v in load_scene(pc_crash.PC_CRASH_DIR / f"{case}.toml").vehicles)
        a, b = pair["V1"], pair["V2"]
        for k in ("dvx", "dvy"):
            assert abs(m1 * float(a[k]) + m2 * float(b[k])) <= 1e-9 * m1 * float(a["delta_v"]), (case, law, contact)
    e, v = 0.1, 50.0  # case 1: V1 at 50 km/h into the standing V2, equal Clios, free rolling, no rolling resistance
    for law in LAWS:
        for veh in ("V1", "V2"):
            dv = float(runs[("head_on", law, "found")][veh]["delta_v"])
            assert math.isclose(dv, (1 + e) * v / 2, rel_tol=1e-3), (law, veh, dv)


def oblique_front_into_side(make_scene, law, mu):
    """Issue 23's oblique front-into-side impact (1500 / 1300 kg, restitution 0): sticking needs contact
    friction 0.50; at 0.45 the slip stops and reverses."""
    return make_scene(vehicles=[{"vehicle": "saloon", "x": -2.521, "y": 2.584, "heading": -75.0, "speed": 50.0,
                                 "overrides": {"mass": 1500.0, "yaw_inertia": 2846.5}},
                                {"speed": 15.0, "overrides": {"mass": 1300.0, "yaw_inertia": 1475.5}}],
                      impact={"restitution": 0.0, "friction": mu, "law": law, "point": [-1.1, 0.82],
                              "plane_angle": 0.0}, duration=3.0)


@pytest.mark.parametrize("law", sorted(LAWS))
def test_a_flagged_impact_is_read(make_scene, impulse_model, law):
    for mu, flagged in ((0.45, True), (0.6, False)):
        scene = oblique_front_into_side(make_scene, law, mu)
        out = impulse_model.simulate(scene)
        rs = pc_crash.outcome_rows("oblique", "impulse", {"law": law, "contact": "given", "depth": None}, scene, out)
        assert [r["vehicle"] for r in rs] == list(scene.vehicle_names)
        assert all(r["slip_reversed"] is flagged for r in rs), (law, mu, [r["kinds"] for r in rs])
        assert all(math.isnan(r["d_pc_crash_m"]) for r in rs)  # no PC-Crash reference in this scene
        if law == "routh":
            assert all(r["kinds"].split(";")[0] == ("reversed" if flagged else "full") for r in rs), rs
