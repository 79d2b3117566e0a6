"""Physical laws, one test each, run over every model crashlab ships (issue 11, item 6).

Each law has a tolerance table below: model -> Tol(value, reason). A model of crashlab's own (entry point in
crashlab.models) registered without an entry fails the law's test until it is given one (or Tol(None,
reason) where the law does not apply). The tolerances are those of the per-model tests these tests
replaced; where a model needs a looser one than the others the reason says why. Only public APIs:
crashlab.get_model, load_scene, the Outcome's fields.
Laws: docs/physics.md §2 (braking, rolling), §3 (momentum, restitution), §13 (restitution of the
continuous-contact force law); case 1: studies/pc_crash/head_on.toml (PC-Crash, thesis Table 3.10).
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
import pytest
from conftest import PC_CRASH, REPO, build_scene

import crashlab
from crashlab import registry
from crashlab.outcome import REST_SPEED
from crashlab.units import G, kmh_to_ms, ms_to_kmh

# crashlab's own models (a third-party plugin installed beside crashlab, e.g. examples/plugin, is checked by its
# own tests with crashlab.testing.check_collision_model)
MODELS = sorted(n for n, origin in registry.origins("crashlab.models").items() if origin.startswith("crashlab.models"))

# column names of Outcome.rest_si (x, y, heading) and Outcome.final_si (vx, vy, yaw rate)
X, Y, HEADING = 0, 1, 2
VX, VY, YAW_RATE = 0, 1, 2
CONTACT_HEADING, CONTACT_SPEED = 2, 3  # Outcome.contact_si columns

MU = 0.8  # road friction of the single-car laws
SPEED = 50.0  # km/h, the single-car start speed
F_RR = (0.01, 0.015, 0.03)  # rolling-resistance coefficients of the deceleration law
RESTITUTION = (0.1, 0.4)  # restitution coefficients of the barrier law

RIGID_WALL = REPO / "studies" / "validation" / "rigid_wall.toml"  # Clio at 64 km/h into a rigid barrier
OBLIQUE = REPO / "studies" / "pymunk" / "oblique.toml"  # oblique, eccentric car-to-car impact
HEAD_ON = PC_CRASH / "head_on.toml"  # PC-Crash case 1


@dataclass(frozen=True)
class Tol:
    value: float | None  # None: the law does not apply to the model (the reason says why)
    why: str


@dataclass(frozen=True)
class Line:
    lateral: float  # m, largest sideways offset of the CG from the start line
    heading: float  # rad, largest heading change
    why: str


# ---------------------------------------------------------------- tolerance tables
BRAKING = {  # relative error of the locked-wheel distance v²/(2 mu g) and stopping time v/(mu g)
    "impulse": Tol(0.01, "planar Coulomb tyre, regularised only below 0.05 m/s"),
    "pymunk": Tol(0.01, "the impulse model's tyre forces"),
    "multibody": Tol(0.02, "3D: the wheel loads swing while the car dives (measured -0.13 %)"),
    "exudyn": Tol(0.02, "the penalty disc's friction is linear below 0.2 m/s (the last centimetres)"),
}
AT_REST = {  # m/s and rad/s, largest final velocity component of a car the run ended at rest
    "impulse": Tol(0.0, "rest detection sets the velocities to zero"),
    "pymunk": Tol(0.0, "rest detection sets the velocities to zero"),
    "multibody": Tol(REST_SPEED, "3D: sleeps below v_rest; the final state is the integrator's"),
    "exudyn": Tol(REST_SPEED, "3D: sleeps below v_rest; the final state is the integrator's"),
}
LINE = {  # a car braking or rolling straight ahead keeps its line
    "impulse": Line(1e-9, 1e-9, "symmetric planar tyre forces: round-off only"),
    "pymunk": Line(1e-9, 1e-9, "symmetric planar tyre forces: round-off only"),
    "multibody": Line(1e-3, 1e-4, "3D: symmetric car, adaptive integrator (measured 4e-9 m, 4e-9 rad)"),
    "exudyn": Line(0.01, math.radians(0.1), "3D: symmetric car; the tolerance of its per-model test"),
}
ROLLING = {  # relative speed change of a free-rolling car without rolling resistance (5 s)
    "impulse": Tol(1e-9, "no tyre force on a free-rolling wheel without slip"),
    "pymunk": Tol(1e-9, "no tyre force on a free-rolling wheel without slip"),
    "multibody": Tol(5e-3, "3D: suspension and tyre deflections settle in the first steps (measured 2e-7)"),
    "exudyn": Tol(1e-3, "3D: as multibody, generalized-alpha at 1 ms (measured 4e-7)"),
}
ROLLING_RESISTANCE = {  # relative error of the deceleration f_r g of a free-rolling car
    "impulse": Tol(0.02, "F_x = -f_r N tanh(v/v_reg): f_r g above v_reg"),
    "pymunk": Tol(0.02, "the impulse model's tyre forces"),
    "multibody": Tol(0.05, "the four wheels' spin inertia adds I/(R_e h) each to the mass: 2 % slower "
                           "(exact value with it: test_multibody_vehicle.py::test_rolling_resistance_deceleration)"),
    "exudyn": Tol(0.05, "the wheels' spin inertia adds I/(R_e h) each to the mass: 2 % slower"),
}
MOMENTUM = {  # |p_end - p_start| / |p_start| of two cars through an oblique impact on ice; and per impact
    "impulse": Tol(1e-9, "instantaneous impulses: momentum exact to round-off"),
    "pymunk": Tol(1e-3, "equal and opposite contact impulses; Chipmunk solver iterations"),
    "multibody": Tol(5e-3, "equal and opposite contact forces; the tolerance asked by issue 5"),
    "exudyn": Tol(1e-4, "equal and opposite contact loads at the step end"),
}
ANGULAR_MOMENTUM = {  # |L_end - L_start| about the origin / |L| about the centre of mass, same run
    "impulse": Tol(1e-3, "impulses conserve it exactly, but sustained contact's position projection (docs/"
                         "physics.md §5) moves the touching cars at unchanged velocities (measured 3.5e-4)"),
    "pymunk": Tol(5e-3, "Chipmunk's position correction moves the bodies at 0.25 ms steps"),
    "multibody": Tol(1e-3, "3D: the planar L uses the CG's yaw rate and the car's yaw inertia; "
                           "roll and pitch of the bodies are outside it (measured 1.4e-4)"),
    "exudyn": Tol(1e-2, "3D: as multibody; the tolerance of its per-model test (measured 8.7e-5)"),
}
BARRIER_E = {  # |e measured - e| with e measured = -v_n after / v_n before the impact with a rigid wall
    "impulse": Tol(1e-3, "Kudlich-Slibar impulse: e exact for a central impact"),
    "pymunk": Tol(1e-4, "the scene's restitution set on Chipmunk's arbiter"),
    "multibody": Tol(0.02, "continuous contact, exact-restitution force law; the road acts on the spinning "
                           "wheels during the 0.1 s contact (measured 2e-3 at e = 0.4)"),
    "exudyn": Tol(0.01, "continuous contact as multibody (measured 1.4e-3 at e = 0.4)"),
}
CASE1 = {  # relative error of the post-impact velocities and delta-V of PC-Crash case 1
    "impulse": Tol(4e-5, "the impulse law gives 50 (1 -/+ e) / 2 km/h exactly; no road force at f_r = 0"),
    "pymunk": Tol(0.03, "sequential-impulse contact over several 0.25 ms steps"),
    "multibody": Tol(0.03, "continuous contact over 0.1 s, the road acting on the wheels (measured 6e-6)"),
    "exudyn": Tol(0.01, "continuous contact as multibody; its test had 0.3 km/h (measured 4e-6)"),
}


def tolerance(table, model):
    """The model's entry of a law's table; skips the test where the law does not apply."""
    assert model in table, f"model {model!r} has no tolerance for this law: add one to the table"
    tol = table[model]
    if getattr(tol, "value", 0.0) is None:
        pytest.skip(tol.why)
    return tol


# ---------------------------------------------------------------- runs, shared by the tests of a law
_RUNS: dict = {}


def run(model: str, scene_key, build):
    """Outcome of `model` on the scene `build()` (cached per module: a scene serves several laws)."""
    key = (model, scene_key)
    if key not in _RUNS:
        scene = build()
        _RUNS[key] = scene, crashlab.get_model(model).simulate(scene)
    return _RUNS[key]


def single(speed, wheels, f_rr=0.0, duration=5.0):
    return build_scene([{"speed": speed, "wheels": wheels, "overrides": {"rolling_resistance": f_rr}}],
                       road={"friction": MU}, duration=duration)


def on_ice(path, duration):
    """A scene file with the road's friction 0: the road carries no horizontal load, only contacts act."""
    scene = crashlab.load_scene(path)
    return scene.replace(duration=duration, road=dataclasses.replace(scene.road, friction=0.0))


