"""Contact episodes and pushes of the 3D models (docs/physics.md §15 "Episodes and pushes"): an episode lasts until
the pair is SEPARATION apart (a re-touch before continues it), and its contact later than PUSH_TIME after the
impact is a push row of its own, as in the impulse model (§5; crashlab.outcome), unless it closes at REIMPACT_SPEED
or faster with a collision's impulse: a re-impact, an impact row of its own.

A rolling bus that strikes a standing car's side pushes it: the car slides ahead on its tyres, the bus catches it
up, the crushed structures touch again and again. Each touch was an episode and an impact row of its own (21 in
5 s); the multibody model failed the run at 12 s ("more than 64 contact episodes", exit 3).

References written here: the records a given sequence of contact states makes, by the rule above; the 1D momentum
of a central impact with restitution e, dV2 = (1 + e) m1 / (m1 + m2) v."""
import math
import sys
from pathlib import Path

import numpy as np
import pytest

from crashlab.models.common import chassis_contact as C
from crashlab.models.common import contact_episodes as EP
from crashlab.outcome import PUSH, PUSH_TIME, REIMPACT_SPEED, SEPARATION, collision_rows

sys.path.insert(0, str(Path(__file__).parent))
from conftest import build_scene  # noqa: E402


def _pair():
    PP = C.pair_table(2, 0, 1e6, 1.5, np.zeros((2, C.N_STR)), [1500.0, 1500.0])
    return PP, np.zeros((1, C.N_PST)), np.zeros((8, EP.N_IMP))


def _step(IMP, n, PP, PST, t, d, gap, v, dd=0.5):
    """One accepted step's end at t: in contact d, gap `gap`, normal closing speed dd (a push's touch by default),
    vehicle 1 moving at v (vehicle 2 at -v)."""
    return EP.episode_step(IMP, n, PP, PST, 0, t, t, t, d, gap, dd, (v, 0.0, 0.0), (-v, 0.0, 0.0))


def test_a_retouch_within_the_separation_continues_the_episode():
    """Touch at 0, contact ends at 0.10 s (V1 at 3 m/s there), the pair 2 cm apart, touches again at 0.15 s
    (before PUSH_TIME), ends at 0.20 s (V1 at 2 m/s), then parts by more than SEPARATION at 0.30 s: one record from
    0 to 0.20 s whose delta-V runs to the second end."""
    PP, PST, IMP = _pair()
    EP.open_episode(PST, 0, 0.0, 5.0, (10.0, 0.0, 0.0), (-10.0, 0.0, 0.0))
    n = _step(IMP, 0, PP, PST, 0.05, 0.1, -0.1, 6.0)
    n = _step(IMP, n, PP, PST, 0.10, -0.01, -0.01, 3.0)
    assert PST[0, C.S_ACT] == EP.ENDED and n == 0
    n = _step(IMP, n, PP, PST, 0.12, -0.02, 0.02, 3.0)
    n = _step(IMP, n, PP, PST, 0.15, 0.01, -0.01, 2.5)
    assert PST[0, C.S_ACT] == EP.IN_CONTACT and n == 0
    n = _step(IMP, n, PP, PST, 0.20, -0.01, -0.005, 2.0)
    n = _step(IMP, n, PP, PST, 0.25, -0.03, 0.03, 1.5)
    assert n == 0
    n = _step(IMP, n, PP, PST, 0.30, -0.08, SEPARATION + 0.01, 1.0)
    assert n == 1 and PST[0, C.S_ACT] == EP.NONE
    r = IMP[0]
    assert (r[EP.I_T0], r[EP.I_T1]) == (0.0, 0.20)
    assert r[EP.I_DVI] == pytest.approx(2.0 - 10.0) and r[EP.I_DVJ] == pytest.approx(-2.0 + 10.0)
    assert r[EP.I_PUSH] == 0.0 and r[EP.I_OPEN] == 0.0


