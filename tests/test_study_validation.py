"""crashlab study validation on a tiny configuration: the impulse model on the NHTSA 10146 barrier test
and on the GBB UK car-to-car rear impact. Asserts the CSV contract and one physical fact each: the rebound
speed off a rigid barrier is restitution x impact speed (within 1 %); in the car-to-car impact the two
cars' delta-V are in the inverse ratio of their masses (momentum, docs/physics.md, within 1e-6) and
their sum is (1 + e) x the closing speed."""
from __future__ import annotations

import csv
import dataclasses
import math

from crashlab.comparison import validation
from crashlab.scene import approach_scene
from crashlab.scene_file import load_scene


def cipriani(v):
    """Cipriani et al. 2002 (SAE 2002-01-0540): restitution at the closing speed v [m/s]."""
    lg = math.log10(v)
    return 0.47477 - 0.26139 * lg + 0.03382 * lg * lg - 0.11639 * lg ** 3


def test_validation_csv_and_rebound(tmp_path):
    tests = [t for t in validation.load_tests() if t["id"] == "nhtsa10146"]
    path = validation.run(["impulse"], tmp_path, quick=True, tests=tests)
    with open(path, newline="") as fh:
        reader = csv.DictReader(fh)
        rows = list(reader)
    assert reader.fieldnames[:6] == ["model", "test", "quantity", "published", "simulated", "error"]
    assert {"unit", "source", "ok"} <= set(reader.fieldnames)
    assert (tmp_path / "validation.md").is_file()
    # the crush rows of the impulse model (no contact depth) are n/a: ok empty, neither pass nor fail
    assert rows and all(r["ok"] == ("" if r["quantity"] in validation.CRUSH_QUANTITIES else "True") for r in rows)
    rebound = {r["restitution"]: float(r["simulated"]) for r in rows
               if r["quantity"] == "rebound_speed" and r["law"] == "kudlich-slibar"}
    scene = load_scene(tests[0]["scene"])
    impact_speed = 57.09  # km/h; a little less at contact after 0.3 m of rolling, well within 1 %
    assert math.isclose(rebound["0.1"], scene.impact.restitution * impact_speed, rel_tol=0.01)
    # restitution = "speed": 57 km/h is above the law's data, its end value at 8 m/s (docs/physics.md §13b)
    assert math.isclose(rebound["speed"], cipriani(8.0) * impact_speed, rel_tol=0.01)
    for r in (r for r in rows if r["ok"] == "True"):
        assert math.isclose(float(r["error"]), float(r["simulated"]) - float(r["published"]), abs_tol=1e-9)


def test_validation_car_to_car_momentum(tmp_path):
    tests = [t for t in validation.load_tests() if t["id"] == "gbb_rear_5mph"]
    assert tests and tests[0]["kind"] == "crash test"
    path = validation.run(["impulse"], tmp_path, quick=True, tests=tests)
    rows = list(csv.DictReader(open(path, newline="")))
    assert {(r["quantity"], r["vehicle"]) for r in rows} == {("delta_v", "V1"), ("delta_v", "V2")}
    assert all(r["ok"] == "True" and r["kind"] == "crash test" for r in rows)
    dv_law = {r["vehicle"]: float(r["simulated"]) for r in rows
              if r["restitution"] == "speed" and r["law"] == "kudlich-slibar"}
    scene = load_scene(tests[0]["scene"])
    m1, m2 = (v.spec.mass for v in scene.vehicles)
    assert (m1, m2) == (950.0, 770.0)  # the published masses
    by_run = {}
    for r in rows:  # every law and contact (found, engagement)
        by_run.setdefault((r["law"], r["contact"], r["restitution"]), {})[r["vehicle"]] = float(r["simulated"])
    for dv in by_run.values():
        assert math.isclose(dv["V1"] / dv["V2"], m2 / m1, rel_tol=1e-6)
    rows = [r for r in rows if r["law"] == "kudlich-slibar" and r["contact"] == "found" and r["restitution"] == "0.1"]
    dv = {r["vehicle"]: float(r["simulated"]) for r in rows}
    # collinear, free cars: dv1 + dv2 = (1 + e) x closing speed; the bullet rolls 0.1 m to contact
    # (rolling resistance 0.01: under 0.2 % of speed lost), so within 0.5 %
    assert math.isclose(dv["V1"] + dv["V2"], (1 + scene.impact.restitution) * 8.851, rel_tol=0.005)
    # restitution = "speed": e of the closing speed 8.851 km/h (within the law's data, docs/physics.md §13b)
    assert math.isclose(dv_law["V1"] + dv_law["V2"], (1 + cipriani(8.851 / 3.6)) * 8.851, rel_tol=0.005)
    # the published delta-V (5.6 / 5.0 km/h) lie above: the test's restitution was higher than 0.1
    pub = {r["vehicle"]: float(r["published"]) for r in rows}
    assert all(dv[v] < pub[v] for v in dv)


