"""Evidence with its uncertainty (issue 14, item 1; crashlab.reconstruction.evidence): the normalised
residuals and the Gaussian log-likelihood of hand-made outcomes against hand-computed values, twins whose
evidence of every kind is fitted, the misfit of every item in the report, and bad evidence refused with
one line naming the file and key."""
from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from conftest import FREE_SPEEDS, assert_one_error_line, assert_refused_with_one_line

from crashlab.outcome import Outcome
from crashlab.reconstruction import load_study
from crashlab.reconstruction.evidence import EvidenceItem, EvidenceSet, log_likelihood_of, polyline_distance
from crashlab.units import kmh_to_ms, ms_to_kmh

REPO = Path(__file__).resolve().parent.parent
SIDE = REPO / "studies" / "pc_crash" / "side.toml"
KMH = 3.6


# ------------------------------------------------------------------ 1. residuals and likelihood by hand
def test_polyline_distance_is_the_distance_to_the_nearest_segment():
    path = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0]])
    pts = np.array([[5.0, 1.0], [10.0, 5.0], [12.0, 12.0], [-3.0, -4.0], [5.0, 0.0]])
    np.testing.assert_allclose(polyline_distance(pts, path), [1.0, 0.0, math.hypot(2, 2), 5.0, 0.0], atol=1e-12)
    assert np.isnan(polyline_distance(pts, np.empty((0, 2)))).all()


def _row(t, vehicle, other, dvx, dvy, px, py):
    return {"t": t, "vehicle": vehicle, "other": other, "dvx": dvx, "dvy": dvy, "d_yaw_rate": 0.0,
            "energy": 1e4, "ees": 1.0, "pdof": 0.0, "side": "front", "kind": "full", "point_x": px, "point_y": py,
            "plane_angle": 0.0}


def hand_made_outcome(ok=True, impacts=True):
    """V1 rests at (1, 2), 10 deg; V2 at (5, 6); speeds at first contact 50 and 30 km/h; V1's CG path the
    polyline (0, 0) - (10, 0) - (10, 10); two impacts, listed latest first: the first (t = 0.5) at (2, 1)."""
    rows = [_row(1.0, "V1", "V2", 3.0, 0.0, 9.0, 9.0), _row(1.0, "V2", "V1", -3.0, 0.0, 9.0, 9.0),
            _row(0.5, "V1", "V2", 3.0, 4.0, 2.0, 1.0), _row(0.5, "V2", "V1", -3.0, -4.0, 2.0, 1.0)]
    traj = {"V1": {"t": np.arange(3.0), "x": np.array([0.0, 10.0, 10.0]), "y": np.array([0.0, 0.0, 10.0])}}
    return Outcome(["V1", "V2"], [[1.0, 2.0, math.radians(10.0)], [5.0, 6.0, 0.0]], np.zeros((2, 3)),
                   [[0.0, 0.0, 0.0, kmh_to_ms(50.0)], [3.0, 0.0, 1.6, kmh_to_ms(30.0)]] if impacts else None,
                   trajectories=traj, impact_rows=rows if impacts else [], ok=ok)


def hand_made_evidence() -> EvidenceSet:
    items = [EvidenceItem("rest", "rest.V1", ("V1",), ("x", "y", "heading"), (1.3, 1.6, 355.0), (0.2, 0.2, 5.0)),
             EvidenceItem("rest", "rest.V2", ("V2",), ("x", "y"), (5.0, 6.0), (0.2, 0.2)),
             EvidenceItem("impact", "impact", ("V1", "V2"), ("x", "y"), (2.5, 1.0), (0.5, 0.5)),
             EvidenceItem("marks", "marks.0", ("V1",), ("p0", "p1", "p2"), (0.0, 0.0, 0.0), (0.5, 0.5, 0.5),
                          np.array([[5.0, 1.0], [10.0, 5.0], [12.0, 12.0]])),
             EvidenceItem("edr", "edr.V1", ("V1",), ("speed_at_impact", "delta_v"), (48.0, 22.0), (2.0, 3.0))]
    return EvidenceSet(["V1", "V2"], items)