@pytest.mark.parametrize("retouch_impulse, graze", [(5.0, True), (3000.0, False)])
def test_a_graze_does_not_stretch_its_impacts_record(retouch_impulse, graze):
    """The sequence above with the impact's impulse 10 kN s: a re-touch carrying 5 N s (under GRAZE_SHARE of it: the
    fronts swiping lightly after an oblique impact) leaves the record's end at the first contact's, 0.10 s and V1's
    3 m/s there (its delta-V the pulse's, not the pulse's and the tyres' until the graze: NHTSA 4364's impact row
    ran to 0.28 s instead of 0.09 s with the same impulse to 4 digits); one carrying 3 kN s (RICSAC 2's reload, half
    its impact) moves it to its own end, 0.20 s and 2 m/s. The impulse sums count both."""
    PP, PST, IMP = _pair()
    EP.open_episode(PST, 0, 0.0, 5.0, (10.0, 0.0, 0.0), (-10.0, 0.0, 0.0))
    PST[0, C.S_JX] = 10e3                                     # accumulated over the first contact
    n = _step(IMP, 0, PP, PST, 0.05, 0.1, -0.1, 6.0)
    n = _step(IMP, n, PP, PST, 0.10, -0.01, -0.01, 3.0)
    n = _step(IMP, n, PP, PST, 0.15, 0.01, -0.01, 2.5)        # the re-touch
    PST[0, C.S_JX] += retouch_impulse
    n = _step(IMP, n, PP, PST, 0.20, -0.01, -0.005, 2.0)
    n = _step(IMP, n, PP, PST, 0.30, -0.08, SEPARATION + 0.01, 1.0)
    assert n == 1
    r = IMP[0]
    end, v_end = (0.10, 3.0) if graze else (0.20, 2.0)
    assert (r[EP.I_T0], r[EP.I_T1]) == (0.0, end)
    assert r[EP.I_DVI] == pytest.approx(v_end - 10.0) and r[EP.I_JX] == pytest.approx(10e3 + retouch_impulse)


def test_contact_later_than_push_time_is_a_push_record():
    """Touch at 0; ended at 0.1 s; touches again at 0.5 s (> PUSH_TIME after the impact): the impact's record
    ends at 0.1 s and a push opens at 0.5 s, which every later re-touch continues until the run ends in contact."""
    PP, PST, IMP = _pair()
    EP.open_episode(PST, 0, 0.0, 5.0, (10.0, 0.0, 0.0), (-10.0, 0.0, 0.0))
    n = _step(IMP, 0, PP, PST, 0.10, -0.01, -0.01, 3.0)
    n = _step(IMP, n, PP, PST, 0.50, 0.01, -0.01, 2.0)
    assert n == 1 and IMP[0, EP.I_T1] == 0.10 and IMP[0, EP.I_PUSH] == 0.0
    assert PST[0, C.S_ACT] == EP.IN_CONTACT and PST[0, C.S_PUSH] == 1.0 and PST[0, C.S_T0] == 0.50
    PST[0, C.S_JX] = 2e3                                      # the push's impulse (a row below PUSH_DV_MIN is none)
    for t in (1.0, 1.5, 2.0):
        n = _step(IMP, n, PP, PST, t, -0.01, 0.01, 1.0)
        n = _step(IMP, n, PP, PST, t + 0.2, 0.01, -0.01, 0.5)
    assert n == 1
    n = EP.finish_episode(IMP, n, PP, PST, 0, 3.0, 0.0, (0.2, 0.0, 0.0), (-0.2, 0.0, 0.0))
    assert n == 2 and IMP[1, EP.I_PUSH] == 1.0 and IMP[1, EP.I_OPEN] == 1.0
    assert (IMP[1, EP.I_T0], IMP[1, EP.I_T1]) == (0.50, 3.0)
    assert IMP[1, EP.I_DVI] == pytest.approx(0.2 - 2.0)


