"""Model `pymunk` (Chipmunk2D through pymunk): physics checks with stated tolerances.

* Case-1 post-impact speeds, momentum, angular momentum and barrier restitution: tests/test_laws.py
  (every model); here the case-1 impact rows and, with the ground forces off (`ground_forces=False`),
  the impact rows' momentum and energy, and the angular-momentum error against the step (slow).
* The pair's friction is exactly the scene's (not Chipmunk's product of per-shape values).
* The tyre forces are the impulse model's: a car braking with locked wheels stops within 1 % of
  v^2 / (2 mu g) and within 2 cm of the impulse model's rest position.
"""
from __future__ import annotations

import math
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest

import crashlab
from crashlab.options import OptionError
from crashlab.scene_file import load_scene, scene_from_dict
from crashlab.units import G

pytest.importorskip("pymunk")

PC_CRASH = Path(__file__).resolve().parent.parent / "studies" / "pc_crash"


def model(**options):
    return crashlab.get_model("pymunk", **options)


def oblique_scene(duration=0.5):
    """An oblique, eccentric car-to-car impact (studies/pymunk/oblique.toml)."""
    return crashlab.load_scene(PC_CRASH.parent / "pymunk" / "oblique.toml").replace(duration=duration)


def start_states(scene):
    return np.array([[v.x, v.y, v.heading, v.speed * math.cos(v.heading), v.speed * math.sin(v.heading),
                      v.yaw_rate] for v in scene.vehicles])


def momenta(scene, states):
    """Linear momentum (2,) and angular momentum about the origin of states (n, 6): x, y, psi, vx, vy, r."""
    p, L = np.zeros(2), 0.0
    for v, s in zip(scene.vehicles, states):
        m, iz = v.spec.mass, v.spec.yaw_inertia
        p += m * s[3:5]
        L += m * (s[0] * s[4] - s[1] * s[3]) + iz * s[5]
    return p, L


def momentum_errors(scene, **options):
    out = model(ground_forces=False, **options).simulate(scene)
    s0, s1 = start_states(scene), np.column_stack([out.rest_si, out.final_si])
    p0, L0 = momenta(scene, s0)
    p1, L1 = momenta(scene, s1)
    mass = sum(v.spec.mass for v in scene.vehicles)
    cm = sum(v.spec.mass * s0[i, 0:2] for i, v in enumerate(scene.vehicles)) / mass
    L0_cm = L0 - (cm[0] * p0[1] - cm[1] * p0[0])
    return np.linalg.norm(p1 - p0) / np.linalg.norm(p0), abs(L1 - L0) / abs(L0_cm), out


# ---------------------------------------------------------------- PC-Crash case 1
@pytest.fixture(scope="module")
def head_on():
    scene = load_scene(PC_CRASH / "head_on.toml")
    return scene, model().simulate(scene)


def test_case1_impact_rows(head_on):
    _, out = head_on
    imp = out.impacts
    assert len(imp) == 2 and set(imp.kind) == {"continuous"}
    v1, v2 = imp.set_index("vehicle").loc["V1"], imp.set_index("vehicle").loc["V2"]
    assert v1.dvx == pytest.approx(-27.5, rel=0.03) and v2.dvx == pytest.approx(27.5, rel=0.03)
    # energy dissipated: (1 - e^2) m1 m2 / (2 (m1 + m2)) v^2 for a central impact
    m, v = 980.0, 50 / 3.6
    assert v1.energy == pytest.approx((1 - 0.1 ** 2) * m / 4 * v ** 2, rel=0.01)
    # first contact: V1's bumper (1.8875 m ahead of its CG) meets V2's at x = 5 - 1.8875 m
    assert out.contact_si[0, 0] + 1.8875 == pytest.approx(5.0 - 1.8875, abs=0.01)
    assert out.contact_si[0, 3] == pytest.approx(v, rel=1e-6)


# ---------------------------------------------------------------- conservation with the road off
def test_impact_rows_exchange_momentum_and_account_for_the_energy():
    scene = oblique_scene()
    out = model(ground_forces=False).simulate(scene)
    imp = out.impacts
    first = imp[imp.t == imp.t.min()].set_index("vehicle")
    # equal masses: dv_1 + dv_2 = 0 (km/h); 1e-6 of the delta-V
    assert abs(first.dvx.sum()) < 1e-6 * first.delta_v.max()
    assert abs(first.dvy.sum()) < 1e-6 * first.delta_v.max()
    # every joule the cars lost went into the contacts (each impact listed once per vehicle row)
    s0, s1 = start_states(scene), np.column_stack([out.rest_si, out.final_si])
    ke = [sum(0.5 * v.spec.mass * (s[q, 3] ** 2 + s[q, 4] ** 2) + 0.5 * v.spec.yaw_inertia * s[q, 5] ** 2
              for q, v in enumerate(scene.vehicles)) for s in (s0, s1)]
    dissipated = imp.drop_duplicates(["t", "energy"]).energy.sum()
    assert dissipated == pytest.approx(ke[0] - ke[1], rel=1e-6)
    assert out.diagnostics["energy_dissipated_impacts"] == pytest.approx(ke[0] - ke[1], rel=1e-6)


