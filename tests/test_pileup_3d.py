"""The 32-car pile-up in the 3D models (issue 27, item 3; tests/pileup.py): both run it, passing the guard. Measured
2026-11-27 (the crush-profile contact), loaded 2-core machine: multibody the whole 5 s (it stops at rest) in
6.3-6.9 s CPU, about 1,940 steps; exudyn 68-73 s CPU (2026-11-26: 10.4 s, 3,241 steps; 77 s). Before the crush
line through zero force (docs/physics.md §13a) exudyn failed a column of 4 touching cars with its reason ("the
contact loads did not settle": a touching pair's force jumped from 0 to A w)."""
from __future__ import annotations

from collections import Counter

import numpy as np
import pytest
from pileup import pileup

import crashlab


@pytest.mark.slow
def test_multibody_pileup_passes_the_guard():
    """32 cars (4 lanes of 8 parked bumper to bumper): the run ends ok, every contact episode dissipates."""
    scene = pileup()
    out = crashlab.get_model("multibody").simulate(scene)
    assert out.outcome_ok, out.warnings[-3:]
    assert len(out.impact_rows) > 31
    assert np.all(out.impact_energy >= -1e-3 * out.diagnostics.energy_start)


@pytest.mark.slow
def test_exudyn_pileup_passes_the_guard():
    """The same 32 cars in exudyn: the run ends ok, every contact episode dissipates."""
    pytest.importorskip("exudyn")
    out = crashlab.get_model("exudyn").simulate(pileup())
    assert out.outcome_ok, out.warnings[-3:]
    assert len(out.impact_rows) > 31
    assert np.all(out.impact_energy >= -1e-3 * out.diagnostics.energy_start)


@pytest.fixture(scope="module")
def one_lane():
    """One lane of tests/pileup.py in multibody: 3 Clios parked bumper to bumper, the fourth driving into them."""
    return crashlab.get_model("multibody").simulate(pileup(n_lanes=1, per_lane=4))


def test_multibody_sleepers_woken_keep_their_episode(one_lane):
    """One lane of tests/pileup.py (3 Clios parked bumper to bumper, the fourth driving into them): the parked cars
    touch from the start and never part by 5 cm, so each pair has one contact episode (a row per car) and, past
    PUSH_TIME, one push row per car (docs/physics.md §15). Two touching sleepers whose episode's contact has ended
    are not evaluated; a vehicle a contact wakes is woken after the step's episodes are booked: woken inside the
    booking, a pair booked after the wake read its skipped (empty) contact outputs and closed its episode (4 rows
    per pair and kind then, 160 instead of 112 rows in the 32-car pile-up)."""
    out = one_lane
    assert out.outcome_ok, out.warnings[-3:]
    rows = Counter((frozenset((r["vehicle"], r["other"])), r["kind"]) for r in out.impact_rows)
    assert {pair for pair, _ in rows} == {frozenset((f"L1C{q}", f"L1C{q + 1}")) for q in (1, 2, 3)}
    assert max(rows.values()) == 2, rows


def test_multibody_says_which_rows_hold_concurrent_contacts(one_lane):
    """The middle cars of the lane are pressed by both neighbours at once: their rows' delta-V (the CG's velocity
    change over each episode) holds both contacts, and the run says so for exactly those cars (docs/physics.md §21
    "Concurrent contacts"); the end cars have one partner each. Checked against the rows: a middle car's two
    overlapping rows differ from their own impulse over its mass, by the other contact's."""
    said = {w.split("'s contacts with different partners")[0] for w in one_lane.warnings
            if "contacts with different partners overlap in time" in w}
    assert said == {"L1C2", "L1C3"}, one_lane.warnings
    mass = {vs.name: vs.spec.mass for vs in pileup(n_lanes=1, per_lane=4).vehicles}
    for r in one_lane.impact_rows:
        own = np.hypot(r["impulse_x"], r["impulse_y"]) / mass[r["vehicle"]]
        if r["vehicle"] == "L1C2" and own > 1.0:  # its contacts with L1C1 and with L1C3, both at about 0.36 s
            assert abs(np.hypot(r["dvx"], r["dvy"]) - own) > 0.3 * own, r
