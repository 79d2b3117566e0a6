"""`crashlab study NAME --units us` (issue 26 item 4): every study's CSV, markdown and summary page in US customary
units, each column named with its unit (crashlab.comparison.base: the columns' unit suffixes, the units map's
patterns; validation.csv by its unit column); degrees, seconds, counts as they are.

The expected columns are written here, and the factors are the exact definitions (1 ft = 0.3048 m, 1 mile =
1609.344 m; NIST SP 811), independent of the pint conversion the code uses."""
from __future__ import annotations

import contextlib
import io
import re

import numpy as np
import pandas as pd
import pytest

from crashlab.cli.main import main
from crashlab.comparison import pc_crash, stability, validation, workprecision
from crashlab.comparison.base import write_table
from crashlab.comparison.report import write_report

FT, MPH = 0.3048, 1.609344  # m, km/h per US unit (exact by definition)

PC_CRASH_US = {"x": ("x [ft]", FT), "y": ("y [ft]", FT), "engagement_depth": ("engagement_depth [ft]", FT),
               "d_pc_crash_m": ("d_pc_crash_ft", FT), "delta_v": ("delta_v [mph]", MPH),
               "dvx": ("dvx [mph]", MPH), "dvy": ("dvy [mph]", MPH)}
WORKPRECISION_US = {"error_m": ("error_ft", FT)}
CONVERGED_US = {"converged_check_m": ("converged_check_ft", FT)}
STABILITY_US = {"speed_kmh": ("speed_mph", MPH), "offset_m": ("offset_ft", FT)}


def assert_converted(si: pd.DataFrame, us: pd.DataFrame, expected: dict) -> None:
    """us has si's columns in order, those of `expected` renamed and divided by their factor, the others equal."""
    assert list(us.columns) == [expected.get(c, (c,))[0] for c in si.columns]
    for c in si.columns:
        name, factor = expected.get(c, (c, 1.0))
        if pd.api.types.is_numeric_dtype(si[c]) and not pd.api.types.is_bool_dtype(si[c]):
            assert np.allclose(us[name].to_numpy(float), si[c].to_numpy(float) / factor, rtol=1e-12,
                               equal_nan=True), c
        else:
            assert us[name].astype(str).tolist() == si[c].astype(str).tolist(), c


@pytest.mark.parametrize("columns, expected", [(workprecision.COLUMNS, WORKPRECISION_US),
                                               (workprecision.CONVERGED_COLUMNS, CONVERGED_US),
                                               (list(stability.COLUMNS), STABILITY_US)])
def test_each_studys_csv_columns_in_us_units(tmp_path, columns, expected):
    """A table with every column of the study's contract (numbers 1.5, 2.5): the length and speed columns
    converted and renamed by their suffix, the rest as they are."""
    si = pd.DataFrame({c: [1.5, 2.5] for c in columns})
    write_table(si, tmp_path / "us.csv", "us")
    write_table(si, tmp_path / "si.csv")
    assert_converted(pd.read_csv(tmp_path / "si.csv"), pd.read_csv(tmp_path / "us.csv"), expected)
    assert list(pd.read_csv(tmp_path / "si.csv").columns) == list(columns)


def test_validation_rows_by_their_unit(tmp_path):
    rows = [{"model": "impulse", "test": "t", "quantity": q, "published": p, "simulated": s, "error": s - p,
             "error_pct": 100 * (s - p) / p, "unit": u, "source": "src", "ok": True, "kind": "crash test",
             "vehicle": "V1", "law": "-", "restitution": "0.1", "contact": "found", "impacts": 1,
             "slip_reversed": False, "_reason": ""}
            for q, p, s, u in (("delta_v", 40.0, 42.0, "km/h"), ("crush_residual", 0.5, 0.4, "m"),
                               ("pdof", 10.0, 12.0, "deg"))]
    validation.write_csv(rows, tmp_path / "si.csv")
    validation.write_csv(rows, tmp_path / "us.csv", "us")
    si, us = pd.read_csv(tmp_path / "si.csv"), pd.read_csv(tmp_path / "us.csv")
    assert list(us.columns) == list(si.columns) == validation.COLUMNS
    assert us.unit.tolist() == ["mph", "ft", "deg"]
    for c in ("published", "simulated", "error"):
        assert np.allclose(us[c], si[c] / np.array([MPH, FT, 1.0]), rtol=1e-12), c
    assert np.allclose(us.error_pct, si.error_pct, rtol=1e-12)


def _pc_rows():
    return [{"case": "side", "model": "impulse", "law": "-", "contact": "engagement", "engagement_depth": 0.5,
             "vehicle": v, "ok": True, "x": 6.0 + k, "y": 1.5, "heading": 26.0, "at_rest": True,
             "d_pc_crash_m": 0.25 + k, "d_pc_crash_deg": 3.0, "delta_v": 20.0 + k, "dvx": 12.0, "dvy": -16.0,
             "impacts": 1, "kinds": "impact", "slip_reversed": False, "warnings": ""}
            for k, v in enumerate(("V1", "V2"))]


def test_pc_crash_csv_and_markdown_in_us_units(tmp_path):
    rows = _pc_rows()
    pc_crash.write_csv(rows, tmp_path / "si.csv")
    pc_crash.write_csv(rows, tmp_path / "us.csv", "us")
    assert_converted(pd.read_csv(tmp_path / "si.csv"), pd.read_csv(tmp_path / "us.csv"), PC_CRASH_US)
    si, us = pc_crash.markdown(rows), pc_crash.markdown(rows, "us")
    assert "V1 dist m" in si and "dV V1 km/h" in si
    assert "V1 dist ft" in us and "dV V1 mph" in us and not re.search(r"\[m\]| m \||km/h", us)
    line = next(s for s in us.splitlines() if s.startswith("| impulse"))
    assert f"engagement {0.5 / FT:.3g}" in line and f"| {0.25 / FT:.2f} |" in line and f"| {21.0 / MPH:.2f} |" in line


