"""The spread between models after `crashlab compare` (issue 26 item 1): per vehicle the largest distance between
two models' rest positions and the largest wrapped heading difference, checked against the poses written by hand
and against the comparison rows of `compare --json` (an independent computation in the test)."""
from __future__ import annotations

import itertools
import json
import math
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import pandas as pd
import pytest

from crashlab.tools.compare import model_spread

SIDE = Path(__file__).resolve().parent.parent / "studies" / "pc_crash" / "side.toml"


def test_spread_of_three_models_written_by_hand():
    """Rest positions on a 3-4-5 triangle (the farthest pair 5 m apart) and headings 170, -170 and 150 deg: the
    widest wrapped difference is 150 / -170 (40 deg), not 170 / -170 (340 unwrapped); a failed model is left out."""
    df = pd.DataFrame({"source": ["a", "b", "c", "d", "pc_crash"], "vehicle": ["V1"] * 5,
                       "x": [0.0, 3.0, 0.0, 50.0, 9.0], "y": [0.0, 0.0, 4.0, 50.0, 9.0],
                       "heading": [170.0, -170.0, 150.0, 0.0, 0.0]})
    outcomes = {m: SimpleNamespace(outcome_ok=m != "d") for m in "abcd"}
    row = model_spread(df, outcomes).iloc[0]
    assert row["models"] == 3
    assert row["distance_m"] == pytest.approx(5.0, abs=1e-12) and row["distance_pair"] == "b/c"
    assert row["heading_deg"] == pytest.approx(40.0, abs=1e-12) and row["heading_pair"] == "b/c"
    assert model_spread(df, {"a": outcomes["a"]}).empty  # one model: no spread


def test_compare_prints_and_writes_the_spread():
    res = subprocess.run([sys.executable, "-m", "crashlab.cli", "compare", str(SIDE), "--models", "impulse,pymunk",
                          "--json"], capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr
    data = json.loads(res.stdout)
    rows = {(r["source"], r["vehicle"]): r for r in data["comparison"]}
    for s in data["spread"]:
        pairs = list(itertools.combinations(["impulse", "pymunk"], 2))
        (a, b), = pairs
        ra, rb = rows[(a, s["vehicle"])], rows[(b, s["vehicle"])]
        assert s["models"] == 2
        assert s["distance_m"] == pytest.approx(math.hypot(ra["x"] - rb["x"], ra["y"] - rb["y"]), abs=2e-6)
        turned = abs((rb["heading"] - ra["heading"] + 180.0) % 360.0 - 180.0)
        assert s["heading_deg"] == pytest.approx(turned, abs=2e-6)
    assert [s["vehicle"] for s in data["spread"]] == ["V1", "V2"]
    text = subprocess.run([sys.executable, "-m", "crashlab.cli", "compare", str(SIDE), "--models", "impulse,pymunk"],
                          capture_output=True, text=True, timeout=600).stdout
    assert "spread between the models" in text
    assert max(len(line) for line in text.splitlines()) <= 100
