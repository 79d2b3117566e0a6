"""The validation study's rows (crashlab.comparison.validation) as issue 24's user pass asked:
- a crush row of a model without a contact depth (the impulse model: rigid outlines) is blank, simulated NaN
  and ok None ("n/a" in validation.md, empty in validation.csv), neither pass nor fail; the other rows keep
  their numbers;
- a run whose restitution law is used outside its data says so: NHTSA 10146 hits the barrier at 57.09 km/h
  (15.9 m/s), above the 1-8 m/s of Cipriani et al.'s law (docs/physics.md §13b), so every run with
  restitution "speed" carries the warning (in the CSV, numbered in validation.md, on stderr per test and
  model) and no run with the constant 0.1 does; the GBB rear impact at 8.85 km/h (2.46 m/s) is within the
  data and warns of nothing about restitution."""
from __future__ import annotations

import csv
import math

import pytest

from crashlab.comparison import validation

CRUSH = ("crush_dynamic", "crush_residual")
BARRIER_KMH = 57.09  # NHTSA 10146, the published impact speed
LAW_RANGE_MS = (1.0, 8.0)  # Cipriani et al. 2002: the closing speeds of its data (docs/physics.md §13b)


def _tests(*ids):
    return [t for t in validation.load_tests() if t["id"] in ids]


@pytest.fixture(scope="module")
def barrier_rows():
    return validation.validation_rows(["impulse"], tests=_tests("nhtsa10146"))


def test_impulse_crush_rows_are_blank_not_pass_or_fail(barrier_rows):
    crush = [r for r in barrier_rows if r["quantity"] in CRUSH]
    other = [r for r in barrier_rows if r["quantity"] not in CRUSH]
    assert crush and other
    for r in crush:
        assert r["ok"] is None and math.isnan(r["simulated"]) and math.isnan(r["error"]) \
            and math.isnan(r["error_pct"]), r
    # the quantities the impulse model has keep a number (rebound, delta-V): ok True, finite
    assert all(r["ok"] is True and math.isfinite(r["simulated"]) for r in other)


def test_crush_blank_in_the_written_table(tmp_path, capsys):
    path = validation.run(["impulse"], tmp_path, tests=_tests("nhtsa10146"))
    rows = list(csv.DictReader(open(path, newline="")))
    crush = [r for r in rows if r["quantity"] in CRUSH]
    assert crush and all(r["ok"] == "" and math.isnan(float(r["simulated"])) for r in crush)
    md = (tmp_path / "validation.md").read_text()
    crush_lines = [ln for ln in md.splitlines() if ln.startswith("| impulse |") and "| crush_" in ln]
    assert crush_lines and all(ln.rstrip().endswith("| n/a |") and "no contact depth" in ln for ln in crush_lines)
    assert not any("-100.0" in ln for ln in crush_lines)


def test_a_model_with_contact_depth_keeps_its_crush():
    """has_quantity: the crush of a model that reports a contact depth stays a number (pymunk's overlap)."""
    rows = validation.validation_rows(["pymunk"], tests=_tests("nhtsa10146"))
    crush = [r for r in rows if r["quantity"] in CRUSH]
    assert crush and all(r["ok"] is True and r["simulated"] > 0.0 for r in crush)


def test_restitution_law_outside_its_data_is_said(barrier_rows, tmp_path, capsys):
    v = BARRIER_KMH / 3.6
    assert not LAW_RANGE_MS[0] <= v <= LAW_RANGE_MS[1]  # the premise: 15.9 m/s, above the law's data
    for r in barrier_rows:
        said = [w for w in r["warnings"] if w.startswith('restitution = "speed"')]
        if r["restitution"] == "speed":
            assert len(said) == 1 and "outside the data of the law" in said[0], r
            # the closing speed it names is the barrier speed (a little less after 0.3 m of rolling)
            named = float(said[0].split("closing speed ")[1].split(" km/h")[0])
            assert named == pytest.approx(BARRIER_KMH, rel=0.01)
        else:
            assert not said, r
    validation.run(["impulse"], tmp_path, tests=_tests("nhtsa10146"))
    err = capsys.readouterr().err
    n_speed = len({(r["law"], r["contact"]) for r in barrier_rows if r["restitution"] == "speed"})
    n_runs = len({(r["law"], r["contact"], r["restitution"]) for r in barrier_rows})
    line = [ln for ln in err.splitlines() if ln.startswith("validation warning: nhtsa10146, impulse")]
    assert len(line) == 1 and f"{n_speed} of {n_runs} runs" in line[0] and "closing speed" in line[0]
    md = (tmp_path / "validation.md").read_text()
    assert "- W1: nhtsa10146, impulse" in md
    marked = [ln for ln in md.splitlines() if ln.startswith("| impulse |") and "| W1 |" in ln]
    assert marked and all("| speed |" in ln for ln in marked)
    rows = list(csv.DictReader(open(tmp_path / "validation.csv", newline="")))
    assert all(("closing speed" in r["warnings"]) == (r["restitution"] == "speed") for r in rows)


def test_no_restitution_warning_within_the_data(capsys):
    rows = validation.validation_rows(["impulse"], tests=_tests("gbb_rear_5mph"))
    assert rows and not any(w.startswith('restitution = "speed"') for r in rows for w in r["warnings"])
    validation.print_warnings(rows)
    assert "restitution" not in capsys.readouterr().err


def test_n_a_is_the_models_own_property():
    """CollisionModel.contact_depth decides n/a, for every model alike (a plugin's default: it has a contact depth),
    not a list of model names in the study."""
    assert not validation.has_quantity("impulse", "crush_dynamic")
    assert validation.has_quantity("impulse", "delta_v")
    assert all(validation.has_quantity(m, "crush_residual") for m in ("pymunk", "multibody", "exudyn"))