@pytest.mark.parametrize("impulse, written", [(5.0, False), (100.0, True)])
def test_a_push_that_moves_nothing_writes_no_record(impulse, written):
    """A push whose impulse changes the pair's relative velocity by less than PUSH_DV_MIN (0.1 km/h; the pair's
    reduced mass here 750 kg: 20.8 N s) writes no record: 5 N s none (light touches of a pair at rest made such rows
    of 0.1-9 N s, 42 of exudyn's 250 on 90 random scenes), 100 N s its push row; the impact's row either way."""
    PP, PST, IMP = _pair()
    EP.open_episode(PST, 0, 0.0, 5.0, (10.0, 0.0, 0.0), (-10.0, 0.0, 0.0))
    n = _step(IMP, 0, PP, PST, 0.10, -0.01, -0.01, 3.0)
    n = _step(IMP, n, PP, PST, 0.50, 0.01, -0.01, 2.0)          # the push opens
    PST[0, C.S_JX] = impulse
    n = _step(IMP, n, PP, PST, 0.60, -0.01, 0.01, 2.0)
    n = _step(IMP, n, PP, PST, 0.70, -0.08, SEPARATION + 0.01, 2.0)
    assert n == (2 if written else 1) and IMP[0, EP.I_PUSH] == 0.0 and PST[0, C.S_ACT] == EP.NONE
    assert 0.1 / 3.6 * 750.0 == pytest.approx(20.8, abs=0.05) and IMP[1, EP.I_PUSH] == (1.0 if written else 0.0)


def test_a_contact_that_outlasts_push_time_splits_there():
    """A contact that never ends: the impact's record up to PUSH_TIME after its start, the push from there."""
    PP, PST, IMP = _pair()
    EP.open_episode(PST, 0, 0.0, 5.0, (10.0, 0.0, 0.0), (-10.0, 0.0, 0.0))
    n = 0
    for k in range(1, 11):
        n = _step(IMP, n, PP, PST, 0.1 * k, 0.01, -0.01, 10.0 - k)
    assert n == 1 and IMP[0, EP.I_T1] == pytest.approx(PUSH_TIME) and PST[0, C.S_PUSH] == 1.0
    assert IMP[0, EP.I_DVI] == pytest.approx(-3.0)


def test_a_retouch_closing_as_fast_as_a_collision_is_a_reimpact():
    """Touch at 0, ended at 0.1 s; at 0.5 s (later than PUSH_TIME) a re-touch closing at 4.6 m/s (the probe's struck
    saloon swinging back into the Clio, 253 kN; a push row before): a record of its own from 0.5 s, an impact row
    (kind "continuous") with its restitution, and its contact later than PUSH_TIME after its own start is its push.
    At REIMPACT_SPEED less a little the same re-touch is the push; at REIMPACT_SPEED the re-impact."""
    PP, PST, IMP = _pair()
    EP.open_episode(PST, 0, 0.0, 5.0, (10.0, 0.0, 0.0), (-10.0, 0.0, 0.0))
    n = _step(IMP, 0, PP, PST, 0.10, -0.01, -0.01, 3.0)
    n = _step(IMP, n, PP, PST, 0.50, 0.01, -0.01, 2.0, dd=4.6)
    assert n == 1 and IMP[0, EP.I_T1] == 0.10 and PST[0, C.S_PUSH] == EP.REIMPACT and PST[0, C.S_DD0] == 4.6
    PST[0, C.S_JX] = 2e3
    n = _step(IMP, n, PP, PST, 0.55, -0.01, -0.01, 1.0, dd=-0.46)          # it rebounds at 0.1
    n = _step(IMP, n, PP, PST, 0.85, 0.01, -0.01, 1.0)                      # touches again softly: its push
    assert n == 2 and PST[0, C.S_PUSH] == EP.PUSHING and PST[0, C.S_T0] == 0.85
    # a re-impact still in contact PUSH_TIME after its start goes on as its push, as an impact does
    PP2, PST2, IMP2 = _pair()
    EP.open_episode(PST2, 0, 0.0, 5.0, (10.0, 0.0, 0.0), (-10.0, 0.0, 0.0))
    m = _step(IMP2, 0, PP2, PST2, 0.10, -0.01, -0.01, 3.0)
    m = _step(IMP2, m, PP2, PST2, 0.50, 0.01, -0.01, 2.0, dd=4.6)
    PST2[0, C.S_JX] = 2e3
    m = _step(IMP2, m, PP2, PST2, 0.80, 0.01, -0.01, 1.0, dd=0.2)
    assert m == 2 and IMP2[1, EP.I_PUSH] == EP.REIMPACT and IMP2[1, EP.I_T1] == 0.80
    assert PST2[0, C.S_PUSH] == EP.PUSHING and PST2[0, C.S_T0] == 0.80
    rows = EP.impact_rows(["V1", "V2"], [1500.0, 1500.0], IMP[:n], np.ones((2, 6)))
    assert [r["kind"] for r in rows] == ["continuous"] * 4
    assert (rows[2]["t"], rows[2]["restitution"]) == (0.50, pytest.approx(0.1))
    for dd, kind in ((REIMPACT_SPEED - 1e-9, EP.PUSHING), (REIMPACT_SPEED, EP.REIMPACT)):
        PP, PST, IMP = _pair()
        EP.open_episode(PST, 0, 0.0, 5.0, (10.0, 0.0, 0.0), (-10.0, 0.0, 0.0))
        n = _step(IMP, 0, PP, PST, 0.10, -0.01, -0.01, 3.0)
        _step(IMP, n, PP, PST, 0.50, 0.01, -0.01, 2.0, dd=dd)
        assert PST[0, C.S_PUSH] == kind