def start_velocity(v):
    return np.array([v.speed * math.cos(v.heading), v.speed * math.sin(v.heading)])


def rows_of(out, name):
    return [r for r in out.impact_rows if r["vehicle"] == name]


def assert_keeps_line(out, model):
    line = tolerance(LINE, model)
    tr = out.trajectories["V1"]
    assert np.max(np.abs(tr["y"] - tr["y"][0])) <= line.lateral
    assert np.max(np.abs(tr["heading"] - tr["heading"][0])) <= line.heading


# ---------------------------------------------------------------- single car on the road (§2)
@pytest.mark.parametrize("speed", [SPEED, 100.0])
@pytest.mark.parametrize("model", MODELS)
def test_locked_wheel_braking_distance_and_time(model, speed):
    """Locked wheels: the car slides v²/(2 mu g) in v/(mu g) on its line and comes to rest."""
    tol = tolerance(BRAKING, model).value
    scene, out = run(model, ("locked", speed), lambda: single(speed, "locked", duration=8.0))
    assert out.outcome_ok, out.warnings
    v = kmh_to_ms(speed)
    tr = out.trajectories["V1"]
    distance = out.rest_si[0, X] - tr["x"][0]
    assert distance == pytest.approx(v * v / (2 * MU * G), rel=tol)
    stop = tr["t"][np.argmax(np.hypot(tr["vx"], tr["vy"]) <= REST_SPEED)]
    assert stop == pytest.approx(v / (MU * G), rel=max(tol, 0.02))
    assert_keeps_line(out, model)
    assert out.diagnostics["t_end"] < scene.duration, "at rest: the run ended early"
    assert np.all(np.abs(out.final_si[0]) <= tolerance(AT_REST, model).value)