def test_the_summary_page_reads_the_us_csvs(tmp_path):
    """write_report(system="us") summarises the CSVs written in US units (no "summary not available")."""
    pc_crash.write_csv(_pc_rows(), tmp_path / "pc_crash.csv", "us")
    write_table(pd.DataFrame({"model": ["impulse"], "scene": ["side"], "setting": ["{}"], "wall_time_s": [1e-3],
                              "error_m": [0.01], "error_deg": [0.1], "error_kind": ["numerical"]}),
                tmp_path / "workprecision.csv", "us")
    page = write_report(tmp_path, system="us").read_text()
    assert "summary not available" not in page
    assert "error_ft" in page and "d_pc_crash_ft" in page and "engagement_depth [ft]" in page
    assert f"{0.25 / FT:.4g}" in page  # V1's distance to PC-Crash, in ft


@pytest.mark.slow
def test_the_study_command_writes_us_units(tmp_path):
    """`crashlab study pc_crash --models impulse --quick --units us`: pc_crash.csv is the SI run's in US units."""
    for units in ("si", "us"):
        with contextlib.redirect_stdout(io.StringIO()):
            assert main(["study", "pc_crash", "--models", "impulse", "--quick", "--units", units, "--out",
                         str(tmp_path / units)]) == 0
    assert_converted(pd.read_csv(tmp_path / "si" / "pc_crash.csv"), pd.read_csv(tmp_path / "us" / "pc_crash.csv"),
                     PC_CRASH_US)
    assert "dV V1 mph" in (tmp_path / "us" / "pc_crash.md").read_text()


def test_the_study_command_passes_its_units(tmp_path, monkeypatch):
    """`--units` reaches the study's run and the page (the wiring; the run itself: the slow test above)."""
    seen = []

    def run(models, out, quick=False, system="si"):
        seen.append(system)
        return out / "pc_crash.csv"
    monkeypatch.setattr(pc_crash, "run", run)
    with contextlib.redirect_stdout(io.StringIO()):
        assert main(["study", "pc_crash", "--models", "impulse", "--units", "us", "--out", str(tmp_path)]) == 0
        assert main(["study", "pc_crash", "--models", "impulse", "--out", str(tmp_path)]) == 0
    assert seen == ["us", "si"]


@pytest.fixture
def saved(monkeypatch):
    """{file name: figure} of every figure saved while the test runs."""
    from pathlib import Path

    from matplotlib.figure import Figure
    figures = {}
    real = Figure.savefig

    def savefig(fig, path, *a, **k):
        figures[Path(str(path)).name] = fig
        return real(fig, path, *a, **k)
    monkeypatch.setattr(Figure, "savefig", savefig)
    return figures


def test_the_studies_figures_in_us_units(tmp_path, saved):
    """The work-precision diagram's error in ft, the stability heat map's speed bins and the validation
    figure's delta-V in mph (the values on the axes, not only their labels)."""
    df = pd.DataFrame({"model": "impulse", "scene": "side", "setting": ['{}', '{"dt": 0.004}'],
                       "wall_time_s": [1e-3, 5e-4], "error_m": [0.01, 0.04], "error_deg": 0.1,
                       "error_kind": "numerical", "knob": ["", "dt"], "is_default": [True, False], "ok": True})
    conv = pd.DataFrame({"model": ["impulse"], "scene": ["side"], "wall_time_s": [2e-3], "converged_check_m": [0.001]})
    workprecision.plot(df, conv, "side", tmp_path / "wp.png", "us")
    ax = saved["wp.png"].axes[0]
    assert ax.get_ylabel().endswith("[ft]")
    assert sorted(ax.get_lines()[0].get_ydata()) == pytest.approx([0.01 / FT, 0.04 / FT], rel=1e-12)
    st = pd.DataFrame({"model": "impulse", "setting": "{}", "speed_kmh": [30.0, 120.0], "angle_deg": [10.0, 90.0],
                       "ok": [True, False]})
    stability.heatmap(st, "impulse", tmp_path / "st.png", "us")
    ax = saved["st.png"].axes[0]
    assert ax.get_ylabel() == "speed of V1 [mph]"
    assert np.allclose(ax.get_yticks(), np.asarray(stability.SPEED_BINS) / MPH, rtol=1e-12)
    rows = [{"ok": True, "kind": "crash test", "quantity": next(iter(validation.DV_QUANTITIES)), "test": "t",
             "model": "impulse", "law": "-", "contact": "found", "restitution": "0.1", "published": 40.0,
             "simulated": 42.0, "error": 2.0, "unit": "km/h"}]
    from crashlab.comparison.base import shown_rows
    validation.write_figure(shown_rows(rows, "us"), tmp_path / "v.png", "mph")
    ax = saved["v.png"].axes[0]
    assert ax.get_xlabel() == "measured delta-V [mph]" and ax.get_ylabel() == "simulated delta-V [mph]"
    points = [c.get_offsets() for c in ax.collections if len(c.get_offsets())]
    assert any(np.allclose(p, [[40.0 / MPH, 42.0 / MPH]]) for p in points)
