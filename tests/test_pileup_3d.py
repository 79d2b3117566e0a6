"""The 32-car pile-up in the 3D models (issue 27, item 3; tests/pileup.py): both run it, passing the guard. Measured
2026-11-27 (the crush-profile contact), loaded 2-core machine: multibody the whole 5 s (it stops at rest) in
6.3-6.9 s CPU, about 1,940 steps; exudyn 68-73 s CPU (2026-11-26: 10.4 s, 3,241 steps; 77 s). Before the crush
line through zero force (docs/physics.md §13a) exudyn failed a column of 4 touching cars with its reason ("the
contact loads did not settle": a touching pair's force jumped from 0 to A w)."""
from __future__ import annotations

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
