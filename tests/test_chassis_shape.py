"""The chassis contact bodies of the 3D models (models/common/vehicle_3d.py, chassis_shape; docs/physics.md §10,
"Chassis bodies"): how high each vehicle's body reaches decides whether a car passes under another vehicle.

* A car's body is the rule it always had, written here: a = length/2 centred between the bumpers, b = width/2,
  c = 0.25 m x height/1.42, 2/eps = 4, centred at the chassis CG (the Clio: its [multibody.chassis] table).
* The 18 t bus reaches down to its published lowest body height (Daimler, Citaro: step height at door 1,
  320 mm; floor 370 mm above the road) at rest: every car of the library overlaps it in height. Before, its
  body spanned 0.61-1.69 m and the Clio's (0.08-0.58 m) ran under it (audit seed 28, tests/test_guard_audit.py).
* Without a structure_bottom a default body reaches down to at most 0.45 m (UN R58 rear underrun protection).
* A Clio driven at 50 km/h into the side of the stationary bus (multibody, road friction 0: the impact isolated)
  hits it: momentum m1 dv1 = m2 dv2 and the central-impact velocity changes of docs/physics.md §3 within 2 %,
  and the Clio ends outside the bus's plan. With the old body it drove under the bus without an impact.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from crashlab.errors import InputError
from crashlab.vehicle import library, load_vehicle

BUS = "citaro_bus"
BUS_BOTTOM = 0.320  # m: Daimler, 'The Citaro: Technical Information' (628.083), step height door 1


def _build(ref, overrides=None):
    from crashlab.models.common.vehicle_3d import build
    return build(load_vehicle(ref, overrides=overrides))


def _z_range(veh, z_cg):
    """(bottom, top) of the upright contact body with its chassis CG at height z_cg."""
    c, zo = veh.chassis_shape[2], veh.chassis_shape[6]
    return z_cg + zo - c, z_cg + zo + c


@pytest.mark.parametrize("ref", [r for r in library() if r != BUS])
def test_a_cars_body_is_the_rule_it_always_had(ref):
    """Bit for bit: the validation study and the tutorial see the same cars."""
    spec = load_vehicle(ref)
    ch = (spec.sections.get("multibody") or {}).get("chassis") or {}
    if "semi_axes" in ch:
        a, b, c = ch["semi_axes"]
        xo = 0.0
    else:
        a, b, c = spec.length / 2, spec.width / 2, 0.25 * spec.height / 1.42
        xo = (spec.cg_to_front - spec.cg_to_rear) / 2
    assert _build(ref).chassis_shape.tolist() == [a, b, c, 0.5, 0.5, xo, 0.0]


def test_the_bus_reaches_down_to_its_skirt_at_rest():
    """The settled bus's body bottom lies at its published 320 mm (within its settling, 2 cm); its top where it
    was; every library car's settled body overlaps the bus's in height by at least 0.25 m."""
    from crashlab.models.multibody import MultibodyModel
    m = MultibodyModel(settle_time=0.5)
    bus = _build(BUS)
    spec = load_vehicle(BUS)
    lo, hi = _z_range(bus, m.settled(bus)[2])
    assert lo == pytest.approx(BUS_BOTTOM, abs=0.02)
    assert hi == pytest.approx(spec.cg_height + 0.25 * spec.height / 1.42, abs=0.02)
    for ref in ("clio", "tercel_1998", "saloon", "club_wagon_1998"):
        car = _build(ref)
        c_lo, c_hi = _z_range(car, m.settled(car)[2])
        assert min(hi, c_hi) - max(lo, c_lo) > 0.25, (ref, (c_lo, c_hi), (lo, hi))


def test_a_default_body_reaches_down_to_the_underrun_limit():
    """The bus without its structure_bottom: its default body (0.61-1.70 m at the CG estimate) is extended down
    to 0.45 m, its top kept."""
    from crashlab.models.common import vehicle_3d as V
    spec = load_vehicle(BUS)
    spec.sections["multibody"]["chassis"].pop("structure_bottom")
    veh = V.build(spec)
    lo, hi = _z_range(veh, veh.z_chassis0)
    assert lo == pytest.approx(0.45, abs=1e-12)
    assert hi == pytest.approx(spec.cg_height + 0.25 * spec.height / 1.42, abs=1e-12)
    assert any("extended down to 0.45 m" in n for n in veh.notes)


@pytest.mark.parametrize("value", [1.8, 0.0])
def test_a_bottom_above_the_body_is_refused(value):
    """Above the body's top (1.70 m) or at the road: bad input naming the scene's vehicle and the key."""
    from crashlab.models.common.vehicle_3d import build_scene_vehicles
    from crashlab.scene_file import scene_from_dict
    with pytest.raises(InputError) as err:
        sc = scene_from_dict({"vehicles": [{"name": "V1", "vehicle": BUS, "overrides": {
            "multibody": {"chassis": {"structure_bottom": value}}}}]})
        build_scene_vehicles(sc)
    assert "V1" in str(err.value) and "structure_bottom" in str(err.value)


def test_a_clio_into_the_bus_side_hits_it():
    """The Clio at 50 km/h into the side of the stationary bus, square, at its CG; road friction 0, restitution
    0.1. Central impact (docs/physics.md §3): dv_bus = (1 + e) m1 / (m1 + m2) v, dv_clio = m2 / m1 dv_bus, within
    2 %; the Clio ends outside the bus's plan (its front behind the bus's side + the crush the pair can keep,
    from Campbell's side line: 2 (v - 0.9) / 20.3 m = 1.28 m). Before, the Clio drove under the bus: no impact."""
    import crashlab
    from crashlab.scene_file import scene_from_dict
    bus, clio = load_vehicle(BUS), load_vehicle("clio")
    v = 50.0 / 3.6
    y0 = -(bus.width / 2 + clio.cg_to_front + 0.3)
    sc = scene_from_dict({"duration": 0.6, "stop_at_rest": False, "road": {"friction": 0.0},
                          "impact": {"restitution": 0.1, "friction": 0.3, "force_law": "exact-restitution"},
                          "vehicles": [
                              {"name": "C", "vehicle": "clio", "y": y0, "heading": 90.0, "speed": 50.0,
                               "wheels": "rolling"},
                              {"name": "B", "vehicle": BUS, "wheels": "rolling"}]})
    out = crashlab.get_model("multibody").simulate(sc)
    rows = {r["vehicle"]: r for r in out.impact_rows}
    assert set(rows) == {"C", "B"}, out.impact_rows
    dv_c, dv_b = math.hypot(rows["C"]["dvx"], rows["C"]["dvy"]), math.hypot(rows["B"]["dvx"], rows["B"]["dvy"])
    m1, m2 = clio.mass, bus.mass
    assert dv_b == pytest.approx(1.1 * m1 / (m1 + m2) * v, rel=0.02)
    assert m1 * dv_c == pytest.approx(m2 * dv_b, rel=0.02)
    tc, tb = out.trajectories["C"], out.trajectories["B"]
    front = tc["y"][-1] + clio.cg_to_front       # heading 90 deg: the Clio's front along +y
    side = tb["y"][-1] - bus.width / 2
    assert front - side < 2 * (v - 0.9) / 20.3, (front, side)
    assert np.all(np.isfinite(out.final_si))