# ---------------------------------------------------------------- coefficients set on the arbiter
def test_tangential_impulse_limited_by_the_scene_friction():
    """A glancing blow on a barrier, sliding all through the contact: |P_t| = mu P_n."""
    mu = 0.3
    scene = scene_from_dict({
        "duration": 0.5, "stop_at_rest": False, "impact": {"restitution": 0.0, "friction": mu},
        "vehicles": [{"name": "V1", "vehicle": "clio", "speed": 50.0, "heading": 10.0}],
        "barriers": [{"x": 0.0, "y": 1.5, "heading": 0.0, "length": 40.0, "width": 0.4}]})
    out = model(ground_forces=False).simulate(scene)
    rows = out.impacts
    dv_n = rows.dvy.sum()  # normal: -y (the barrier's face is along x)
    dv_t = rows.dvx.sum()
    assert dv_n < 0 and dv_t < 0
    # sliding friction: the tangential impulse is mu times the normal impulse (on the CG, both / m)
    assert abs(dv_t) == pytest.approx(mu * abs(dv_n), rel=0.02)


# ---------------------------------------------------------------- tyre forces shared with impulse
def test_locked_wheels_stop_in_the_coulomb_distance_and_agree_with_impulse():
    mu, v0 = 0.8, 50.0 / 3.6
    scene = scene_from_dict({
        "duration": 5.0, "road": {"friction": mu},
        "vehicles": [{"name": "V1", "vehicle": "clio", "speed": 50.0, "wheels": "locked",
                      "overrides": {"rolling_resistance": 0.0}}]})
    out = model().simulate(scene)
    ref = crashlab.get_model("impulse").simulate(scene)
    assert out.rest.at["V1", "x"] == pytest.approx(v0 ** 2 / (2 * mu * G), rel=0.01)
    assert abs(out.rest.at["V1", "x"] - ref.rest.at["V1", "x"]) < 0.02
    assert out.diagnostics["t_end"] < 5.0, "rest detection ends the run"
    assert out.warnings == ["no contact between the vehicles"]


def test_wheels_lock_at_the_first_contact():
    """Side collision (case 3, locked_after_impact): before contact the cars roll freely (f_rr = 0, so
    constant speed), after it they slide to rest in about the Coulomb time."""
    scene = load_scene(PC_CRASH / "side.toml")
    out = model().simulate(scene)
    assert out.outcome_ok
    tr = out.trajectory("V1")
    before = tr[tr.t < out.contact_time - 1e-9]
    assert np.allclose(np.hypot(before.vx, before.vy), 50.0, rtol=1e-9)
    # all at rest well before the 10 s run ends; a rolling car would still run at ~25 km/h
    assert out.diagnostics["t_end"] < 3.0
    assert np.all(out.final_si == 0.0)


# ---------------------------------------------------------------- interface
def test_conformance():
    from crashlab.testing import check_collision_model
    check_collision_model(model())


@pytest.mark.parametrize("bad", [{"dt": 0.0}, {"dt": "1e-3"}, {"iterations": 0}, {"iterations": 2.5},
                                 {"collision_slop": -1.0}, {"v_rest": 0.0}, {"ground_forces": "no"},
                                 {"record_dt": -0.1}, {"unknown": 1}])
def test_bad_options(bad):
    with pytest.raises(OptionError) as err:
        model(**bad)
    assert err.value.key == next(iter(bad))


def test_options_round_trip():
    m = model(dt=0.0005, iterations=30, ground_forces=False)
    assert m.get_options()["dt"] == 0.0005 and m.get_options()["ground_forces"] is False
    assert type(model(**m.get_options())).__name__ == "PymunkModel"


def test_listing_and_constructing_do_not_import_pymunk():
    code = ("import sys, crashlab; crashlab.available_models(); crashlab.get_model('pymunk'); "
            "assert 'pymunk' not in sys.modules, 'pymunk imported early'")
    subprocess.run([sys.executable, "-c", code], check=True)