def test_failed_model_is_recorded(tmp_path, monkeypatch):
    tests = [t for t in validation.load_tests() if t["id"] == "nhtsa10146"]

    def boom(model, scene):
        return None, "RuntimeError: boom"
    monkeypatch.setattr(validation, "_simulate", boom)
    path = validation.run(["impulse"], tmp_path, tests=tests)
    rows = list(csv.DictReader(open(path, newline="")))
    assert rows and all(r["ok"] == "False" and math.isnan(float(r["simulated"])) for r in rows)


# ---------------------------------------------------------------- the published car-to-car tests
# An independent transcription of the source tables (Rose et al. SAE 2006-01-0908 as quoted
# in pycrash test_inputs_rose.py; RICSAC as tabulated by Day SAE 2004-01-1207), in the published units.
MPH, LB, SLUG_FT2, INCH, FOOT = 1.609344, 0.45359237, 1.3558179, 0.0254, 0.3048
# vehicle: weight [lb], yaw inertia [slug ft^2], length, width, wheelbase, CG to front axle [in]
ROSE_VEHICLES = {("nhtsa4363", "V1"): (3451.1, 2152, 185.8, 70.1, 107.1, 45.88),
                 ("nhtsa4363", "V2"): (4695.4, 2805, 181.5, 67.7, 107.1, 53.55),
                 ("nhtsa4438", "V1"): (3305.7, 2066, 185.8, 70.1, 107.1, 44.7),
                 ("nhtsa4438", "V2"): (4725.3, 2889, 181.2, 66.2, 106.8, 52.2),
                 # 4364 and 4474: pycrash's entries marked "used in Rose paper" (projects/data/
                 # vehicle_data_collection.py), paired as pycrash's validation notebook pairs them
                 ("nhtsa4364", "V1"): (3451.1, 2152, 185.8, 70.1, 107.1, 45.88),   # 'HondaAccord'
                 ("nhtsa4364", "V2"): (5192.5, 3563, 191.7, 74.4, 113, 56.8),      # 'ChevyTrailblazer'
                 ("nhtsa4474", "V1"): (3305.7, 2066, 185.8, 70.1, 107.1, 44.7),    # 'HondaAccord4438'
                 ("nhtsa4474", "V2"): (4657, 2863, 178.3, 66.7, 107.3, 51.5)}      # 'MitsubishiMontero1999'
# test: per vehicle (d [ft], theta [deg], heading [deg], speed [mph]), normal [deg in V1's frame], Rose's e,
# measured delta-V V1, V2 [mph], measured |yaw-rate change| V1, V2 [deg/s]
ROSE_TESTS = {"nhtsa4363": ((2.6, 23.8, 180, 35.1), (5.7, 10.6, 32, 35.0), 55, 0.126, (39.5, 29.1), (31, 182)),
              "nhtsa4438": ((2.8, 35.3, 180, 34.7), (5.0, 13.2, 30, 35.0), 50.7, 0.095, (39.7, 27.8), (68, 166)),
              "nhtsa4364": ((2.3, 45.7, 180, 35.0), (7.1, 11.2, 30, 34.9), 51.9, 0.089, (40.1, 26.6), (108, 148)),
              "nhtsa4474": ((2.9, 34.7, 180, 35.0), (5.5, 15.2, 31.6, 35.0), 51.8, 0.150, (40.5, 28.7), (40, 194))}
# RICSAC: speeds [mph], measured delta-V [mph], estimated weights [lb]
RICSAC_TESTS = {"ricsac2": ((31.53, 31.53), (19.5, 25.8), (3982, 3010)),
                "ricsac3": ((21.23, 0.0), (9.4, 15.4), (4930, 3010)),
                "ricsac6": ((21.47, 21.47), (9.2, 14.6), (3982, 3982 * 9.2 / 14.6)),
                "ricsac10": ((31.35, 31.35), (28.7, 13.1), (4930 * 13.1 / 28.7, 4930))}
CAR_TO_CAR = ("nhtsa4363", "nhtsa4438", "nhtsa4364", "nhtsa4474", "ricsac2", "ricsac3", "ricsac6", "ricsac10")