def test_a_hard_retouch_in_a_push_is_a_reimpact():
    """A push (opened at 0.5 s) ends at 0.6 s; a soft re-touch at 0.7 s continues it, a hard one at 0.9 s (2 m/s)
    writes it and opens a re-impact, though the push is younger than PUSH_TIME."""
    PP, PST, IMP = _pair()
    EP.open_episode(PST, 0, 0.0, 5.0, (10.0, 0.0, 0.0), (-10.0, 0.0, 0.0))
    n = _step(IMP, 0, PP, PST, 0.10, -0.01, -0.01, 3.0)
    n = _step(IMP, n, PP, PST, 0.50, 0.01, -0.01, 2.0)
    PST[0, C.S_JX] = 2e3
    n = _step(IMP, n, PP, PST, 0.60, -0.01, -0.01, 2.0)
    n = _step(IMP, n, PP, PST, 0.70, 0.01, -0.01, 2.0)
    assert n == 1 and PST[0, C.S_PUSH] == EP.PUSHING and PST[0, C.S_T0] == 0.50
    PST[0, C.S_JX] += 1e3                                    # the re-touch's impulse (no graze)
    n = _step(IMP, n, PP, PST, 0.80, -0.01, -0.01, 2.0)
    n = _step(IMP, n, PP, PST, 0.90, 0.01, -0.01, 2.0, dd=2.0)
    assert n == 2 and IMP[1, EP.I_PUSH] == EP.PUSHING and IMP[1, EP.I_T1] == 0.80
    assert PST[0, C.S_PUSH] == EP.REIMPACT and PST[0, C.S_T0] == 0.90