# ---------------------------------------------------------------- step-size study
@pytest.mark.slow
def test_angular_momentum_error_against_step_size(capsys):
    """The table of the final report: the error shrinks with the step, below 0.5 % from 0.25 ms."""
    rows = []
    for dt in (2e-3, 1e-3, 5e-4, 2.5e-4, 1e-4):
        err_p, err_L, out = momentum_errors(oblique_scene(), dt=dt)
        rows.append((dt, err_p, err_L, out.diagnostics["max_penetration"]))
    with capsys.disabled():
        print("\ndt [s]     |dP|/|P0|   |dL|/|L0_cm|   max penetration [mm]")
        for dt, ep, el, pen in rows:
            print(f"{dt:<10g} {ep:<11.1e} {100 * el:8.3f} %     {1e3 * pen:8.2f}")
    assert all(r[1] < 1e-9 for r in rows)
    errs = [r[2] for r in rows]
    assert errs[0] > errs[2] > errs[4], "the error shrinks with the step"
    assert all(e < 5e-3 for dt, _, e, _ in rows if dt <= 2.5e-4)


# ---------------------------------------------------------------- overrides, stress (issue 10)
def test_mass_override_sets_the_delta_v_split():
    """The Clio overridden to 700 kg (inertias scaled) against the library SUV (1665 kg): the contact
    impulses are equal and opposite, so the delta-V ratio is the inverse mass ratio (10 % asked by the
    issue; 0.1 % here)."""
    from crashlab.vehicle import load_vehicle
    clio = load_vehicle("clio")
    f = 700.0 / clio.mass
    scene = scene_from_dict({
        "duration": 1.0, "stop_at_rest": False,
        "vehicles": [{"name": "V1", "vehicle": "clio", "speed": 50.0,
                      "overrides": {"mass": 700.0, "yaw_inertia": clio.yaw_inertia * f}},
                     {"name": "V2", "vehicle": "suv", "x": 6.0, "y": 0.3, "heading": 90.0}]})
    out = model().simulate(scene)
    assert out.outcome_ok, out.warnings
    dv = out.impacts.groupby("vehicle").delta_v.sum()
    assert dv["V1"] / dv["V2"] == pytest.approx(1665.0 / 700.0, rel=1e-3)


def _stress(scenes, check_moving):
    from test_impulse_stress import violations
    m = model(record_dt=0.01)
    return [(k, bad) for k, s in enumerate(scenes) if (bad := violations(s, m.simulate(s), check_moving))]


def test_stress_extremes_short():
    """Three extremes for 1.5 s (the crash, not the run-out): 200 km/h into a wall and head-on, a 700 kg
    car grazing a 3000 kg one at 2 deg. Nothing caught (overlap, energy, impact energy and momentum per
    impact, finite, ok)."""
    from test_impulse_stress import extreme_scenes
    scenes = [s.replace(duration=1.5) for s in extreme_scenes()[:4]]
    scenes = [scenes[0], scenes[2], scenes[3]]
    assert _stress(scenes, check_moving=False) == []


def push_scene(restitution=0.0, duration=10.0):
    """A free-rolling Clio of 1500 kg at 30 km/h into a locked one of 1000 kg standing 0.3 m ahead (no rolling
    resistance): the scene and the distance of their centres."""
    from crashlab.vehicle import load_vehicle
    spec = load_vehicle("clio")

    def ov(m):
        return {"mass": m, "yaw_inertia": spec.yaw_inertia * m / spec.mass, "rolling_resistance": 0.0}
    gap = spec.cg_to_front + spec.cg_to_rear + 0.3
    return scene_from_dict({
        "duration": duration, "road": {"friction": 0.8},
        "impact": {"restitution": restitution, "friction": 0.3},
        "vehicles": [{"name": "V1", "vehicle": "clio", "speed": 30.0, "overrides": ov(1500.0)},
                     {"name": "V2", "vehicle": "clio", "x": gap, "wheels": "locked", "overrides": ov(1000.0)}]}), gap


def test_sustained_push_matches_the_analytic_push():
    """A free-rolling car pushing a locked one (e = 0): the pair moves off at the common speed and slides
    v_c^2 / (2 mu g m2 / (m1 + m2)) together (as test_impulse_sustained_contact.py), within 1 %; the
    episode's contact interval spans the push and the run ends when both are at rest against each other."""
    scene, gap = push_scene()
    out = model().simulate(scene)
    assert out.outcome_ok, out.warnings
    vc, a = 1500.0 * 30.0 / 3.6 / 2500.0, 0.8 * G * 1000.0 / 2500.0
    assert out.rest_si[1, 0] - gap == pytest.approx(vc * vc / (2 * a), rel=0.01)
    (t0, t1), = out.contact_intervals
    assert t1 - t0 == pytest.approx(vc / a, rel=0.03)
    assert out.diagnostics["t_end"] < t1 + 0.5, "at rest against each other ends the run"


