"""A 32-car pile-up (issue 27; tests/pileup.py): the impulse model's impact cap scales with the scene, and
pymunk's guard judges the energy of the cars in touch with each other, not a pair's share of it."""
from __future__ import annotations

import numpy as np
import pytest
from pileup import pileup

import crashlab


def test_impulse_pileup_runs_at_the_default_impact_cap():
    """At the old fixed cap of 20 impacts the pile-up stopped failed; the cap max_impacts x (n - 1) lets it
    finish, guarded, and the cap still stops a run that reaches it."""
    scene = pileup(gap=1.0)  # 33 impacts: beyond the old 20 and beyond max_impacts = 1 x 31
    out = crashlab.get_model("impulse").simulate(scene)
    assert out.outcome_ok, out.warnings[-3:]
    assert 20 < out.diagnostics["episodes"] <= 20 * 31
    capped = crashlab.get_model("impulse", max_impacts=1).simulate(scene)
    assert not capped.outcome_ok and any("max_impacts = 1 x (vehicles - 1)" in w for w in capped.warnings)
    two = crashlab.get_model("impulse").impact_cap(2)
    assert two == 20  # a two-car scene keeps its cap


@pytest.mark.slow
def test_pymunk_pileup_passes_the_guard():
    """32 cars (4 lanes of 8 parked bumper to bumper, cars pressed between others): no false "impact creates
    energy" (booked per pair it read "impact 15 creates 19.7 kJ"), every impact dissipates."""
    scene = pileup()
    out = crashlab.get_model("pymunk").simulate(scene)
    assert out.outcome_ok, out.warnings[-3:]
    ke0 = out.diagnostics.energy_start
    assert np.all(out.impact_energy >= -1e-6 * ke0)
