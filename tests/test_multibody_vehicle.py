"""Physics of the 3D multibody vehicle (issue 4): static equilibrium, braking, rolling, cornering,
constraint drift, energy conservation, contact onset. Tolerances as stated in the issue."""
import math

import numpy as np
import pytest

import crashlab
from crashlab.models.common.vehicle_3d import NB, S_K, S_L0, S_P, S_Q
from crashlab.models.multibody import MultibodyModel
from crashlab.scene_file import scene_from_dict
from crashlab.units import G


def scene(speed=0.0, wheels="locked", mu=0.8, duration=5.0, steer=0.0, vehicle="clio", stop_at_rest=True,
          overrides=None):
    v = {"name": "V1", "vehicle": vehicle, "speed": speed, "wheels": wheels, "steer": steer}
    if overrides:
        v["overrides"] = overrides
    return scene_from_dict({"duration": duration, "stop_at_rest": stop_at_rest, "road": {"friction": mu},
                            "vehicles": [v]})


@pytest.fixture(scope="module")
def model():
    return MultibodyModel()


def test_registered():
    assert "multibody" in crashlab.available_models()
    assert isinstance(crashlab.get_model("multibody"), MultibodyModel)


@pytest.mark.parametrize("vehicle", ["clio", "saloon", "suv"])
def test_static_equilibrium(model, vehicle):
    sc = scene(0.0, "rolling", duration=1.0, vehicle=vehicle)
    prep = model.prepare(sc)
    out = model.run(sc, prep)
    fz = np.array(out.diagnostics["wheel_loads_static"]["V1"])
    veh = prep["vehicles"][0]
    m = veh.mass
    assert abs(fz.sum() / (m * G) - 1.0) < 1e-3
    # front/rear split from the CG position between the axles (all bodies' masses)
    y = prep["Y"][0]
    mass = veh.BODY[:, 0]
    r = np.array([y[7 * b:7 * b + 3] for b in range(NB)])
    cg = (mass[:, None] * r).sum(0) / m
    front = 0.5 * (r[5, 0] + r[6, 0])
    rear = 0.5 * (r[7, 0] + r[8, 0])
    share = (cg[0] - rear) / (front - rear)
    assert abs((fz[0] + fz[1]) / fz.sum() / share - 1.0) < 0.01
    # suspension deflection matches the spring rate: k (l0 - l) = load on the spring (vertical springs)
    m_u = mass[1] + mass[5]
    for k in range(4):
        S = veh.SPR[k]
        top = r[0] + S[S_P:S_P + 3]        # chassis level at static (roll, pitch ~ 0 at rest)
        bottom = r[1 + k] + S[S_Q:S_Q + 3]
        length = np.linalg.norm(top - bottom)
        spring_force = S[S_K] * (S[S_L0] - length)
        assert abs(spring_force / (fz[k] - m_u * G) - 1.0) < 0.01
    assert out.outcome_ok


@pytest.mark.parametrize("kmh", [50.0, 100.0])
def test_locked_wheel_braking_distance(model, kmh):
    out = model.simulate(scene(kmh, "locked", mu=0.8, duration=6.0))
    v = kmh / 3.6
    expected = v * v / (2 * 0.8 * G)
    assert abs(out.rest_si[0, 0] / expected - 1.0) < 0.02
    assert abs(out.rest_si[0, 1]) < 1e-3 and abs(out.rest_si[0, 2]) < 1e-4
    assert out.diagnostics["t_end"] < 6.0          # came to rest and the run ended early
    tr = out.trajectory("V1")
    assert {"z", "roll", "pitch"} <= set(tr.columns)
    assert tr["pitch"].max() > 0.5                 # dives nose-down (ISO pitch positive) while braking