def test_residuals_and_log_likelihood_of_a_hand_made_outcome():
    ev = hand_made_evidence()
    R = ev.residuals([hand_made_outcome()])
    dv = math.hypot(6.0, 4.0) * KMH  # V1's impact rows summed: (3, 4) + (3, 0) m/s
    expected = [(1.0 - 1.3) / 0.2, (2.0 - 1.6) / 0.2, 15.0 / 5.0,  # heading 10 - 355 wraps to +15 deg
                0.0, 0.0,
                (2.0 - 2.5) / 0.5, 0.0,  # the first impact (t = 0.5), not the first row listed
                1.0 / 0.5, 0.0, math.hypot(2.0, 2.0) / 0.5,
                (50.0 - 48.0) / 2.0, (dv - 22.0) / 3.0]
    assert ev.labels == ["rest.V1.x", "rest.V1.y", "rest.V1.heading", "rest.V2.x", "rest.V2.y", "impact.x",
                         "impact.y", "marks.0.p0", "marks.0.p1", "marks.0.p2", "edr.V1.speed_at_impact",
                         "edr.V1.delta_v"]
    np.testing.assert_allclose(R[0], expected, rtol=0, atol=1e-9)
    L = ev.log_likelihood([hand_made_outcome()])
    assert L[0] == pytest.approx(-0.5 * sum(e * e for e in expected), abs=1e-9)
    # per item and per vehicle: the point of impact is in both vehicles' objectives, once in the likelihood
    items = ev.item_misfits(R)[0]
    np.testing.assert_allclose(items, [math.hypot(-1.5, 2.0, 3.0), 0.0, 1.0,
                                       math.hypot(2.0, math.hypot(2, 2) / 0.5), math.hypot(1.0, (dv - 22) / 3)])
    F = ev.objectives(R)[0]
    assert ev.objective_names == ["V1", "V2"]
    assert F[1] == pytest.approx(1.0)  # V2: its rest pose (exact) and the point of impact (one sigma in x)
    assert -0.5 * (F[0] ** 2 + F[1] ** 2 - items[2] ** 2) == pytest.approx(L[0])


def test_an_outcome_that_cannot_be_scored_has_nan_residuals_and_minus_inf_likelihood():
    ev = hand_made_evidence()
    outs = [hand_made_outcome(ok=False), hand_made_outcome(impacts=False), None, RuntimeError("boom"),
            hand_made_outcome()]
    R = ev.residuals(outs)
    assert np.isnan(R[:4]).all() and np.isfinite(R[4]).all()
    L = ev.log_likelihood(outs)
    assert np.all(L[:4] == -np.inf) and np.isfinite(L[4])
    np.testing.assert_array_equal(log_likelihood_of(np.zeros((2, 3))), [0.0, 0.0])


# ------------------------------------------------------------------ 2. twins with every kind of evidence
ALL_EVIDENCE = f'''
name = "twin, every kind of evidence"
scene = "{SIDE.as_posix()}"
[optimizer]
name = "nsga2"
pop_size = 12
generations = 4
seed = 1
{FREE_SPEEDS}[evidence]
twin = true
NOISE
[evidence.rest.V1]
sigma_xy = 0.2
sigma_heading = 5.0
[evidence.rest.V2]
sigma_xy = 0.2
[evidence.impact]
sigma = 0.5
[[evidence.marks]]
vehicle = "V1"
sigma = 0.3
n_points = 5
[evidence.edr.V1]
sigma_speed = 2.0
sigma_delta_v = 3.0
[evidence.edr.V2]
sigma_delta_v = 3.0
[polish]
evaluations = 60
'''


