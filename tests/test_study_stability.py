"""The stability study (crashlab.comparison.stability) on a tiny configuration: the impulse model on a few
seeded random crashes at its default and at a step 8 times its default."""
from __future__ import annotations

import json

import pandas as pd
import pytest

from crashlab.comparison import stability

COLUMNS = ["model", "setting", "speed_kmh", "angle_deg", "mass_ratio", "offset_m", "restitution", "impact_friction",
           "road_friction", "wheels", "ok", "violation", "failure", "step_collapse", "wall_time_s", "seed"]


def test_the_sample_is_seeded_and_inside_the_space():
    a, b = stability.sample(12, seed=5), stability.sample(12, seed=5)
    assert [s for s, _, _ in a] == [s for s, _, _ in b] and [p for _, p, _ in a] == [p for _, p, _ in b]
    for seed, p, scene in a:
        assert 5 <= p["speed_kmh"] <= 200 and 0 <= p["angle_deg"] <= 180 and 0.25 <= p["mass_ratio"] <= 4
        v1, v2 = scene.vehicles
        assert v1.spec.mass / v2.spec.mass == pytest.approx(p["mass_ratio"], rel=1e-9)
        assert f"{v1.wheels}/{v2.wheels}" == p["wheels"]
        assert stability.draw(seed)[0] == p, "a row's seed rebuilds its scene"


def test_impulse_study_writes_the_contract_and_is_stable_at_its_default(tmp_path):
    path = stability.study(["impulse"], tmp_path, lambda m: (8, 4), all_knobs=False, factors=(8,), log=lambda s: None)
    df = pd.read_csv(path, keep_default_na=False)
    assert list(df.columns) == COLUMNS
    assert list(df.setting.unique()) == ["{}", json.dumps({"dt": 0.04})]
    assert (df.setting == "{}").sum() == 8 and len(df) == 12
    default = df[df.setting == "{}"]
    # a physical fact: the impulse model at its default passes the physics guard on every drawn crash
    assert default.ok.all() and (default.violation == "").all() and (default.failure == "").all()
    summary = pd.read_csv(tmp_path / "stability_summary.csv")
    assert summary.loc[0, "model"] == "impulse" and summary.loc[0, "runs"] == 8
    assert summary.loc[0, "largest_stable_step"] >= 0.005, "the default step itself is stable"
    assert (tmp_path / "stability_impulse.png").stat().st_size > 0


def test_coarse_settings_stay_inside_the_declared_range():
    settings = stability.coarse_settings("pymunk", factors=(2, 4, 8, 64))
    assert ("dt", 64, {"dt": 0.016}) not in settings, "pymunk's dt is at most 0.01 s"
    assert ("iterations", 8, {"iterations": 12}) in settings, "an iteration count is divided"


def test_a_failed_run_gives_its_reason_not_only_its_first_note(monkeypatch):
    """exudyn's 189 km/h side impact (seed 4) failed on 'the contact loads did not settle' after a crush-zone note:
    the csv said only the note (its first warning) before 2026-11-27."""
    import numpy as np

    from crashlab.comparison import stability as S
    from crashlab.outcome import Outcome

    class Failing:
        def simulate(self, scene):
            return Outcome(["V1"], np.zeros((1, 3)), np.zeros((1, 3)), warnings=["a note", "the reason"], ok=False)

    monkeypatch.setattr(S, "get_model", lambda name, **kw: Failing())
    (row,) = S.run_setting("failing", {}, [(4, {}, None)])
    assert not row["ok"] and "the reason" in row["failure"] and "a note" in row["failure"]