def test_rolling_resistance_deceleration(model):
    sc = scene(50.0, "rolling", duration=5.0)
    prep = model.prepare(sc)
    out = model.run(sc, prep)
    veh = prep["vehicles"][0]
    tr = out.trajectory("V1")
    t, v = tr["t"].to_numpy(), tr["vx"].to_numpy() / 3.6
    sel = t > 1.0
    decel = -np.polyfit(t[sel], v[sel], 1)[0]
    # moment f_r F_z h on each wheel = resistance force f_r F_z; the wheels' spin inertia adds I/(R_e h)
    fr, m = veh.TYR[0, 9], veh.mass
    fz = np.array(out.diagnostics["wheel_loads_static"]["V1"])
    R = veh.TYR[0, 2] + veh.TYR[0, 3]
    h = R - fz.mean() / veh.TYR[0, 4]
    Re = R - (fz.mean() / veh.TYR[0, 4]) / 3.0
    expected = fr * G * m / (m + 4 * veh.BODY[5, 2] / (Re * h))
    assert decel == pytest.approx(expected, rel=0.02)


@pytest.mark.parametrize("steer_deg", [5.0, 10.0])
def test_low_speed_cornering_radius(model, steer_deg):
    out = model.simulate(scene(10.0, "rolling", duration=8.0, steer=steer_deg))
    tr = out.trajectory("V1")
    sel = tr["t"] > 4.0
    x, y = tr["x"][sel].to_numpy(), tr["y"][sel].to_numpy()
    A = np.c_[2 * x, 2 * y, np.ones_like(x)]
    c = np.linalg.lstsq(A, x * x + y * y, rcond=None)[0]
    radius = math.sqrt(c[2] + c[0] ** 2 + c[1] ** 2)
    spec = out.diagnostics  # noqa: F841
    L, b = 2.47, 2.47 - 1.24
    kinematic = math.hypot(L / math.tan(math.radians(steer_deg)), b)   # CG radius of the Ackermann geometry
    assert abs(radius / kinematic - 1.0) < 0.05


def test_constraint_drift_and_euler_norms(model):
    out = model.simulate(scene(30.0, "rolling", duration=10.0, steer=5.0, stop_at_rest=False))
    d = out.diagnostics
    assert d["t_end"] == pytest.approx(10.0)
    assert d["max_constraint_drift"] < 1e-6
    assert d["max_euler_norm_error"] < 1e-9


def test_energy_conserved_without_damping_and_friction():
    m = MultibodyModel(damping=False, friction=False)
    sc = scene(50.0, "rolling", duration=5.0, stop_at_rest=False)
    prep = m.prepare(sc)
    Y = prep["Y"]
    Y[0, [7 * b + 2 for b in range(NB)]] += 0.01          # drop 1 cm: the car bounces on springs and tyres
    out = m.run(sc, prep)
    d = out.diagnostics
    assert d["t_end"] == pytest.approx(5.0)
    assert d["work_nonconservative"][0] == 0.0
    e0, e1 = d["mechanical_energy_start"][0], d["mechanical_energy_end"][0]
    assert abs(e1 / e0 - 1.0) < 1e-3
    # and the motion was not trivial: the bounce exchanges energy between springs and motion
    assert np.ptp(out.trajectory("V1")["z"]) > 0.005


def test_contact_onset_located(model):
    """Issue 5 changed this contract: the run no longer stops at contact onset; the onset is located
    (first-contact control) and recorded as the first contact, and the run goes on."""
    sc = scene_from_dict({"duration": 3.0, "vehicles": [
        {"name": "A", "vehicle": "clio", "x": 0.0, "speed": 36.0, "wheels": "rolling"},
        {"name": "B", "vehicle": "clio", "x": 10.0, "heading": 180.0, "speed": 0.0, "wheels": "locked"}]})
    out = model.simulate(sc)
    assert out.outcome_ok
    gap = 10.0 - 2 * 1.8875
    assert out.contact_time == pytest.approx(gap / 10.0, rel=0.01)
    c = out.contact_si
    assert c[0, 0] + 1.8875 == pytest.approx(c[1, 0] - 1.8875, abs=2e-3)
    assert 0.0 < out.diagnostics["max_onset_penetration"] <= model.get_options()["onset_tol"]
    assert out.diagnostics["episodes"] >= 1


def test_braked_wheels_stop_near_friction_limit(model):
    out = model.simulate(scene(50.0, "braked", mu=0.8, duration=6.0))
    v = 50 / 3.6
    expected = v * v / (2 * 0.8 * G)
    assert 1.0 < out.rest_si[0, 0] / expected < 1.15