def write_study(tmp_path, text, name="study.toml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def test_twin_fills_every_kind_of_evidence_and_scores_zero_at_the_truth(tmp_path):
    study = load_study(write_study(tmp_path, ALL_EVIDENCE.replace("NOISE", "")))
    ev = study.evidence_set
    assert study.mode == "misfit"  # default as soon as a sigma is given
    assert [it.label for it in ev.items] == ["rest.V1", "rest.V2", "impact", "marks.0", "edr.V1", "edr.V2"]
    assert ev.items[1].components == ("x", "y")  # no sigma_heading: no heading item
    edr = ev.items[4]
    assert edr.values[0] == pytest.approx(50.0, abs=1e-6)  # side.toml: V1 at 50 km/h, no braking before contact
    problem = study.make_problem()
    truth = problem.base_values()
    F, R = problem.evaluate(np.array([truth, truth + [8.0, -5.0]]), return_values_of=["F", "residuals"])
    np.testing.assert_allclose(F[0], 0.0, atol=1e-9)
    np.testing.assert_allclose(R[0], 0.0, atol=1e-9)
    assert np.all(F[1] > 1.0)  # 8 km/h off: several sigmas
    print(f"\nresiduals 8 and -5 km/h off the truth: {dict(zip(ev.labels, np.round(R[1], 2)))}")


def test_twin_noise_draws_the_evidence_from_the_sigmas(tmp_path):
    study = load_study(write_study(tmp_path, ALL_EVIDENCE.replace("NOISE", "noise_seed = 3")))
    exact = load_study(write_study(tmp_path, ALL_EVIDENCE.replace("NOISE", ""), "exact.toml"))
    problem = study.make_problem()
    R = problem.evaluate(problem.base_values()[None], return_values_of=["residuals"])
    # at the truth the residuals are the noise drawn / sigma: standard normal components (the marks' are
    # distances of noisy points: positive); the evidence differs from the exact twin's
    m = R.shape[1]
    chi2 = float(np.sum(R ** 2))
    print(f"\nnoise_seed 3: chi2 at the truth {chi2:.2f} for {m} components")
    assert 0.0 < chi2 < 3.0 * m
    assert any(a.values != b.values for a, b in zip(study.evidence_set.items, exact.evidence_set.items))


def test_twin_with_every_kind_of_evidence_is_fitted_and_the_report_lists_each_misfit(tmp_path):
    study = load_study(write_study(tmp_path, ALL_EVIDENCE.replace("NOISE", "")))
    out = tmp_path / "out"
    res = study.run(out_dir=out)
    best = res.pareto.iloc[0]
    print(f"\nbest: V1 {best['V1.speed']:.3f}, V2 {best['V2.speed']:.3f} km/h, f {best['f_V1']:.4f} "
          f"{best['f_V2']:.4f}, log-likelihood {best['log_likelihood']:.5f}; {res.evaluations} evaluations")
    assert best["f_V1"] < 0.1 and best["f_V2"] < 0.1  # a tenth of a sigma
    assert best["V1.speed"] == pytest.approx(50.0, abs=0.5) and best["V2.speed"] == pytest.approx(30.0, abs=0.5)
    table = pd.read_csv(out / "pareto.csv")
    cols = [f"misfit_{it.label}" for it in study.evidence_set.items]
    assert set(cols + ["log_likelihood"]) <= set(table.columns)
    assert table[cols].notna().all().all()
    # the log-likelihood is -0.5 x the sum of the items' squared misfits, each item once
    np.testing.assert_allclose(table["log_likelihood"], -0.5 * (table[cols] ** 2).sum(axis=1), rtol=1e-9)
    summary = (out / "summary.md").read_text()
    assert "Misfit of every evidence item, every Pareto row" in summary
    for c in cols:
        assert c in summary
    for label in ("rest.V1: x =", "impact: x =", "marks.0: V1's CG path", "edr.V2: delta_v ="):
        assert label in summary


def test_thesis_files_keep_the_thesis_objective():
    case = load_study(REPO / "studies" / "reconstruction" / "case1.toml")
    twin = load_study(REPO / "studies" / "reconstruction" / "twin2.toml")
    assert case.mode == twin.mode == "thesis" and case.evidence_set is None
    assert list(case.evidence) == case.objective_names == ["V1", "V2"]
    example = load_study(REPO / "studies" / "reconstruction" / "twin_evidence.toml")
    assert example.mode == "misfit"
    assert [it.label for it in example.evidence_set.items] == ["rest.V1", "rest.V2", "impact", "edr.V1"]


# ------------------------------------------------------------------ 3. bad evidence
MEASURED = f'''
scene = "{SIDE.as_posix()}"
[[free]]
vehicle = "V1"
field = "speed"
lower = 30.0
upper = 70.0
[evidence.rest.V1]
x = 7.11
y = 3.51
heading = 147.7
sigma_xy = 0.2
sigma_heading = 5.0
[evidence.impact]
x = 0.9
y = 0.1
sigma = 0.5
[[evidence.marks]]
vehicle = "V1"
points = [[-12.0, 0.1], [-6.0, 0.05], [0.0, 0.0]]
sigma = 0.3
[evidence.edr.V1]
speed_at_impact = 48.0
sigma_speed = 2.0
delta_v = 22.0
sigma_delta_v = 3.0
'''

BAD = {  # id: (old, new, key, words)
    "sigma-zero": ("sigma_xy = 0.2", "sigma_xy = 0.0", "evidence.rest.V1.sigma_xy", ["greater than 0"]),
    "sigma-negative": ("sigma = 0.5", "sigma = -0.5", "evidence.impact.sigma", ["greater than 0"]),
    "sigma-heading-zero": ("sigma_heading = 5.0", "sigma_heading = 0", "evidence.rest.V1.sigma_heading",
                           ["greater than 0"]),
    "edr-sigma-zero": ("sigma_delta_v = 3.0", "sigma_delta_v = 0.0", "evidence.edr.V1.sigma_delta_v",
                       ["greater than 0"]),
    "marks-one-point": ("points = [[-12.0, 0.1], [-6.0, 0.05], [0.0, 0.0]]", "points = [[0.0, 0.0]]",
                        "evidence.marks.0.points", ["at least 2"]),
    "marks-unknown-vehicle": ('vehicle = "V1"\npoints', 'vehicle = "V9"\npoints', "evidence.marks.0.vehicle",
                              ["'V9'"]),
    "rest-unknown-vehicle": ("[evidence.rest.V1]", "[evidence.rest.V3]", "evidence.rest.V3", ["'V3'"]),
    "edr-unknown-vehicle": ("[evidence.edr.V1]", "[evidence.edr.V7]", "evidence.edr.V7", ["'V7'"]),
    "edr-without-sigma": ("sigma_speed = 2.0\n", "", "evidence.edr.V1.sigma_speed", ["missing", "sigma"]),
    "edr-delta-v-without-sigma": ("sigma_delta_v = 3.0\n", "", "evidence.edr.V1.sigma_delta_v", ["missing"]),
    "heading-without-sigma": ("sigma_heading = 5.0\n", "", "evidence.rest.V1.sigma_heading", ["missing"]),
    "rest-without-sigma": ("sigma_xy = 0.2\n", "", "evidence.rest.V1.sigma_xy", ["missing"]),
    "mark-point-nan": ("[-6.0, 0.05]", "[-6.0, nan]", "evidence.marks.0.points.1.1", ["finite"]),
    "noise-without-twin": ("[evidence.rest.V1]", "[evidence]\nnoise_seed = 1\n[evidence.rest.V1]",
                           "evidence.noise_seed", ["twin"]),
    "thesis-with-impact": ("[evidence.impact]", '[objective]\nmode = "thesis"\n[evidence.impact]', "objective.mode",
                           ["misfit"]),
}


def test_measured_evidence_file_loads():
    import tempfile
    with tempfile.TemporaryDirectory() as d:
        study = load_study(write_study(Path(d), MEASURED))
    assert [it.label for it in study.evidence_set.items] == ["rest.V1", "impact", "marks.0", "edr.V1"]
    assert study.evidence_set.needs_trajectory and study.objective_names == ["V1", "V2"]


@pytest.mark.parametrize("case", list(BAD), ids=list(BAD))
def test_bad_evidence_is_one_error_naming_the_key(tmp_path, case):
    old, new, key, words = BAD[case]
    assert old in MEASURED
    assert_refused_with_one_line(load_study, write_study(tmp_path, MEASURED.replace(old, new, 1)), key, words)


def test_bad_evidence_on_the_command_line_exits_2(tmp_path):
    path = write_study(tmp_path, MEASURED.replace("sigma_xy = 0.2", "sigma_xy = -1.0"))
    res = subprocess.run([sys.executable, "-m", "crashlab.cli", "reconstruct", str(path), "--no-progress"],
                         capture_output=True, text=True, timeout=300)
    assert_one_error_line(res, path, "evidence.rest.V1.sigma_xy", ["greater than 0"])


def test_speed_residual_uses_the_speed_at_first_contact():
    """The EDR speed is the speed at first contact (contact_si[:, 3], km/h), not the start speed."""
    ev = EvidenceSet(["V1", "V2"], [EvidenceItem("edr", "edr.V2", ("V2",), ("speed_at_impact",), (30.0,), (1.0,))])
    o = hand_made_outcome()
    assert ev.residuals([o])[0, 0] == pytest.approx(ms_to_kmh(o.contact_si[1, 3]) - 30.0, abs=1e-12)