@pytest.mark.parametrize("impulse, kind", [(2e3, "continuous"), (900.0, "continuous"), (700.0, PUSH)])
def test_a_reimpact_that_exchanges_little_is_a_push(impulse, kind):
    """A re-touch at 0.5 s closing at 2.6 m/s whose impulse changes the pair's relative velocity (1000 and 3000 kg:
    the reduced mass 750 kg) by 2.7 m/s or 1.2 m/s is an impact row; by 0.93 m/s, under REIMPACT_SPEED, a push row:
    its closing speed was not the pair's (exudyn's NHTSA 4363 at 1 s: 2.6 m/s at the touch, 0.2 m/s of exchange,
    335 kN at a step). 900 N s is under either car's mass times REIMPACT_SPEED: the pair's reduced mass decides."""
    PP = C.pair_table(2, 0, 1e6, 1.5, np.zeros((2, C.N_STR)), [1000.0, 3000.0])
    PST, IMP = np.zeros((1, C.N_PST)), np.zeros((8, EP.N_IMP))
    EP.open_episode(PST, 0, 0.0, 5.0, (10.0, 0.0, 0.0), (-10.0, 0.0, 0.0))
    n = _step(IMP, 0, PP, PST, 0.10, -0.01, -0.01, 3.0)
    n = _step(IMP, n, PP, PST, 0.50, 0.01, -0.01, 2.0, dd=2.6)
    PST[0, C.S_JX] = impulse
    n = EP.finish_episode(IMP, n, PP, PST, 0, 0.7, 0.0, (1.0, 0.0, 0.0), (-1.0, 0.0, 0.0))
    rows = EP.impact_rows(["V1", "V2"], [1000.0, 3000.0], IMP[:n], np.ones((2, 6)))
    assert [r["kind"] for r in rows] == ["continuous"] * 2 + [kind] * 2


def _row_restitution(dd0, dd_end, split=False):
    """The restitution of the impact row of an episode touched at the normal approach speed dd0 that ends with the
    normal velocity dd_end (< 0: separating), or that is still in contact when PUSH_TIME splits it (split)."""
    PP, PST, IMP = _pair()
    EP.open_episode(PST, 0, 0.0, dd0, (10.0, 0.0, 0.0), (-10.0, 0.0, 0.0))
    if split:
        n = EP.episode_step(IMP, 0, PP, PST, 0, PUSH_TIME, PUSH_TIME, PUSH_TIME, 0.01, -0.01, dd_end,
                            (4.0, 0.0, 0.0), (-4.0, 0.0, 0.0))
    else:
        n = EP.episode_step(IMP, 0, PP, PST, 0, 0.1, 0.1, 0.1, -0.01, -0.01, dd_end, (1.0, 0.0, 0.0),
                            (-1.0, 0.0, 0.0))
        n = EP.episode_step(IMP, n, PP, PST, 0, 0.2, 0.2, 0.2, -0.1, SEPARATION + 0.01, dd_end, (1.0, 0.0, 0.0),
                            (-1.0, 0.0, 0.0))
    rows = EP.impact_rows(["V1", "V2"], [1500.0, 1500.0], IMP[:n], np.ones((2, 6)))
    return rows[0]["restitution"]


def test_a_row_reports_a_restitution_only_where_the_rebound_ratio_is_one():
    """separation / approach at the contact point: 0.1 for a clean impact; no number (None, as a push's) where the
    touch's normal approach was a graze (a car's corner on a post touched at 0.001 m/s along a normal that turned:
    "e" 2800, a fuzzer) or where the impact was still closing when its push took over ("e" -0.026)."""
    assert _row_restitution(5.0, -0.5) == pytest.approx(0.1)
    assert _row_restitution(0.001, -2.8) is None
    assert _row_restitution(5.0, 0.13, split=True) is None


