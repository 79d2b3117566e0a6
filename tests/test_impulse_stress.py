"""Numerical stability of the impulse model over a sweep of impact speeds and angles.

V2 stands still; V1 approaches its centre from angle `phi` (0 = from behind V2, 180 = head-on) at 5-150
km/h, wheels locked after the impact, road friction 0.8. Every run must end at rest within its duration
with finite numbers, every impulse must conserve momentum (1e-9) and dissipate energy, and the total
kinetic energy can only fall."""
import math

import numpy as np
import pytest

SPEEDS = [5.0, 20.0, 50.0, 100.0, 150.0]  # km/h
ANGLES = [0.0, 30.0, 60.0, 90.0, 120.0, 150.0, 180.0]  # deg


def _scene(make_scene, speed, phi, e=0.1, law="kudlich-slibar"):
    a = math.radians(phi)
    start = 6.0  # m from V2's CG, beyond both outlines
    return make_scene(
        vehicles=[{"x": -start * math.cos(a), "y": -start * math.sin(a) + 0.4, "heading": phi, "speed": speed,
                   "wheels": "locked_after_impact"},
                  {"x": 0.0, "y": 0.0, "heading": 0.0, "speed": 0.0, "wheels": "locked_after_impact"}],
        impact={"restitution": e, "friction": 0.3, "law": law}, duration=30.0)


@pytest.mark.parametrize("law", ["kudlich-slibar", "brach"])
def test_sweep_is_finite_conservative_and_ends_at_rest(make_scene, impulse_model, law):
    scenes = [_scene(make_scene, v, phi, law=law) for v in SPEEDS for phi in ANGLES]
    outs = impulse_model.simulate_batch(scenes)
    for sc, out in zip(scenes, outs):
        label = f"{sc.vehicles[0].speed * 3.6:.0f} km/h, heading {math.degrees(sc.vehicles[0].heading):.0f}"
        assert out.outcome_ok, f"{label}: {out.warnings}"
        assert np.all(np.isfinite(out.rest_si)), label
        assert len(out.impact_rows) >= 1, f"{label}: the cars collide"
        assert out.diagnostics["t_end"] < sc.duration, f"{label}: both cars come to rest"
        assert np.allclose(out.final_si, 0.0), label
        ke0 = out.diagnostics["kinetic_energy_start"]
        assert 0.0 <= out.diagnostics["energy_dissipated_impacts"] <= ke0 * (1 + 1e-12), label
        masses = {v.name: v.spec.mass for v in sc.vehicles}
        for t in {r["t"] for r in out.impact_rows}:
            rows = [r for r in out.impact_rows if r["t"] == t]
            px = sum(masses[r["vehicle"]] * r["dvx"] for r in rows)
            py = sum(masses[r["vehicle"]] * r["dvy"] for r in rows)
            scale = sum(masses[r["vehicle"]] * math.hypot(r["dvx"], r["dvy"]) for r in rows)
            assert math.hypot(px, py) <= 1e-9 * scale, f"{label}: momentum at t = {t}"
            assert rows[0]["energy"] >= -1e-9 * ke0, f"{label}: an impulse created energy"


def test_rest_poses_converge_with_the_step(make_scene):
    """Halving the fine step changes the rest poses of oblique impacts by less than 2 cm and 1 deg."""
    import crashlab
    scenes = [_scene(make_scene, v, phi) for v in (30.0, 80.0) for phi in (45.0, 135.0)]
    coarse = crashlab.get_model("impulse").simulate_batch(scenes)
    fine = crashlab.get_model("impulse", dt=0.001).simulate_batch(scenes)
    for c, f in zip(coarse, fine):
        assert np.max(np.hypot(*(c.rest_si[:, :2] - f.rest_si[:, :2]).T)) < 0.02
        assert np.max(np.abs(np.degrees(c.rest_si[:, 2] - f.rest_si[:, 2]))) < 1.0