@pytest.mark.parametrize("model", MODELS)
def test_free_rolling_keeps_line_and_speed(model):
    """Free rolling without rolling resistance: speed and line kept over 5 s."""
    tol = tolerance(ROLLING, model).value
    _, out = run(model, ("rolling", 0.0), lambda: single(SPEED, "rolling"))
    assert out.outcome_ok, out.warnings
    tr = out.trajectories["V1"]
    v0 = kmh_to_ms(SPEED)
    assert tr["t"][-1] == pytest.approx(5.0)
    assert np.max(np.abs(np.hypot(tr["vx"], tr["vy"]) / v0 - 1.0)) <= tol
    assert (tr["x"][-1] - tr["x"][0]) / (v0 * tr["t"][-1]) == pytest.approx(1.0, abs=tol)
    assert_keeps_line(out, model)


@pytest.mark.parametrize("f_rr", F_RR)
@pytest.mark.parametrize("model", MODELS)
def test_rolling_resistance_deceleration(model, f_rr):
    """Free rolling with rolling resistance f_r: deceleration f_r g (fitted after the first 0.5 s)."""
    tol = tolerance(ROLLING_RESISTANCE, model).value
    _, out = run(model, ("rolling", f_rr), lambda: single(SPEED, "rolling", f_rr=f_rr, duration=3.0))
    tr = out.trajectories["V1"]
    sel = tr["t"] > 0.5
    decel = -np.polyfit(tr["t"][sel], np.hypot(tr["vx"], tr["vy"])[sel], 1)[0]
    assert decel == pytest.approx(f_rr * G, rel=tol)
    assert_keeps_line(out, model)


# ---------------------------------------------------------------- car to car with the road off (§3)
def oblique(model):
    """The oblique, eccentric impact on ice, 1 s (the contact is over): (scene, outcome, p0, p1, L0, L1,
    L0 about the system's centre of mass)."""
    scene, out = run(model, "oblique", lambda: on_ice(OBLIQUE, 1.0))
    assert out.outcome_ok, out.warnings
    assert len(out.impact_rows) >= 2, "the cars collide"
    p0, p1, l0, l1 = np.zeros(2), np.zeros(2), 0.0, 0.0
    for i, v in enumerate(scene.vehicles):
        m, vel = v.spec.mass, start_velocity(v)
        p0 += m * vel
        l0 += m * (v.x * vel[1] - v.y * vel[0]) + v.spec.yaw_inertia * v.yaw_rate
        end = out.final_si[i]
        p1 += m * end[[VX, VY]]
        l1 += m * (out.rest_si[i, X] * end[VY] - out.rest_si[i, Y] * end[VX]) + v.spec.yaw_inertia * end[YAW_RATE]
    mass = sum(v.spec.mass for v in scene.vehicles)
    cm = sum(v.spec.mass * np.array([v.x, v.y]) for v in scene.vehicles) / mass
    l0_cm = l0 - (cm[0] * p0[1] - cm[1] * p0[0])
    return scene, out, p0, p1, l0, l1, l0_cm


@pytest.mark.parametrize("model", MODELS)
def test_linear_momentum_conserved_through_an_impact(model):
    """Only the contact acts: the total linear momentum at the end is the one at the start, and in
    every car-to-car impact row pair m1 dv1 + m2 dv2 = 0 (relative to m1 |dv1|)."""
    tol = tolerance(MOMENTUM, model).value
    scene, out, p0, p1, *_ = oblique(model)
    assert np.linalg.norm(p1 - p0) <= tol * np.linalg.norm(p0)
    mass = {v.name: v.spec.mass for v in scene.vehicles}
    a, b = rows_of(out, "V1"), rows_of(out, "V2")
    assert len(a) == len(b) >= 1
    for ra, rb in zip(a, b):
        exchange = np.array([mass["V1"] * ra["dvx"] + mass["V2"] * rb["dvx"],
                             mass["V1"] * ra["dvy"] + mass["V2"] * rb["dvy"]])
        assert np.linalg.norm(exchange) <= tol * mass["V1"] * math.hypot(ra["dvx"], ra["dvy"])