@pytest.mark.parametrize("model", ["multibody", "exudyn"])
def test_a_bus_pushing_a_car_is_one_impact_and_one_push(model):
    """A Citaro bus (18 t) at 30 km/h into a standing Clio's side, wheels rolling, 12 s: one impact row per
    vehicle (the Clio's delta-V within 5 % of the central 1D momentum value (1 + e) m1 / (m1 + m2) v = 31.3 km/h)
    and one push row per vehicle, starting later than PUSH_TIME after it; before, 64 episodes and more. In the
    push the crushed structures do not ring (docs/physics.md §13a "Push damping"): from 0.3 s after it began until
    it ends, the two cars' velocities along the push differ by less than 0.05 m/s (undamped, the elastic reload
    made the Clio bounce ahead and be caught again: +-0.5 m/s after 1 s), and the push's force stays below the
    impact's peak where it crushes no further."""
    from crashlab.registry import get_model

    sc = build_scene([{"vehicle": "citaro_bus", "speed": 30.0},
                      {"vehicle": "clio", "x": 9.0, "y": 0.0, "heading": 90.0, "speed": 0.0}],
                     impact={"restitution": 0.1, "friction": 0.3}, road={"friction": 0.8}, duration=12.0)
    m1, m2 = (v.spec.mass for v in sc.vehicles)
    out = get_model(model).simulate(sc)
    assert out.outcome_ok, out.warnings
    impacts = collision_rows(out.impact_rows)
    pushes = [r for r in out.impact_rows if r["kind"] == PUSH]
    assert sorted(r["vehicle"] for r in impacts) == ["V1", "V2"]
    assert sorted(r["vehicle"] for r in pushes) == ["V1", "V2"]
    clio = next(r for r in impacts if r["vehicle"] == "V2")
    assert 3.6 * math.hypot(clio["dvx"], clio["dvy"]) == pytest.approx(1.1 * m1 / (m1 + m2) * 30.0, rel=0.05)
    assert clio["duration"] <= PUSH_TIME and min(r["t"] for r in pushes) >= clio["t"] + PUSH_TIME
    push = next(r for r in pushes if r["vehicle"] == "V2")
    bus, car = out.trajectories["V1"], out.trajectories["V2"]
    t = np.asarray(car["t"])
    pressed = (t > push["t"] + 0.3) & (t < push["t"] + push["duration"])
    assert np.count_nonzero(pressed) > 50
    assert np.max(np.abs(np.asarray(bus["vx"]) - np.asarray(car["vx"]))[pressed]) < 0.05
    # the push crushes no further than the impact did, so its damped force stays below the loading line's: at most
    # the impact's peak (the damping alone, up to the structures' force, had exudyn's push at 198 against 166 kN)
    assert push["max_penetration"] <= clio["max_penetration"]
    assert push["peak_force"] <= clio["peak_force"] * (1 + 1e-3)


def test_a_push_is_continuous_where_its_contact_begins():
    """The stability study's seed 3 (21.7 km/h, 43 deg, restitution 0.047) in exudyn at a 4 ms step: its push
    touches again and again at the edge of the permanent set, where the structures' force is about 0. A
    Kelvin-Voigt term alone jumps there from 0 to c dd (24 kN at 0.04 m/s) and exudyn's load iteration flipped
    between the two ("the contact loads did not settle", 10 steps); the push damping, held at most the structures'
    force (docs/physics.md §13a "Push damping"), is continuous there."""
    pytest.importorskip("exudyn")
    from crashlab.comparison.stability import draw
    from crashlab.registry import get_model

    _, scene = draw(3)
    out = get_model("exudyn", step=0.004).simulate(scene)
    assert out.outcome_ok, out.warnings
    assert any(r["kind"] == PUSH for r in out.impact_rows)


def test_an_impact_still_unloading_at_push_time_is_no_push():
    """Contact from 0 still on at 0.35 s but separating (dd < 0, an impact's rebound): no push yet; at 0.40 s closing
    again (dd > 0): the push opens there."""
    PP, PST, IMP = _pair()
    EP.open_episode(PST, 0, 0.0, 5.0, (10.0, 0.0, 0.0), (-10.0, 0.0, 0.0))
    n = EP.episode_step(IMP, 0, PP, PST, 0, 0.35, 0.35, 0.35, 0.01, -0.01, -0.5, (3.0, 0.0, 0.0), (-3.0, 0.0, 0.0))
    assert n == 0 and PST[0, C.S_PUSH] == 0.0
    n = EP.episode_step(IMP, n, PP, PST, 0, 0.40, 0.40, 0.40, 0.01, -0.01, 0.1, (2.0, 0.0, 0.0), (-2.0, 0.0, 0.0))
    assert n == 1 and PST[0, C.S_PUSH] == 1.0 and IMP[0, EP.I_T1] == 0.40