def _tests(*ids):
    tests = {t["id"]: t for t in validation.load_tests()}
    return [tests[i] for i in ids]


def _published(test, quantity, vehicle):
    return next(q["published"] for q in test["quantity"] if q["name"] == quantity and q["vehicle"] == vehicle)


def test_car_to_car_scenes_and_published_numbers_match_the_source_tables():
    for t in _tests(*CAR_TO_CAR):
        scene = load_scene(t["scene"])
        assert t["kind"] == "crash test" and len(scene.vehicles) == 2
        if t["id"] in ROSE_TESTS:
            v1, v2, normal, _e, dv, dyaw = ROSE_TESTS[t["id"]]
            for k, (geo, name) in enumerate(((v1, "V1"), (v2, "V2"))):
                w, izz, length, width, wb, a = ROSE_VEHICLES[(t["id"], name)]
                v = scene.vehicles[k]
                s = v.spec
                assert math.isclose(s.mass, w * LB, abs_tol=0.01)
                assert math.isclose(s.yaw_inertia, izz * SLUG_FT2, abs_tol=0.1)
                for got, inch in ((s.length, length), (s.width, width), (s.wheelbase, wb), (s.cg_to_front_axle, a)):
                    assert math.isclose(got, inch * INCH, abs_tol=1e-4)
                d, theta, heading, speed = geo
                assert math.isclose(math.degrees(v.heading) % 360, heading, abs_tol=1e-9)
                assert math.isclose(v.speed * 3.6, speed * MPH, abs_tol=1e-3)
                # the point of impact lies at Rose's d and theta from this CG (vehicle frame, counter-clockwise)
                px, py = scene.impact.point
                rx, ry = px - v.x, py - v.y
                assert math.isclose(math.hypot(rx, ry), d * FOOT, abs_tol=1e-3)
                ang = math.degrees(math.atan2(ry, rx) - v.heading)
                assert math.isclose((ang - theta + 180) % 360 - 180, 0.0, abs_tol=0.01)
                assert math.isclose(_published(t, "impact_delta_v", name), dv[k] * MPH, abs_tol=1e-3)
                assert _published(t, "impact_yaw_rate_change", name) == dyaw[k]
            plane = math.degrees(scene.impact.plane_angle)
            assert math.isclose(plane, v1[2] + normal - 90, abs_tol=1e-9)
        else:
            speeds, dv, weights = RICSAC_TESTS[t["id"]]
            for k, name in enumerate(("V1", "V2")):
                v = scene.vehicles[k]
                assert math.isclose(v.spec.mass, weights[k] * LB, abs_tol=0.1)
                assert math.isclose(v.speed * 3.6, speeds[k] * MPH, abs_tol=1e-3)
                assert math.isclose(_published(t, "impact_delta_v", name), dv[k] * MPH, abs_tol=1e-3)


def _moved_to_contact(scene):
    """The scene's vehicles moved forward along their velocities until their outlines first touch (the inverse of
    approach_scene's gap): {name: (x, y, heading, vehicle)}."""
    from crashlab.scene import start_overlaps
    lo, hi = 0.0, 0.1
    moved = {}
    for _ in range(60):
        t = 0.5 * (lo + hi)
        moved = scene.replace(vehicles=tuple(dataclasses.replace(v, x=v.x + t * v.speed * math.cos(v.heading),
                                                                y=v.y + t * v.speed * math.sin(v.heading))
                                             for v in scene.vehicles))
        lo, hi = (lo, t) if start_overlaps(moved) else (t, hi)
    return {v.name: v for v in moved.vehicles}


def test_ricsac_6_and_10_touch_where_the_sources_figure_shows():
    """The collision positions read from Day's figure (studies/validation/README.md), checked by hand geometry
    at the moment the outlines touch: RICSAC 6, the Malibu's right front corner on the Rabbit's right side 0.7 m
    behind its front bumper; RICSAC 10, the Civic's front square on the Torino's right side, its centre 0.65 m
    behind the Torino's front bumper. Each within 2 cm (the scenes print 0.1 mm; the gap closes at 0.1 m)."""
    (r6,) = _tests("ricsac6")
    cars = _moved_to_contact(load_scene(r6["scene"]))
    malibu, rabbit = cars["V1"], cars["V2"]
    h = malibu.heading
    corner = (malibu.x + malibu.spec.cg_to_front * math.cos(h) + malibu.spec.width / 2 * math.sin(h),
              malibu.y + malibu.spec.cg_to_front * math.sin(h) - malibu.spec.width / 2 * math.cos(h))
    # in the Rabbit's frame (heading 0): its right side at y = -width / 2, its front bumper at x = cg_to_front
    cx, cy = corner[0] - rabbit.x, corner[1] - rabbit.y
    assert rabbit.heading == 0.0 and math.isclose(math.degrees(h), 120.0)
    assert abs(cy + rabbit.spec.width / 2) < 0.02
    assert abs(rabbit.spec.cg_to_front - cx - 0.7) < 0.02
    (r10,) = _tests("ricsac10")
    cars = _moved_to_contact(load_scene(r10["scene"]))
    civic, torino = cars["V1"], cars["V2"]
    front = (civic.x + civic.spec.cg_to_front * math.cos(civic.heading),
             civic.y + civic.spec.cg_to_front * math.sin(civic.heading))
    assert torino.heading == 0.0 and math.isclose(math.degrees(civic.heading), 90.0)
    assert abs(front[1] - torino.y + torino.spec.width / 2) < 0.02
    assert abs(torino.x + torino.spec.cg_to_front - front[0] - 0.65) < 0.02


