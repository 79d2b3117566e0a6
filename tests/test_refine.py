"""The second opinion (issue 14, item 5; crashlab.reconstruction.refine): the best candidates simulated again
with another model and polished with it within `[refine] evaluations`.

The twin: side.toml's collision (V1 50 km/h, V2 30 km/h) simulated by the impulse model is the evidence (rest
poses, thesis objective). Refined with the impulse model itself from a start off the truth, the polish must
reach the truth (the residuals vanish there) and the refine model's values at the start must equal the search
model's (the same model, the same start). Refined with pymunk on a tiny budget: refine.csv's columns, the budget
kept, and the refine model's sum of squared residuals at the refined point never above the start's.
"""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from conftest import PC_CRASH, side_twin_study

from crashlab.cli import main
from crashlab.errors import InputError
from crashlab.reconstruction import load_study, refine

SIDE = PC_CRASH / "side.toml"

# tighter bounds than the other twins' (conftest.FREE_SPEEDS): the tiny search budget starts near the truth
TWIN = side_twin_study("twin for refine", pop_size=8, generations=2, polish=0, free="""[[free]]
vehicle = "V1"
field = "speed"
lower = 40.0
upper = 60.0
[[free]]
vehicle = "V2"
field = "speed"
lower = 20.0
upper = 40.0
""")


def _study(tmp_path, extra="", name="study.toml"):
    path = tmp_path / name
    path.write_text(TWIN + extra)
    return path


def _columns(labels, objectives, vehicles):
    cols = ["candidate", "row", "status", "refine_evaluations"]
    for lab in labels:
        cols += [lab, f"refined_{lab}", f"moved_{lab}"]
    cols.append("moved_norm")
    for n in objectives:
        cols += [f"search_f_{n}", f"refine_f_{n}_start", f"refine_f_{n}", f"search_f_{n}_refined"]
    cols += ["search_sumsq", "refine_sumsq_start", "refine_sumsq", "search_sumsq_refined"]
    for v in vehicles:
        cols.append(f"model_gap_{v}")
        for pre in ("search_rest", "refine_rest", "refined_rest"):
            cols += [f"{pre}_{v}_{q}" for q in ("x", "y", "heading")]
    return cols


def test_refine_with_the_search_model_reaches_the_truth(tmp_path):
    """Same model: at the start both columns agree exactly and the models' rest poses are 0 m apart; the polish
    from (52, 29) km/h reaches the truth within 0.05 km/h. The candidates may carry other columns (posterior
    draws: log_likelihood) and are taken best first."""
    study = load_study(_study(tmp_path))
    draws = pd.DataFrame({"V1.speed": [52.0, 47.0], "V2.speed": [29.0, 32.0], "log_likelihood": [-3.0, -9.0]})
    res = refine(study, draws, tmp_path / "out", model="impulse", evaluations=60, n_candidates=1,
                 source="posterior draws")
    row = res.table.iloc[0]
    assert len(res.table) == 1 and res.evaluations <= 60 and row["row"] == 0
    assert row["refine_f_V1_start"] == row["search_f_V1"] and row["refine_f_V2_start"] == row["search_f_V2"]
    assert row["model_gap_V1"] == 0.0 and row["model_gap_V2"] == 0.0
    assert row["refine_sumsq_start"] > 0.01  # the start is off the truth ...
    assert row["refine_sumsq"] < 1e-6  # ... the polished point is on it
    assert abs(row["refined_V1.speed"] - 50.0) < 0.05 and abs(row["refined_V2.speed"] - 30.0) < 0.05
    assert row["moved_V1.speed"] == pytest.approx(row["refined_V1.speed"] - 52.0)
    assert "posterior draws" in (tmp_path / "out" / "refine.md").read_text()