@pytest.mark.parametrize("model", MODELS)
def test_angular_momentum_conserved_through_an_impact(model):
    """Same run: the angular momentum about the origin, sum m (x v_y - y v_x) + I_z r, is kept, relative
    to the angular momentum about the centre of mass (the strictest reference)."""
    tol = tolerance(ANGULAR_MOMENTUM, model).value
    _, out, _, _, l0, l1, l0_cm = oblique(model)
    assert abs(out.final_si[0, YAW_RATE]) > 0.1, "the eccentric impact turns the cars"
    assert abs(l1 - l0) <= tol * abs(l0_cm)


# ---------------------------------------------------------------- restitution (§3, §13)
@pytest.mark.parametrize("e", RESTITUTION)
@pytest.mark.parametrize("model", MODELS)
def test_restitution_against_a_barrier(model, e):
    """Head-on into a rigid wall at 64 km/h: one impact; the normal velocity after it is -e times the one
    before (before: the speed at first contact; after: plus the impact row's delta-V)."""
    tol = tolerance(BARRIER_E, model).value

    def scene():
        s = crashlab.load_scene(RIGID_WALL)
        return s.replace(impact=dataclasses.replace(s.impact, restitution=e))
    _, out = run(model, ("wall", e), scene)
    assert out.outcome_ok, out.warnings
    (row,) = rows_of(out, "V1")
    assert row["other"].startswith("barrier")
    before = out.contact_si[0, CONTACT_SPEED] * math.cos(out.contact_si[0, CONTACT_HEADING])
    after = before + row["dvx"]
    assert -after / before == pytest.approx(e, abs=tol)


SPEED_LAW_KMH = (15.0, 25.0)  # km/h into the rigid wall: both within the speed law's data (1-8 m/s)


def cipriani(v):
    """Cipriani et al. 2002 (SAE 2002-01-0540), v in m/s (docs/physics.md §13b), written out here."""
    lg = math.log10(v)
    return 0.47477 - 0.26139 * lg + 0.03382 * lg * lg - 0.11639 * lg ** 3


@pytest.mark.parametrize("kmh", SPEED_LAW_KMH)
@pytest.mark.parametrize("model", MODELS)
def test_speed_restitution_against_a_barrier(model, kmh):
    """restitution = "speed" (§13b): head-on into the rigid wall, the rebound / approach speed is the law's e at
    the closing speed (two speeds: two different restitutions), to the model's BARRIER_E tolerance."""
    tol = tolerance(BARRIER_E, model).value

    def scene():
        s = crashlab.load_scene(RIGID_WALL)
        v = s.vehicles[0]
        return s.replace(impact=dataclasses.replace(s.impact, restitution_law="speed"),
                         vehicles=(dataclasses.replace(v, speed=kmh_to_ms(kmh)),))
    _, out = run(model, ("wall-speed", kmh), scene)
    assert out.outcome_ok and not [w for w in out.warnings if "restitution" in w], out.warnings
    (row,) = rows_of(out, "V1")
    before = out.contact_si[0, CONTACT_SPEED] * math.cos(out.contact_si[0, CONTACT_HEADING])
    after = before + row["dvx"]
    assert -after / before == pytest.approx(cipriani(before), abs=tol)


# ---------------------------------------------------------------- PC-Crash case 1
@pytest.mark.parametrize("model", MODELS)
def test_case1_post_impact_speeds_match_pc_crash(model):
    """Head-on into a stopped car, e = 0.1: the velocities at the end of the run (free rolling, f_r = 0)
    are PC-Crash's (22.50 and 27.50 km/h), and so are the velocities right after the impact (at first
    contact plus the impact rows' delta-V)."""
    tol = tolerance(CASE1, model).value
    scene, out = run(model, "case1", lambda: crashlab.load_scene(HEAD_ON))
    assert out.outcome_ok, out.warnings
    for i, v in enumerate(scene.vehicles):
        ref = scene.references["pc_crash"][v.name]
        expected = kmh_to_ms(np.array([ref["vx"], ref["vy"]]))
        scale = np.linalg.norm(expected)
        assert np.all(np.abs(out.final_si[i, [VX, VY]] - expected) <= tol * scale), ms_to_kmh(out.final_si[i])
        dv = sum(np.array([r["dvx"], r["dvy"]]) for r in rows_of(out, v.name))
        assert np.all(np.abs(start_velocity(v) + dv - expected) <= tol * scale), ms_to_kmh(dv)