def test_rose_geometry_reproduces_roses_own_analysis():
    """The transcription check of the collision position: with Rose's own fitted restitution, the Brach law
    and a sticking impact (Rose's impulse ratio 100 % of critical), the impulse at the scene's point of
    impact gives the measured delta-V (published to 0.1 mph) and yaw-rate changes (to 1 deg/s; the
    distances are given to 0.1 ft: 3 deg/s). Not the predictive run: e is Rose's fit. 4364 within 0.2 mph:
    its Accord comes out 39.93 mph against 40.1 (the Trailblazer 26.54 against 26.6; with these masses the
    momentum gives the Accord 1.505 times the Trailblazer's delta-V, the published pair 1.508), the inputs printed
    to 0.1 ft and 0.001 of e; 4363, 4438 and 4474 are within 0.1 mph. The vehicle pairing of 4364 and 4474 is
    pycrash's: this check is what says it is Rose's (4364 with 4363's Blazer mass and inertia instead of the
    Trailblazer's gives 38.19 / 28.07 mph and 97 / 164 deg/s: it fails)."""
    import dataclasses

    from crashlab.registry import get_model
    for t in _tests(*ROSE_TESTS):
        _v1, _v2, _n, e_rose, dv, dyaw = ROSE_TESTS[t["id"]]
        scene = validation.variant_scene(t["scene"], "brach", e_rose)
        scene = scene.replace(impact=dataclasses.replace(scene.impact, friction=5.0))
        out = get_model("impulse").simulate(scene)
        first = [r for r in out.impact_rows if r["t"] == 0.0]
        assert [r["vehicle"] for r in first] == ["V1", "V2"] and all(r["kind"] == "full" for r in first)
        for k, r in enumerate(first):
            tol = 0.2 if t["id"] == "nhtsa4364" else 0.1
            assert math.isclose(3.6 * math.hypot(r["dvx"], r["dvy"]), dv[k] * MPH, abs_tol=tol * MPH)
            assert math.isclose(abs(math.degrees(r["d_yaw_rate"])), dyaw[k], abs_tol=3.0)


def test_car_to_car_impulse_conserves_momentum_and_errors_are_recorded(tmp_path, record_property):
    """Every variant of the impulse model on the car-to-car tests: the first impact conserves linear
    momentum (m1 dv1 = -m2 dv2, docs/physics.md §3) and every row carries its error in %. The errors are
    recorded (junit properties and the CSV), not asserted: the study measures, it is not fitted."""
    tests = _tests(*CAR_TO_CAR)
    path = validation.run(["impulse"], tmp_path, tests=tests)
    rows = list(csv.DictReader(open(path, newline="")))
    runs = {(r["test"], r["law"], r["contact"], r["restitution"]) for r in rows}
    assert {law for _, law, _, _ in runs} == set(validation.IMPACT_LAWS)
    assert {(t, c) for t, _, c, _ in runs} == {(t, c) for t in CAR_TO_CAR for c in ("found", "engagement")} | {
        (t, "given") for t in ROSE_TESTS}
    assert all(r["ok"] == "True" for r in rows)
    for r in rows:
        pub, sim = float(r["published"]), float(r["simulated"])
        assert math.isclose(float(r["error_pct"]), 100 * (sim - pub) / pub, rel_tol=1e-9)
        if r["quantity"] == "impact_delta_v":
            record_property(f"{r['test']}/{r['law']}/{r['contact']}/{r['vehicle']} dV error %",
                            round(float(r["error_pct"]), 2))
    assert (tmp_path / validation.FIGURE).is_file()
    for t in tests:
        for law in validation.IMPACT_LAWS:
            found = approach_scene(validation.variant_scene(t["scene"], law))
            engaged = found.replace(impact=dataclasses.replace(found.impact, engagement=True))
            for scene in (validation.variant_scene(t["scene"], law), found, engaged):
                out = validation._simulate("impulse", scene)[0]
                first = sorted(out.impact_rows, key=lambda r: r["t"])[:2]
                assert {r["vehicle"] for r in first} == {"V1", "V2"}
                m = {v.name: v.spec.mass for v in scene.vehicles}
                for axis in ("dvx", "dvy"):
                    p = sum(m[r["vehicle"]] * r[axis] for r in first)
                    scale = max(m[r["vehicle"]] * abs(r[axis]) for r in first)
                    assert abs(p) <= 1e-9 * scale + 1e-12


