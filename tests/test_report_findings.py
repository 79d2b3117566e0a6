"""What a fuzz of the reports found (fuzz15): a question's numbers shown beside US values without their units
(D1), `reconstruct --json --units us`'s refine block left in km/h and m (D2), posterior.csv written with 6
significant digits so that `crashlab avoid` answered on other draws than infer (D3), and report.html's refine
table showing its integer columns as "0.000" (D5).

Each test runs a small posterior or refine of side.toml's twin (studies/infer/twin_infer.toml, the impulse
model, serial)."""
from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from conftest import PC_CRASH, side_twin_study

from crashlab.reconstruction import html_sections, load_study, refine
from crashlab.reconstruction.infer import run_posterior
from crashlab.reconstruction.posterior import load_posterior
from crashlab.units import table_from_shown

FT, MPH = 0.3048, 1.609344  # m, km/h per US unit (exact by definition)
REPO = Path(__file__).resolve().parent.parent
TWIN_INFER = REPO / "studies" / "infer" / "twin_infer.toml"
SIDE = PC_CRASH / "side.toml"


def _twin_infer(tmp_path: Path, us_file: bool = False) -> Path:
    """twin_infer.toml with an absolute scene path; us_file: written in US units (its bounds in mph, its
    questions as a user writes them in mph)."""
    text = TWIN_INFER.read_text().replace('scene = "../pc_crash/side.toml"', f'scene = "{SIDE.as_posix()}"')
    if us_file:
        for old, new in (("lower = 30.0", "lower = 18.6"), ("upper = 70.0", "upper = 43.5"),
                         ("lower = 10.0", "lower = 6.2"), ("upper = 50.0", "upper = 31.1"),
                         ('expr = "V1.speed > 50"', 'expr = "V1.speed > 31"'),
                         ("sigma_xy = 0.2        # m", "sigma_xy = 0.66"), ("sigma_xy = 0.2\n", "sigma_xy = 0.66\n")):
            assert old in text, old
            text = text.replace(old, new)
        text = 'units = "us"\n' + text
    path = tmp_path / ("twin_us.toml" if us_file else "twin.toml")
    path.write_text(text)
    return path


@pytest.fixture(scope="module")
def infer_us(tmp_path_factory):
    """A tiny posterior of the SI study file shown in US units (--units us)."""
    tmp = tmp_path_factory.mktemp("infer_us")
    post = load_posterior(_twin_infer(tmp))
    post.study.shown_units = "us"
    post.settings = post.settings.model_copy(update={"walkers": 8, "burn": 4, "samples": 160, "draws_plotted": 0})
    res = run_posterior(post, tmp / "out", progress=False)
    return post, res, tmp / "out"


def _questions_table(md: str) -> list[str]:
    lines = md.split("## Questions", 1)[1].strip().splitlines()
    return [ln for ln in lines if ln.startswith("|")]


# ------------------------------------------------------------------ D1: a question's units
def test_questions_say_they_are_in_the_study_files_units_under_units_us(infer_us):
    """`V1.speed > 50` is answered in km/h (the study file's units) while the tables around it show mph:
    summary.md and report.html say so, per question and in a note, and show the expression as written."""
    post, _, out = infer_us
    rows = _questions_table((out / "summary.md").read_text())
    assert "the study file's" in rows[0]
    assert rows[2].startswith("| `V1.speed > 50` |") and rows[2].endswith("| V1.speed in km/h |")
    assert rows[3].endswith("| V1.speed in km/h, V2.speed in km/h |")
    md = (out / "summary.md").read_text()
    assert 'in the study file\'s units (units = "si": km/h) whatever --units shows' in md
    page = (out / "report.html").read_text()
    table = page.split('<table id="questions">', 1)[1].split("</table>", 1)[0]
    assert "the study file&#39;s" in table and "km/h" in table and "mph" not in table
    assert re.search(r"<code>V1\.speed &gt; 50</code></td>.*<td class=\"text\">V1\.speed in km/h</td>", table)


def test_a_us_study_files_questions_say_mph_as_written(tmp_path):
    """A study file in US units: its question's number is mph, shown as the user wrote it (not converted)."""
    from crashlab.reconstruction.infer_report import question_note, question_units
    post = load_posterior(_twin_infer(tmp_path, us_file=True))
    assert [q.expr for q in post.questions][0] == "V1.speed > 31"
    assert question_units(post) == ["V1.speed in mph", "V1.speed in mph, V2.speed in mph"]
    assert '(units = "us": mph)' in question_note(post)