def test_a_push_after_push_time_is_a_push_row_with_the_analytic_split():
    """The shared episode rule (crashlab.outcome, docs/physics.md §15, §18): the push scene above gives one impact
    row per car, the contact up to PUSH_TIME after the touch, and one push row, the rest. Independent reference:
    after the plastic impact at the common speed v_c the locked car V2 is pushed at the pair's deceleration
    a = mu g m2 / (m1 + m2), so the contact force on it is m2 a + mu g m2 = mu g m1 m2 / (m1 + m2): its impact row
    carries v_c plus that force over PUSH_TIME, its push row that force over the rest of the contact (rows exclude
    the tyre forces, §18). Within 2 %. Before the rule pymunk gave one row of kind "continuous" for the whole 2 s."""
    from crashlab.outcome import PUSH, PUSH_TIME
    scene, gap = push_scene()
    out = model().simulate(scene)
    assert out.outcome_ok, out.warnings
    rows = sorted((r for r in out.impact_rows if r["vehicle"] == "V2"), key=lambda r: r["t"])
    assert [r["kind"] for r in rows] == ["continuous", PUSH]
    impact, push = rows
    assert push["t"] == pytest.approx(impact["t"] + PUSH_TIME, abs=2 * model().dt)
    (t0, t1), = out.contact_intervals
    vc = 1500.0 * 30.0 / 3.6 / 2500.0
    force_per_m2 = 0.8 * G * 1500.0 / 2500.0  # contact force on V2 over its mass
    assert math.hypot(impact["dvx"], impact["dvy"]) == pytest.approx(vc + force_per_m2 * PUSH_TIME, rel=0.02)
    assert math.hypot(push["dvx"], push["dvy"]) == pytest.approx(force_per_m2 * (t1 - push["t"]), rel=0.02)


def test_a_re_touch_after_the_pair_was_5_cm_apart_is_a_new_impact():
    """The push scene with e = 0.3: the struck car rebounds, the pair parts by more than 5 cm (measured here from
    the recorded positions: the gap between V1's front and V2's rear, the cars aligned) and V1 catches it up
    later than PUSH_TIME: a second impact row of kind "continuous", not the first one's push."""
    from crashlab.outcome import PUSH_TIME
    from crashlab.vehicle import load_vehicle
    spec = load_vehicle("clio")
    scene, _ = push_scene(restitution=0.3, duration=3.0)
    out = model().simulate(scene)
    assert out.outcome_ok, out.warnings
    rows = sorted((r for r in out.impact_rows if r["vehicle"] == "V2"), key=lambda r: r["t"])
    assert [r["kind"] for r in rows[:2]] == ["continuous", "continuous"]
    assert rows[1]["t"] - rows[0]["t"] > PUSH_TIME
    t1, t2 = rows[0]["t"] + rows[0]["duration"], rows[1]["t"]
    tr1, tr2 = out.trajectories["V1"], out.trajectories["V2"]
    between = (np.asarray(tr1["t"]) > t1) & (np.asarray(tr1["t"]) < t2)
    parted = (np.asarray(tr2["x"]) - spec.cg_to_rear) - (np.asarray(tr1["x"]) + spec.cg_to_front)
    assert between.any() and parted[between].max() > 0.05


def test_a_re_touch_within_5_cm_later_than_push_time_is_the_push():
    """RICSAC 10 with restitution "speed": the Civic's contact ends and closes again 0.3 s after the touch without
    the pair parting by 5 cm: that re-touch is the impact's push (a row of kind "push"), not part of the impact."""
    from crashlab.outcome import PUSH, PUSH_TIME
    data = tomllib.loads((Path(__file__).resolve().parents[1]
                          / "studies/validation/ricsac10_civic_torino_side.toml").read_text())
    data["impact"]["restitution"] = "speed"
    out = model().simulate(scene_from_dict(data))
    assert out.outcome_ok, out.warnings
    rows = sorted((r for r in out.impact_rows if r["vehicle"] == "V2"), key=lambda r: r["t"])
    kinds = [r["kind"] for r in rows]
    assert PUSH in kinds
    push = rows[kinds.index(PUSH)]
    assert push["t"] - rows[0]["t"] >= PUSH_TIME
    assert rows[0]["t"] + rows[0]["duration"] < push["t"]  # the contact had ended: a re-touch