def test_a_soft_impact_longer_than_push_time_keeps_its_rebound():
    """A saloon at 30 km/h into a 0.1 m wide rigid pole on ice, locked wheels, e = 0.6: the contact's quarter period
    (pi/2) sqrt(m / (w B)) is 0.25 s, so it unloads past PUSH_TIME. The rebound is e times the impact speed (the
    structure law's unloading gives back e^2 of the energy, docs/physics.md §13a): 5.0 m/s. The push's damping took
    it before (0.30 of the impact speed, a push row of 0 km/h)."""
    scene = build_scene([{"vehicle": "saloon", "speed": 30.0, "wheels": "locked"}], duration=1.0, stop_at_rest=False,
                        road={"friction": 0.0}, impact={"restitution": 0.6},
                        barriers=[{"x": 2.872, "y": 0.0, "heading": 90.0, "length": 0.1, "width": 1.0}])
    from crashlab.registry import get_model
    out = get_model("multibody").simulate(scene)
    assert out.outcome_ok, out.warnings
    assert -out.final_si[0, 0] == pytest.approx(0.6 * 30.0 / 3.6, rel=0.01)
    assert [r["kind"] for r in out.impact_rows] == ["continuous"]


@pytest.mark.parametrize("model", ["multibody", "exudyn"])
def test_a_struck_car_swinging_back_is_a_reimpact_row(model):
    """A scene of the probe (2026-11-28): a Clio at 57.7 km/h into a saloon moving at 6.8 km/h on locked wheels, at
    115.5 deg and 1.0 m off its centre line. The pair stays within 5 cm, and 0.46 s after the impact's onset the
    saloon swings back into the Clio, closing at 2.0 m/s, 0.35 s at up to 141 kN (exudyn 179 kN; the impact: 182
    kN): a push row before, now an impact row of its own whose impulse exchanges more than REIMPACT_SPEED of the
    pair's relative velocity (2.1 m/s), followed by the push. Its delta-V lies within the road's Coulomb impulse
    mu g T of its contact impulse over the mass (tyres alone act beside the contact)."""
    if model == "exudyn":
        pytest.importorskip("exudyn")
    from crashlab.registry import get_model
    from crashlab.vehicle import load_vehicle

    clio, saloon = load_vehicle("clio"), load_vehicle("saloon")
    th, T, off = math.radians(115.5), 0.25, 1.0
    v1, v2 = 57.7 / 3.6, 6.8 / 3.6
    d = clio.cg_to_front + max(saloon.cg_to_front, saloon.cg_to_rear) + 0.4
    mu = 0.8
    sc = build_scene([{"vehicle": "clio", "speed": 57.7, "x": -v1 * T},
                      {"vehicle": "saloon", "speed": 6.8, "heading": 115.5, "wheels": "locked",
                       "x": d - v2 * T * math.cos(th), "y": off - v2 * T * math.sin(th)}],
                     impact={"restitution": 0.1, "friction": 0.3}, road={"friction": mu}, duration=4.0)
    out = get_model(model).simulate(sc)
    assert out.outcome_ok, out.warnings
    rows = collision_rows(out.impact_rows)
    assert len(rows) == 4, [(r["kind"], r["t"]) for r in out.impact_rows]
    first, again = rows[0], rows[2]
    assert again["t"] >= first["t"] + PUSH_TIME + 0.1 and again["approach_speed"] >= REIMPACT_SPEED
    assert again["peak_force"] > 0.5 * first["peak_force"]
    m = {v.name: v.spec.mass for v in sc.vehicles}
    m_red = m["V1"] * m["V2"] / (m["V1"] + m["V2"])
    assert math.hypot(again["impulse_x"], again["impulse_y"]) >= 1.5 * REIMPACT_SPEED * m_red
    pushes = [r for r in out.impact_rows if r["kind"] == PUSH]
    assert pushes and min(r["t"] for r in pushes) >= again["t"]
    for r in rows[2:]:
        off = math.hypot(r["dvx"] - r["impulse_x"] / m[r["vehicle"]], r["dvy"] - r["impulse_y"] / m[r["vehicle"]])
        assert off <= mu * 9.81 * r["duration"] * 1.05
