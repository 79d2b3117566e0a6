"""The impulse model's re-impacts (docs/physics.md §5, §15 "Re-impacts"): a follow-up contact impulse closing at
crashlab.outcome.REIMPACT_SPEED or faster in a push, or later than PUSH_TIME after its impact, opens a row of its
own, as the 3D models' re-touches do; after the run a re-impact's row whose impulse exchanges less than
REIMPACT_SPEED of the pair's relative velocity is a push's. Before, every such impulse was booked into the push row.

References written here: the pair's reduced mass m1 m2 / (m1 + m2) (a barrier's pair: the vehicle's mass) times
REIMPACT_SPEED as the least impulse of a re-impact's row; momentum m1 dv1 + m2 dv2 = 0 of each row."""
import math
import sys
from pathlib import Path

import numpy as np

import crashlab
from crashlab.models.common.planar_vehicle import P_MASS
from crashlab.models.impulse import layout as L
from crashlab.models.impulse.impacts import _settle_reimpacts
from crashlab.outcome import PUSH_TIME, REIMPACT_SPEED, collision_rows

sys.path.insert(0, str(Path(__file__).parent))
from conftest import build_scene  # noqa: E402


def _records(rows):
    """Impact records: (i, j, |J| along the row's normal, re-impact flag, kind) each."""
    imp = np.zeros((len(rows), L.N_IMP))
    for n, (i, j, pn, flag, kind) in enumerate(rows):
        imp[n, L.I_I], imp[n, L.I_J], imp[n, L.I_PN], imp[n, L.I_REIMPACT], imp[n, L.I_KIND] = i, j, pn, flag, kind
    return imp


def test_a_reimpact_that_exchanges_little_is_a_push():
    """Masses 1000 and 3000 kg (reduced mass 750 kg) and a barrier: a re-impact's row of 900 N s (1.2 m/s of the
    pair's relative velocity) stays an impact, one of 700 N s (0.93 m/s) is a push's; against the barrier the
    vehicle's 1000 kg decide (900 N s: a push's); a row not flagged keeps its kind whatever its impulse."""
    P = np.zeros((2, 13))
    P[0, P_MASS], P[1, P_MASS] = 1000.0, 3000.0
    sliding = 1.0
    imp = _records([(0, 1, 900.0, 1.0, sliding), (0, 1, 700.0, 1.0, sliding), (0, 2, 900.0, 1.0, sliding),
                    (0, 1, 10.0, 0.0, sliding)])
    _settle_reimpacts(P, imp, len(imp), 2)
    assert list(imp[:, L.I_KIND]) == [sliding, L.PUSH, L.PUSH, sliding]
    assert 750.0 * REIMPACT_SPEED < 900.0 < 1000.0 * REIMPACT_SPEED


def test_a_hard_contact_in_a_push_is_a_reimpact_row():
    """A scene of the 2026-11-28 probe: two saloons at 31.6 and 33.5 km/h, 38 deg apart, the second on locked
    wheels, 0.49 m off. Their rigid outlines stay within 5 cm after the impact; 0.6 s after it, in the push, the
    pair closes again at more than REIMPACT_SPEED: an impact row of its own (before: part of a 28.2 km/h push
    row), whose impulse exchanges more than REIMPACT_SPEED of the pair's relative velocity, each row balancing
    momentum; the trajectory is the same as before (the follow-ups stay plastic)."""
    th, T, v1, v2 = math.radians(37.99), 0.25, 31.58 / 3.6, 33.54 / 3.6
    from crashlab.vehicle import load_vehicle
    saloon = load_vehicle("saloon")
    d = saloon.cg_to_front + max(saloon.cg_to_front, saloon.cg_to_rear) + 0.4
    scene = build_scene([{"vehicle": "saloon", "speed": 31.58, "x": -v1 * T},
                         {"vehicle": "saloon", "speed": 33.54, "heading": 37.99, "wheels": "locked",
                          "x": d - v2 * T * math.cos(th), "y": -0.4887 - v2 * T * math.sin(th)}],
                        impact={"restitution": 0.1, "friction": 0.3}, road={"friction": 0.8}, duration=4.0)
    out = crashlab.get_model("impulse").simulate(scene)
    assert out.outcome_ok, out.warnings
    rows = collision_rows(out.impact_rows)
    first = rows[0]
    again = [r for r in rows if r["vehicle"] == "V1" and r["t"] > first["t"] + PUSH_TIME]
    assert len(again) == 1, out.impacts
    m = saloon.mass  # equal masses: the reduced mass m / 2, the relative velocity's change 2 |dv1|
    mine = [r for r in rows if r["t"] == again[0]["t"]]
    assert len(mine) == 2
    dv = {r["vehicle"]: (r["dvx"], r["dvy"]) for r in mine}
    assert math.hypot(dv["V1"][0] + dv["V2"][0], dv["V1"][1] + dv["V2"][1]) < 1e-9 * math.hypot(*dv["V1"])
    assert m * math.hypot(*dv["V1"]) / 3.6 >= REIMPACT_SPEED * m / 2


def test_a_reimpact_row_has_no_closing_speed_for_the_speed_law():
    """RICSAC 10 (the validation study's scene) with restitution "speed": its re-impact at 0.44 s, plastic as every
    follow-up, uses no restitution, so the law's range is not said of it (it printed "closing speed nan km/h"); the
    impact's own range warning (50 km/h, above the law's data) stays."""
    from dataclasses import replace

    from crashlab.scene_file import load_scene

    scene = load_scene(Path(__file__).parents[1] / "studies" / "validation" / "ricsac10_civic_torino_side.toml")
    scene = scene.replace(impact=replace(scene.impact, restitution_law="speed"))
    out = crashlab.get_model("impulse").simulate(scene)
    assert out.outcome_ok, out.warnings
    assert len(collision_rows(out.impact_rows)) == 4, out.impacts
    said = [w for w in out.warnings if "outside the data of the law" in w]
    assert len(said) == 1 and "nan" not in said[0], out.warnings