def test_a_re_touch_before_the_pair_is_5_cm_apart_continues_its_episode():
    """RICSAC 10 (studies/validation): the Civic's front slides along the Torino's side, its contact breaking and
    closing again; the pair is never 5 cm apart until they part, so the collision is one episode, one row per car
    (before the shared rule, Chipmunk's begin .. separate: four rows within 0.17 s). Its delta-V then holds the
    whole momentum exchange: m1 dv1 = m2 dv2 (the contact impulse's, both cars' tyre parts taken out)."""
    scene = load_scene(Path(__file__).resolve().parents[1] / "studies/validation/ricsac10_civic_torino_side.toml")
    out = model().simulate(scene)
    assert out.outcome_ok, out.warnings
    rows = [r for r in out.impact_rows if r["other"] in ("V1", "V2")]
    assert len({r["t"] for r in rows}) == 1 and len(rows) == 2
    m = {v.name: v.spec.mass for v in scene.vehicles}
    p = [sum(m[r["vehicle"]] * r[ax] for r in rows) for ax in ("dvx", "dvy")]
    assert math.hypot(*p) < 1e-6 * max(m[r["vehicle"]] * math.hypot(r["dvx"], r["dvy"]) for r in rows)


@pytest.mark.slow
def test_stress_sweep_full():
    """100 seeded random scenes (tests/test_impulse_stress.py's space) and the 20 extremes, 10 s each:
    nothing caught. Vehicles still moving after 10 s are not judged (braking from 200 km/h at friction 0.3
    takes 19 s; with 60 s runs they stop, checked on the scenes that moved)."""
    from test_impulse_stress import extreme_scenes, stress_scenes
    scenes = [s.replace(duration=10.0) for s in stress_scenes(100, seed=1) + extreme_scenes()]
    caught = _stress(scenes, check_moving=False)
    print(f"\npymunk stress: {len(scenes)} runs, {len(caught)} caught")
    assert caught == []


# ---------------------------------------------------------------- a car pressed between two others
def sandwich_scene(restitution=0.5):
    """V1 at 50 km/h into V2, which stands against V3 (bumpers touching): V2 is pressed between the two."""
    from conftest import build_scene
    length = 2 * 1.8875  # the Clio's cg_to_front + cg_to_rear
    return build_scene([{"x": 0.0, "speed": 50.0}, {"x": length + 1.0}, {"x": 2 * length + 1.0}],
                       impact={"restitution": restitution, "friction": 0.3}, duration=1.0)


def test_a_sandwiched_car_is_no_energy_creating_impact():
    """Issue 27: the per-pair share of a car pressed between two others read "impact creates 31.5 kJ" while
    the total kinetic energy fell. Booked per contact island, every impact dissipates, the impacts account
    for the energy lost (road off), the kinetic energy never rises along the trajectories, and the guard
    passes the run."""
    scene = sandwich_scene()
    out = model(ground_forces=False).simulate(scene)
    assert out.outcome_ok, out.warnings
    ke0 = out.diagnostics.energy_start
    assert np.all(out.impact_energy >= -1e-6 * ke0), out.impact_energy
    assert out.impact_energy.sum() == pytest.approx(ke0 - out.diagnostics.energy_end, rel=1e-6)
    ke = sum(0.5 * v.spec.mass * (out.trajectories[v.name]["vx"] ** 2 + out.trajectories[v.name]["vy"] ** 2)
             + 0.5 * v.spec.yaw_inertia * out.trajectories[v.name]["yaw_rate"] ** 2 for v in scene.vehicles)
    assert np.all(np.diff(ke) <= 1e-6 * ke0)  # the system's kinetic energy: never up
    assert model().simulate(scene).outcome_ok  # with the road


def test_an_energy_creating_sandwich_still_fails(monkeypatch):
    """The same scene with the contacts' restitution forced to 1.6 (an engine that creates energy): the
    island's books show it and the guard fails the run."""
    from crashlab.models.pymunk.contacts import Contacts

    pre_solve = Contacts._pre_solve

    def bouncy(self, arb, space, data):
        pre_solve(self, arb, space, data)
        arb.restitution = 1.6

    monkeypatch.setattr(Contacts, "_pre_solve", bouncy)
    out = model(ground_forces=False).simulate(sandwich_scene())
    assert out.diagnostics.energy_end > out.diagnostics.energy_start
    assert not out.outcome_ok and "impact_energy" in out.violations
