"""US customary units in the second opinion (issue 26 item 4; crashlab.reconstruction.refine): with the study's
shown units "us" (`--units us`), refine.csv, refine.md and the refine summary line show ft and mph, each column
named with its US unit; the RefineResult's own table stays in file units.

The expected columns are written here, and the factors are the exact definitions (1 ft = 0.3048 m, 1 mile =
1609.344 m; NIST SP 811), independent of the pint conversion the code uses."""
from __future__ import annotations

import re

import numpy as np
import pandas as pd
import pytest
from test_refine import _study

from crashlab.reconstruction import load_study, refine
from crashlab.reconstruction.refine import write_refine

FT, MPH = 0.3048, 1.609344  # m, km/h per US unit (exact by definition)


def us_columns(si_columns):
    """The refine.csv column each SI column becomes in US units: the speeds in mph, the objectives (thesis: m),
    the models' gap and the rest positions in ft; headings, sums of squares and counts as they are."""
    out = {}
    for c in si_columns:
        if c.endswith("V1.speed") or c.endswith("V2.speed"):
            out[c] = (f"{c} [mph]", MPH)
        elif re.fullmatch(r"(search|refine)_f_V[12](_start|_refined)?|model_gap_V[12]|\w+_rest_V[12]_[xy]", c):
            out[c] = (f"{c} [ft]", FT)
        else:
            out[c] = (c, 1.0)
    return out


@pytest.fixture(scope="module")
def refined(tmp_path_factory):
    """(the RefineResult, its study, the SI folder, the US folder): refined once with the impulse model, written
    in both units."""
    d = tmp_path_factory.mktemp("us_refine")
    study = load_study(_study(d))
    draws = pd.DataFrame({"V1.speed": [52.0], "V2.speed": [29.0]})
    res = refine(study, draws, d / "si", model="impulse", evaluations=6, n_candidates=1)
    study.shown_units = "us"
    write_refine(study, study.make_problem(), res, d / "us")
    return res, study, d / "si", d / "us"


def test_refine_csv_in_us_units(refined):
    res, _, si_dir, us_dir = refined
    si, us = pd.read_csv(si_dir / "refine.csv"), pd.read_csv(us_dir / "refine.csv")
    expected = us_columns(si.columns)
    assert list(us.columns) == [name for name, _ in expected.values()]
    assert "V1.speed [mph]" in us.columns and "search_rest_V2_y [ft]" in us.columns
    assert "search_rest_V1_heading" in us.columns and "refine_sumsq" in us.columns
    for c, (name, factor) in expected.items():
        if pd.api.types.is_numeric_dtype(si[c]):
            assert np.allclose(us[name].to_numpy(float), si[c].to_numpy(float) / factor, rtol=1e-12,
                               equal_nan=True), c
        else:
            assert us[name].tolist() == si[c].tolist(), c
    # the result's own table stays in file units (JSON, report.html convert it themselves)
    assert res.table["V1.speed"].iloc[0] == 52.0


def test_refine_md_in_us_units(refined):
    res, _, si_dir, us_dir = refined
    si, us = (p.joinpath("refine.md").read_text() for p in (si_dir, us_dir))
    assert "[m]" in si and "km/h" in si
    assert not re.search(r"\[m\]|km/h|\bin m\b", us), us
    assert "x, y [ft]" in us and "gap [ft]" in us and "mph" in us
    best = res.table.iloc[0]
    assert f"V1.speed {52.0 / MPH:.2f} -> {best['refined_V1.speed'] / MPH:.2f} mph" in us
    ev = refined[1].evidence["V1"]
    assert f"{ev[0] / FT:.2f}, {ev[1] / FT:.2f}" in us  # the measured rest position


def test_refine_summary_line_in_us_units(refined):
    res, study, _, _ = refined
    best = res.table.iloc[0]
    si = res.summary_line(study.variables, wrote=True)
    us = res.summary_line(study.variables, wrote=True, system="us")
    assert f"V1.speed {best['moved_V1.speed']:+.3f} km/h" in si
    assert f"V1.speed {best['moved_V1.speed'] / MPH:+.3f} mph" in us and "km/h" not in us