# ------------------------------------------------------------------ D3: posterior.csv in full
def test_posterior_csv_gives_back_every_draw_exactly(infer_us, tmp_path):
    """posterior.csv reads back (crashlab avoid: table_from_shown) to infer's own draws: exactly in file
    units, to the last bit but one in US units (x / f * f)."""
    post, res, out = infer_us
    back = table_from_shown(pd.read_csv(out / "posterior.csv"))
    for j, lab in enumerate(res.labels):
        np.testing.assert_allclose(back[lab].to_numpy(), res.samples[:, j], rtol=4e-16, atol=0)
    np.testing.assert_array_equal(back["log_likelihood"].to_numpy(), res.log_likelihood)
    post.study.shown_units = "si"
    try:
        from crashlab.reconstruction.infer_report import write_posterior_csv
        write_posterior_csv(post, res, tmp_path / "posterior.csv")
    finally:
        post.study.shown_units = "us"
    si = pd.read_csv(tmp_path / "posterior.csv")
    for j, lab in enumerate(res.labels):
        np.testing.assert_array_equal(si[lab].to_numpy(), res.samples[:, j])


# ------------------------------------------------------------------ D2, D5: refine in US units, its table
@pytest.fixture(scope="module")
def refined(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("refine")
    (tmp / "study.toml").write_text(side_twin_study("twin for refine", pop_size=8, generations=2, polish=0))
    study = load_study(tmp / "study.toml")
    study.shown_units = "us"
    draws = pd.DataFrame({"V1.speed": [52.0, 44.0], "V2.speed": [29.0, 36.0]})
    res = refine(study, draws, tmp / "out", model="impulse", evaluations=8, n_candidates=2)
    return res, tmp / "out"


def test_refine_json_in_us_units_matches_refine_csv(refined):
    """RefineResult.to_json_dict("us"): every number with a US unit converted, as refine.csv shows it, and its
    "units" map saying so; to_json_dict() stays in file units; counts and sums of squares are not converted."""
    res, out = refined
    si, us = res.to_json_dict(), res.to_json_dict("us")
    csv = pd.read_csv(out / "refine.csv")
    assert json.loads(json.dumps(us)) == us  # plain JSON
    assert us["units"]["V1.speed"] == "mph" and us["units"]["search_f_<n>"] == "ft"
    assert si["units"]["V1.speed"] == "km/h" and si["units"]["search_f_<n>"] == "m"
    for k, (a, b) in enumerate(zip(si["candidates"], us["candidates"])):
        assert b["V1.speed"] == pytest.approx(a["V1.speed"] / MPH, rel=1e-12)
        assert b["V1.speed"] == pytest.approx(csv.loc[k, "V1.speed [mph]"], rel=1e-12)
        assert b["moved_V2.speed"] == pytest.approx(a["moved_V2.speed"] / MPH, rel=1e-12, abs=1e-12)
        assert b["search_f_V1"] == pytest.approx(a["search_f_V1"] / FT, rel=1e-12)
        assert b["search_f_V1"] == pytest.approx(csv.loc[k, "search_f_V1 [ft]"], rel=1e-12)
        assert b["search_rest_V2_x"] == pytest.approx(a["search_rest_V2_x"] / FT, rel=1e-12)
        for key in ("candidate", "row", "refine_evaluations", "search_rest_V1_heading", "refine_sumsq",
                    "moved_norm"):
            assert b[key] == a[key], key
    assert us["evaluations"] == si["evaluations"] and us["budget"] == si["budget"]


def test_report_refine_table_shows_integers_as_integers(refined):
    """report.html's refine.csv table: candidate, row and refine_evaluations as integers, not "0.000"."""
    _, out = refined
    table = html_sections.refine_context(out)["csv"]
    head = table.header
    for row in table.rows:
        for col in ("candidate", "row", "refine_evaluations"):
            assert re.fullmatch(r"-?\d+", row[head.index(col)]), (col, row[head.index(col)])
    assert [r[head.index("candidate")] for r in table.rows] == ["0", "1"]
    assert re.fullmatch(r"-?\d+\.\d{3}", table.rows[0][head.index("V1.speed [mph]")])
