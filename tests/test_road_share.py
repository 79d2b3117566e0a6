"""The 3D models' warning of an impact row whose delta-V the road forces of a long contact moved away from its
contact impulse (models/common/contact_report.road_share_warnings, docs/physics.md §15 "Road forces in a row").

Reference written here: a car struck from behind while standing on locked wheels slides on them through the whole
contact, so the road takes mu m g T of its momentum over the contact's T (Coulomb): its row's delta-V (its CG's
velocity change) lies mu g T from its contact impulse over its mass, while the striking car, rolling free, keeps
its contact impulse's."""
import math
import re
import sys
from pathlib import Path

import pytest

from crashlab.models.common.contact_report import ROAD_SHARE
from crashlab.outcome import collision_rows
from crashlab.units import G

sys.path.insert(0, str(Path(__file__).parent))
from conftest import build_scene  # noqa: E402


@pytest.mark.parametrize("model", ["multibody", "exudyn"])
def test_a_car_struck_on_locked_wheels_loses_mu_g_t_to_the_road_and_is_said(model):
    """A saloon rolling at 10 km/h into the rear of a standing Clio on locked wheels (e = 0.1, mu = 0.8): the Clio's
    impact row lies mu g T from its contact impulse (within 5 %; measured 0.4 % in multibody, 2.5 % in exudyn: its
    row 3.4 km/h, its contact impulse 11.5 km/h over the 0.29 s contact) and is said, with both numbers; the
    saloon's, rolling free, lies within ROAD_SHARE of its impulse and is not."""
    if model == "exudyn":
        pytest.importorskip("exudyn")
    from crashlab.registry import get_model
    from crashlab.vehicle import load_vehicle

    saloon, clio = load_vehicle("saloon"), load_vehicle("clio")
    mu = 0.8
    sc = build_scene([{"vehicle": "saloon", "speed": 10.0},
                      {"vehicle": "clio", "x": saloon.cg_to_front + clio.cg_to_rear + 0.05, "wheels": "locked"}],
                     impact={"restitution": 0.1, "friction": 0.3}, road={"friction": mu}, duration=3.0)
    out = get_model(model).simulate(sc)
    assert out.outcome_ok, out.warnings
    mass = {v.name: v.spec.mass for v in sc.vehicles}
    rows = {r["vehicle"]: r for r in collision_rows(out.impact_rows)}
    contact = {n: math.hypot(r["impulse_x"], r["impulse_y"]) / mass[n] for n, r in rows.items()}
    apart = {n: math.hypot(r["dvx"] - r["impulse_x"] / mass[n], r["dvy"] - r["impulse_y"] / mass[n])
             for n, r in rows.items()}
    assert apart["V2"] == pytest.approx(mu * G * rows["V2"]["duration"], rel=0.05)
    assert apart["V2"] > ROAD_SHARE * contact["V2"] and apart["V1"] < ROAD_SHARE * contact["V1"]
    said = [w for w in out.warnings if "road forces included" in w]
    assert len(said) == 1 and said[0].startswith("V2's delta-V in its impact with V1"), out.warnings
    v2 = rows["V2"]
    assert [float(x) for x in re.findall(r"(\d+\.\d) km/h", said[0])] == \
        pytest.approx([3.6 * math.hypot(v2["dvx"], v2["dvy"]), 3.6 * contact["V2"]], abs=0.051)
