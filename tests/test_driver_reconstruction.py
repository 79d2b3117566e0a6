"""A reconstruction that frees a driver action (issue 13): how fast was V1, and when did its driver brake?

studies/reconstruction/brake_onset.toml is a twin experiment (truth: 70 km/h, wheels locked at 0.8 s) that
frees V1's speed and `actions.0.t`. The rest poses are fitted within 0.1 m, and the starts that fit them
that well trace the trade-off rest poses leave open: a later brake from a lower speed (the same speed at
impact, hence the same crash).
"""
import subprocess
import sys

import pandas as pd
import pytest
from conftest import REPO, assert_one_error_line

STUDY = REPO / "studies" / "reconstruction" / "brake_onset.toml"


def test_free_brake_onset_fits_the_twin_and_shows_the_onset_speed_trade_off(tmp_path):
    res = subprocess.run([sys.executable, "-m", "crashlab.cli", "reconstruct", str(STUDY), "--out", str(tmp_path)],
                         capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr
    pareto = pd.read_csv(tmp_path / "pareto.csv")
    assert pareto[["f_V1", "f_V2"]].iloc[0].max() < 0.1
    near = pd.read_csv(tmp_path / "near_optimal.csv")
    assert (near[["f_V1", "f_V2"]].max(axis=1) <= 0.1).all() and len(near) >= 20
    onset, speed = near["V1.actions.0.t"], near["V1.speed"]
    assert onset.max() - onset.min() > 0.3  # s: rest poses alone leave the onset open ...
    assert speed.corr(onset, method="spearman") < -0.8  # ... along a curve: later braking, lower speed
    summary = (tmp_path / "summary.md").read_text()
    assert "explain the evidence within 0.1 m" in summary and "V1.actions.0.t" in summary


@pytest.mark.parametrize("edit, key, words", [
    (("field = \"actions.0.t\"", "field = \"actions.1.t\""), "free.1.field", ["1 action"]),
    (("upper = 1.3", "upper = 9.0"), "free.1.upper", ["end of the run"]),
    (("field = \"actions.0.t\"", "field = \"actions.0.colour\""), "free.1.field", ["unknown field"]),
])
def test_bad_free_action_fields_are_one_line(tmp_path, edit, key, words):
    text = STUDY.read_text().replace('scene = "../driver/', f'scene = "{REPO}/studies/driver/').replace(*edit)
    path = tmp_path / "bad.toml"
    path.write_text(text)
    res = subprocess.run([sys.executable, "-m", "crashlab.cli", "reconstruct", str(path), "--out",
                          str(tmp_path / "out")], capture_output=True, text=True, timeout=120)
    assert_one_error_line(res, path, key, words)