def test_refine_csv_columns_and_budget_with_pymunk(tmp_path):
    """pymunk, 6 evaluations: refine.csv has every column, one candidate per basin (spaced as the polish's
    starts), the budget is kept and the polish never ends above its start (under pymunk, whose rest poses
    differ from the impulse model's twin by decimetres)."""
    study = load_study(_study(tmp_path, '[refine]\nmodel = "pymunk"\nevaluations = 6\ncandidates = 2\n'))
    cands = pd.DataFrame({"V1.speed": [50.0, 50.1, 44.0], "V2.speed": [30.0, 30.1, 36.0]})  # row 1: row 0's basin
    res = refine(study, cands, tmp_path / "out")
    table = pd.read_csv(tmp_path / "out" / "refine.csv")
    assert list(table.columns) == _columns(["V1.speed", "V2.speed"], ["V1", "V2"], ["V1", "V2"])
    assert res.model == "pymunk" and res.search_model == "impulse" and res.budget == 6
    assert 1 <= res.evaluations <= 6 and table["row"].tolist() == [0, 2]
    assert table["refine_evaluations"].sum() + len(table) == res.evaluations
    polished = table[table.status == "polished"]
    assert len(polished) >= 1
    assert (polished.refine_sumsq <= polished.refine_sumsq_start).all()
    assert np.isfinite(table.model_gap_V1).all() and (table.model_gap_V1 > 0).all()  # two models, two answers
    assert (tmp_path / "out" / "refine.md").is_file()


@pytest.mark.parametrize("section, key", [
    ('[refine]\nmodel = "nosuchmodel"\n', "refine.model"),
    ('[refine]\nmodel = "pymunk"\nevaluations = 0\n', "refine.evaluations"),
    ('[refine]\nmodel = "pymunk"\nevaluations = 2.5\n', "refine.evaluations"),
    ('[refine]\nmodel = "pymunk"\nsteps = 3\n', "refine.steps"),
    ('[refine]\nmodel = "pymunk"\n[refine.model_options]\ndt = -1.0\n', "refine.model_options.dt"),
])
def test_bad_refine_is_one_line(tmp_path, capsys, section, key):
    """Bad [refine] input: one line naming the file and the key, exit 2, before any simulation."""
    path = _study(tmp_path, section)
    with pytest.raises(InputError):
        load_study(path)
    assert main(["reconstruct", str(path), "--no-progress"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and str(path) in err and key in err


def test_refine_without_section_or_candidates(tmp_path):
    """refine() of a study without [refine] and no model given is refused naming `refine`; candidates that name
    none of the variables are refused; no candidates give an empty table."""
    study = load_study(_study(tmp_path))
    with pytest.raises(InputError, match="refine"):
        refine(study, pd.DataFrame({"V1.speed": [50.0]}))
    with pytest.raises(InputError, match="none of the variables"):
        refine(study, pd.DataFrame({"speed": [50.0]}), model="impulse")
    assert len(refine(study, pd.DataFrame(columns=["V1.speed", "V2.speed"]), model="impulse").table) == 0


def test_reconstruct_with_refine_puts_it_on_the_report_page(tmp_path):
    """`[refine]` in the study: the search, then the second opinion, and report.html (written before it) shows
    refine.md and refine.csv."""
    path = _study(tmp_path, '[refine]\nmodel = "impulse"\nevaluations = 4\n')
    out = tmp_path / "out"
    res = load_study(path).run(out_dir=out)
    assert res.refine is not None and (out / "refine.csv").is_file()
    page = (out / "report.html").read_text()
    assert "refine.md" in page or "Second opinion" in page or "second opinion" in page
    assert (out / "refine.md").read_text().splitlines()[0].strip("# ") in page


def test_infer_with_refine_refines_the_most_likely_draws(tmp_path):
    """`[refine]` in a posterior study: after sampling, the most likely draws get the second opinion
    (source "posterior draws"), refine.csv is written and report.html shows it."""
    from crashlab.reconstruction.infer import run_posterior
    from crashlab.reconstruction.posterior import load_posterior
    twin_infer = SIDE.parents[1] / "infer" / "twin_infer.toml"
    text = twin_infer.read_text().replace('scene = "../pc_crash/side.toml"', f'scene = "{SIDE.as_posix()}"')
    path = tmp_path / "infer_refine.toml"
    path.write_text(text + '\n[refine]\nmodel = "impulse"\nevaluations = 6\ncandidates = 1\n')
    post = load_posterior(path)
    post.settings = post.settings.model_copy(update={"walkers": 8, "burn": 4, "samples": 80, "draws_plotted": 2})
    res = run_posterior(post, tmp_path / "out", progress=False)
    assert res.refine is not None and res.refine.source == "posterior draws"
    table = pd.read_csv(tmp_path / "out" / "refine.csv")
    best = np.argmax(res.log_likelihood)
    assert table.loc[0, "V1.speed"] == pytest.approx(res.samples[best, res.labels.index("V1.speed")], abs=1e-9)
    assert table.loc[0, "refine_sumsq"] <= table.loc[0, "refine_sumsq_start"] + 1e-12
    assert "posterior draws" in (tmp_path / "out" / "report.html").read_text()