def test_approach_scene_parts_the_cars_along_their_velocities():
    from crashlab.scene import start_overlaps
    for t in _tests(*ROSE_TESTS):
        given = load_scene(t["scene"])
        assert start_overlaps(given)  # the collision position: the outlines overlap by design
        app = approach_scene(given)
        assert app.impact.point is None and not start_overlaps(app)
        back = []
        for a, g in zip(app.vehicles, given.vehicles):
            dx, dy = g.x - a.x, g.y - a.y  # forward along the velocity by the same time for both
            back.append(math.hypot(dx, dy) / g.speed)
            assert math.isclose(dx * math.sin(g.heading) - dy * math.cos(g.heading), 0.0, abs_tol=1e-9)
            assert dx * math.cos(g.heading) + dy * math.sin(g.heading) > 0
        assert math.isclose(back[0], back[1], rel_tol=1e-9)
        # without the gap the outlines just touch: a little further forward they overlap
        nogap = approach_scene(given, gap=0.0)
        closer = approach_scene(given, gap=-0.01)
        assert not start_overlaps(nogap) and start_overlaps(closer)


def test_impact_laws_are_the_schemas():
    import typing

    from crashlab.scene_file import ImpactFile
    assert validation.IMPACT_LAWS == typing.get_args(ImpactFile.model_fields["law"].annotation)
    assert {"kudlich-slibar", "brach"} <= set(validation.IMPACT_LAWS)
    t = _tests("ricsac3")[0]
    assert len(validation.runs("impulse", t)) == 2 * len(validation.IMPACT_LAWS) * len(validation.RESTITUTION_VARIANTS)
    assert [r["law"] for r in validation.runs("multibody", t)] == ["-"] * len(validation.RESTITUTION_VARIANTS)


def test_every_law_and_the_engagement_point_are_run():
    """Issue 23 item 5: the impulse model runs every law (routh included) in every placement (given,
    found, engagement) on a test with a published point; the other models once, law "-"."""
    t = _tests("nhtsa4363")[0]
    runs = validation.runs("impulse", t)
    assert {(r["law"], r["contact"]) for r in runs} == {(law, c) for law in ("kudlich-slibar", "brach", "routh")
                                                        for c in ("given", "found", "engagement")}
    assert {(r["law"], r["contact"]) for r in validation.runs("pymunk", t)} == {("-", "found")}


def test_side_by_side_marks_a_flagged_run():
    """validation.md's per-law table: a column per (law, contact), "*" after an error whose run had an impact
    flagged slip_reversed, "fail" for a failed run."""
    base = {"model": "impulse", "test": "t", "quantity": "delta_v", "vehicle": "V1", "published": 10.0,
            "restitution": 0.1}
    rows = [{**base, "law": "brach", "contact": "found", "ok": True, "error_pct": -35.0, "slip_reversed": True},
            {**base, "law": "routh", "contact": "found", "ok": True, "error_pct": 2.0, "slip_reversed": False},
            {**base, "law": "routh", "contact": "engagement", "ok": False, "error_pct": math.nan,
             "slip_reversed": False}]
    lines = validation.side_by_side(rows)
    assert "| t | delta_v | V1 | 10.000 | -35.0* | 2.0 | fail |" in lines
    assert validation.side_by_side(rows[1:2]) == []  # one variant: no side-by-side table
    # columns that differ only in the restitution say which is which (they read "- found | - found" before)
    two = [{**base, "model": "multibody", "law": "-", "contact": "found", "ok": True, "error_pct": 1.0,
            "slip_reversed": False, "restitution": e} for e in (0.1, "speed")]
    head = next(line for line in validation.side_by_side(two) if line.startswith("| test"))
    assert "| - found e 0.1 | - found e speed |" in head
