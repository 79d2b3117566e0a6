"""US customary units in the reconstruction (issue 26 item 4): a study written in ft, mph and lb (`units = "us"`)
gives the same Pareto set and posterior as its SI twin (1e-9 relative, small budgets, fixed seeds), and
`--units us` shows every table reconstruct, infer, avoid and the Monte Carlo print or write in US units: every
column with a length or a speed converted and named with its US unit, no SI unit left in a header.

The twin and the expected columns are written here with the exact definitions (1 ft = 0.3048 m, 1 mile =
1609.344 m, 1 lb = 0.45359237 kg; NIST SP 811), independent of the pint conversion the code uses."""
from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from crashlab.cli.main import main

FT, MPH, LB = 0.3048, 1.609344, 0.45359237  # m, km/h, kg per US unit (exact by definition)
REPO = Path(__file__).resolve().parent.parent
SIDE = REPO / "studies" / "pc_crash" / "side.toml"

STUDY = """{units}
name = "US study twin"
scene = "{scene}"
model = "impulse"
free = [{{vehicle = "V1", field = "speed", lower = {v_lo}, upper = {v_hi}}},
        {{vehicle = "V2", field = "x", lower = {x_lo}, upper = {x_hi}}}]

[optimizer]
name = "nsga2"
pop_size = 8
generations = 2
seed = 1

[evidence.rest]
V1 = {{x = {r1x}, y = {r1y}, heading = 26.0, sigma_xy = {sxy}, sigma_heading = 5.0}}
V2 = {{x = {r2x}, y = {r2y}, sigma_xy = {sxy}}}

[evidence.impact]
x = {ix}
y = {iy}
sigma = {isig}

[[evidence.marks]]
vehicle = "V1"
points = [[{m0}, 0.0], [{m1}, {m2}]]
sigma = {msig}

[evidence.edr.V1]
speed_at_impact = {edr}
sigma_speed = {edrs}

[repair]
max_shift = {shift}

[polish]
evaluations = 0

[execution]
backend = "serial"
timeout_s = 0

[infer]
walkers = 8
burn = 4
samples = 32
draws_plotted = 0
seed = 2

[[questions]]
expr = "V1.speed > {q}"

[[uncertain]]
field = "vehicles.V2.speed"
distribution = "normal"
mean = {u_mean}
sd = {u_sd}
lower = {u_lo}
upper = {u_hi}

[[counterfactuals]]
name = "slower"
set = {{ "vehicles.V1.speed" = {cf_set} }}
shift = {{ "vehicles.V1.x" = {cf_shift} }}
"""
SI = dict(v_lo=40.0, v_hi=60.0, x_lo=2.5, x_hi=4.5, r1x=6.66, r1y=1.64, sxy=0.3, r2x=8.04, r2y=5.97, ix=2.6,
          iy=0.4, isig=1.0, m0=0.0, m1=1.0, m2=0.05, msig=0.5, edr=48.0, edrs=3.0, shift=1.0, q=50.0,
          u_mean=30.0, u_sd=2.0, u_lo=24.0, u_hi=36.0, cf_set=40.0, cf_shift=-1.0)
LENGTHS = {"x_lo", "x_hi", "r1x", "r1y", "sxy", "r2x", "r2y", "ix", "iy", "isig", "m0", "m1", "m2", "msig", "shift",
           "cf_shift"}
SPEEDS = {"v_lo", "v_hi", "edr", "edrs", "q", "u_mean", "u_sd", "u_lo", "u_hi", "cf_set"}


@pytest.fixture(scope="module")
def twins(tmp_path_factory):
    """(si.toml, us.toml): the same study, the second written in ft and mph."""
    d = tmp_path_factory.mktemp("us_study")
    us = {k: v / FT if k in LENGTHS else v / MPH if k in SPEEDS else v for k, v in SI.items()}
    paths = d / "si.toml", d / "us.toml"
    for path, units, values in zip(paths, ("", 'units = "us"'), (SI, us)):
        path.write_text(STUDY.format(units=units, scene=SIDE.as_posix(), **{k: repr(v) for k, v in values.items()}))
    return paths


def close(a, b, rel=1e-9, atol=0.0):
    a, b = np.asarray(a, float), np.asarray(b, float)
    assert a.shape == b.shape
    assert np.all(np.isnan(a) == np.isnan(b))
    ok = ~np.isnan(a)
    assert np.all(np.abs(a[ok] - b[ok]) <= rel * np.maximum(1.0, np.abs(a[ok])) + atol), np.max(np.abs(a[ok] - b[ok]))


# ------------------------------------------------------------------ a study in US units
def test_the_us_study_is_read_into_the_si_study(twins):
    from crashlab.reconstruction.posterior import load_posterior
    a, b = (load_posterior(p) for p in twins)
    for va, vb in zip(a.variables, b.variables, strict=True):
        assert (va.label, va.path, va.unit) == (vb.label, vb.path, vb.unit)
        close([va.lower, va.upper], [vb.lower, vb.upper], 1e-12)
    assert b.variables[2].prior.mean == pytest.approx(30.0, rel=1e-12)
    assert b.variables[2].prior.sd == pytest.approx(2.0, rel=1e-12)
    for ia, ib in zip(a.study.evidence_set.items, b.study.evidence_set.items, strict=True):
        assert ia.label == ib.label and ia.components == ib.components
        close(ia.values, ib.values, 1e-12)
        close(ia.sigmas, ib.sigmas, 1e-12)
        if ia.points is not None:
            close(ia.points, ib.points, 1e-12)
    assert b.study.spec.repair.max_shift == pytest.approx(1.0, rel=1e-12)
    (ca,), (cb,) = a.counterfactuals, b.counterfactuals
    close([v for _, _, v in ca.changes], [v for _, _, v in cb.changes], 1e-12)


def test_the_us_study_gives_the_si_studys_pareto_set(twins):
    from crashlab.reconstruction.study import load_study
    a, b = (load_study(p).run() for p in twins)
    assert len(a.pareto) > 0 and list(a.pareto.columns) == list(b.pareto.columns)
    numeric = a.pareto.select_dtypes("number").columns
    close(a.pareto[numeric], b.pareto[numeric])


def test_the_us_study_gives_the_si_studys_posterior_and_answers(twins):
    from crashlab.reconstruction.infer import run_posterior
    from crashlab.reconstruction.infer_report import question_rows
    from crashlab.reconstruction.posterior import load_posterior
    posts = [load_posterior(p) for p in twins]
    a, b = (run_posterior(p, progress=False) for p in posts)
    close(a.samples, b.samples)
    close(a.log_likelihood, b.log_likelihood)
    # "V1.speed > 50" (km/h) and "V1.speed > 31.07" (mph): the same question, the same share of the draws
    (_, pa, _), = question_rows(posts[0], a)
    (_, pb, _), = question_rows(posts[1], b)
    assert pa == pb
    close([r["p_avoided"] for r in a.counterfactuals], [r["p_avoided"] for r in b.counterfactuals])
    close([r["V1.impact_speed_50"] for r in a.counterfactuals], [r["V1.impact_speed_50"] for r in b.counterfactuals])


# ------------------------------------------------------------------ --units us: what is printed and written
SI_HEADS = re.compile(r"\[(m|km/h|kg|J|N|kJ)[,\]]|_kmh\b")


def no_si_headers(text: str) -> list[str]:
    """The lines of printed output with an SI unit in a header ([m], [km/h], ...)."""
    return [line for line in text.splitlines() if SI_HEADS.search(line)]


# pareto.csv / failures.csv / near_optimal.csv: every column of the SI file with a length or a speed, the US
# header it must get and the factor (US value = SI value / factor); every other column must stay as it is
PARETO_US = {"V1.speed": ("V1.speed [mph]", MPH), "V2.x": ("V2.x [ft]", FT), "V2.speed": ("V2.speed [mph]", MPH)}
for _n in ("V1", "V2"):
    PARETO_US |= {f"rest_{_n}_x": (f"rest_{_n}_x [ft]", FT), f"rest_{_n}_y": (f"rest_{_n}_y [ft]", FT),
                  f"contact_{_n}_x": (f"contact_{_n}_x [ft]", FT), f"contact_{_n}_y": (f"contact_{_n}_y [ft]", FT),
                  f"contact_{_n}_speed": (f"contact_{_n}_speed [mph]", MPH)}
TIME_DISTANCE_US = {"s": ("s [ft]", FT), "speed": ("speed [mph]", MPH), "to_impact": ("to_impact [ft]", FT)}
POSTERIOR_US = {"V1.speed": ("V1.speed [mph]", MPH), "V2.x": ("V2.x [ft]", FT), "V2.speed": ("V2.speed [mph]", MPH)}
COUNTERFACTUALS_US = {f"{n}.{q}_{p}": (f"{n}.{q}_{p} [mph]", MPH) for n in ("V1", "V2")
                      for q in ("impact_speed", "delta_v") for p in (5, 50, 95)} | {
    f"miss_distance_{p}": (f"miss_distance_{p} [ft]", FT) for p in (5, 50, 95)}


def assert_converted(si_csv: Path, us_csv: Path, expected: dict, decimals: int | None = None) -> None:
    """Every column of the SI file in the US file: the expected ones renamed and divided by their factor, the
    others as they are (same name, same values); decimals: the files' rounding (else 6 significant digits)."""
    a, b = pd.read_csv(si_csv), pd.read_csv(us_csv)
    assert len(a.columns) == len(b.columns) and len(a) == len(b)
    for ca, cb in zip(a.columns, b.columns):
        name, factor = expected.get(ca, (ca, 1.0))
        assert cb == name, (us_csv.name, ca, cb)
        if pd.api.types.is_numeric_dtype(a[ca]) and not pd.api.types.is_bool_dtype(a[ca]):
            atol = 0.0 if decimals is None else 10.0 ** -decimals / min(factor, 1.0)  # both files' rounding
            close(b[cb], a[ca] / factor, 1e-5, atol)  # (CSV text: 6 significant digits and more)
        else:
            assert a[ca].astype(str).tolist() == b[cb].astype(str).tolist(), ca


@pytest.fixture(scope="module")
def reconstructed(twins, tmp_path_factory):
    """`crashlab reconstruct si.toml --out DIR` in SI and in US units: (the printed outputs, the folders)."""
    import contextlib
    import io
    d = tmp_path_factory.mktemp("reconstructed")
    printed = {}
    for units in ("si", "us"):
        buf = io.StringIO()
        with contextlib.redirect_stdout(buf):
            assert main(["reconstruct", str(twins[0]), "--no-progress", "--units", units, "--out",
                         str(d / units)]) == 0
        printed[units] = buf.getvalue()
    return printed, d


def test_reconstruct_prints_and_writes_us_units(reconstructed):
    printed, d = reconstructed
    assert not no_si_headers(printed["us"]), no_si_headers(printed["us"])
    assert "V1.speed [mph]" in printed["us"] and "V2.x [ft]" in printed["us"]
    assert "V1.speed [km/h]" in printed["si"]
    for name in ("pareto.csv", "failures.csv", "near_optimal.csv"):
        assert_converted(d / "si" / name, d / "us" / name, PARETO_US)
    assert_converted(d / "si" / "time_distance.csv", d / "us" / "time_distance.csv", TIME_DISTANCE_US, 4)
    summary = (d / "us" / "summary.md").read_text()
    assert "V1.speed [mph]" in summary and "V2.x [ft]" in summary
    page = (d / "us" / "report.html").read_text().replace("<wbr>", "")
    for head in ("speed at impact [mph]", "delta-V [mph]", "energy dissipated [ft-lbf]", "mass [lb]", "x [ft]",
                 "V1.speed [mph]"):
        assert head in page, head
    assert not re.search(r"\[(km/h|kg|kJ)\]", page)


def test_reconstruct_json_in_us_units(twins):
    import contextlib
    import io
    import json
    out = {}
    for units in ("si", "us"):
        buf = io.StringIO()
        with contextlib.redirect_stdout(buf):
            assert main(["reconstruct", str(twins[0]), "--json", "--units", units]) == 0
        out[units] = json.loads(buf.getvalue())
    a, b = out["si"]["pareto"][0], out["us"]["pareto"][0]
    assert b["start"]["V1.speed"] == pytest.approx(a["start"]["V1.speed"] / MPH, rel=1e-9)
    assert b["start"]["V2.x"] == pytest.approx(a["start"]["V2.x"] / FT, rel=1e-9)
    assert b["rest"]["V1"]["x"] == pytest.approx(a["rest"]["V1"]["x"] / FT, rel=1e-9)
    assert b["rest"]["V1"]["heading"] == a["rest"]["V1"]["heading"]
    assert b["objectives"] == a["objectives"]  # sigmas
    assert out["us"]["units"]["V1.speed"] == "mph" and out["us"]["units"]["rest_<vehicle>_x"] == "ft"


def test_infer_and_avoid_print_and_write_us_units(twins, tmp_path, capsys):
    for units in ("si", "us"):
        assert main(["infer", str(twins[0]), "--no-progress", "--units", units, "--out", str(tmp_path / units)]) == 0
    printed = capsys.readouterr().out
    us_part = printed[printed.index("V1.speed [mph]"):]
    assert not no_si_headers(us_part), no_si_headers(us_part)
    assert "V2.x [ft]" in us_part and "median impact speed" in us_part and "mph" in us_part
    assert_converted(tmp_path / "si" / "posterior.csv", tmp_path / "us" / "posterior.csv", POSTERIOR_US)
    assert_converted(tmp_path / "si" / "counterfactuals.csv", tmp_path / "us" / "counterfactuals.csv",
                     COUNTERFACTUALS_US)
    assert_converted(tmp_path / "si" / "time_distance.csv", tmp_path / "us" / "time_distance.csv", TIME_DISTANCE_US, 4)
    summary = (tmp_path / "us" / "summary.md").read_text()
    assert "| V1.speed | mph |" in summary and "| V2.x | ft |" in summary
    page = (tmp_path / "us" / "report.html").read_text().replace("<wbr>", "")
    assert "speed at impact [mph]" in page and not re.search(r"\[(km/h|kg|kJ)\]", page)
    # avoid reads the US posterior.csv back (its columns say their unit) and answers as on the SI one
    si_answers = pd.read_csv(tmp_path / "si" / "counterfactuals.csv")
    assert main(["avoid", str(twins[0]), "--units", "us", "--out", str(tmp_path / "us")]) == 0
    avoid_printed = capsys.readouterr().out
    assert "mph" in avoid_printed and "km/h" not in avoid_printed
    assert_converted(tmp_path / "si" / "counterfactuals.csv", tmp_path / "us" / "counterfactuals.csv",
                     COUNTERFACTUALS_US)
    assert main(["avoid", str(twins[0]), "--out", str(tmp_path / "us")]) == 0  # SI answers from the US draws
    close(pd.read_csv(tmp_path / "us" / "counterfactuals.csv")["p_avoided"], si_answers["p_avoided"])


def test_monte_carlo_prints_and_writes_us_units(tmp_path, capsys):
    import crashlab
    from crashlab.reconstruction import montecarlo
    from crashlab.scene_file import load_scene
    result = montecarlo.run(load_scene(REPO / "studies" / "montecarlo" / "side.toml"), crashlab.get_model("impulse"),
                            12, seed=3)
    montecarlo.print_summary(result, system="us")
    text = capsys.readouterr().out
    assert not no_si_headers(text) and " km/h" not in text and " m;" not in text and " ft" in text and "mph" in text
    montecarlo.write(result, tmp_path / "si")
    montecarlo.write(result, tmp_path / "us", "us")
    expected = {f"{n}.{q}": (f"{n}.{q} [{u}]", f) for n in result.names
                for q, u, f in (("x", "ft", FT), ("y", "ft", FT), ("delta_v", "mph", MPH))}
    expected |= {e.field: (f"{e.field} [mph]", MPH) for e in result.scene.uncertain if e.field.endswith(".speed")}
    expected |= {e.field: (f"{e.field} [ft]", FT) for e in result.scene.uncertain
                 if e.field.endswith((".x", ".y"))}
    assert_converted(tmp_path / "si" / "montecarlo.csv", tmp_path / "us" / "montecarlo.csv", expected)
    a, b = (pd.read_csv(tmp_path / d / "summary.csv") for d in ("si", "us"))
    factor = a["quantity"].map({"x": FT, "y": FT, "heading": 1.0, "delta_v": MPH})
    close(b["median"], a["median"] / factor, 1e-5)
    assert list(b["unit"]) == list(a["quantity"].map({"x": "ft", "y": "ft", "heading": "deg", "delta_v": "mph"}))
    js = result.to_json_dict("us")
    row = next(r for r in js["summary"] if r["quantity"] == "delta_v")
    ref = next(r for r in result.to_json_dict()["summary"] if r["quantity"] == "delta_v")
    assert row["median"] == pytest.approx(ref["median"] / MPH, rel=1e-5) and row["unit"] == "mph"


def test_simulate_monte_carlo_passes_units_us_to_its_files_and_json(tmp_path, capsys):
    """The command line's --units reaches the Monte Carlo's CSV, summary and JSON (not only the module)."""
    side = str(REPO / "studies" / "montecarlo" / "side.toml")
    assert main(["simulate", side, "--monte-carlo", "6", "--seed", "3", "--units", "us", "--out",
                 str(tmp_path / "us")]) == 0
    printed = capsys.readouterr().out
    assert "mph" in printed and " km/h" not in printed
    columns = pd.read_csv(tmp_path / "us" / "montecarlo.csv").columns
    assert "V1.delta_v [mph]" in columns and "V1.x [ft]" in columns and "V1.delta_v" not in columns
    assert main(["simulate", side, "--monte-carlo", "6", "--seed", "3", "--units", "us", "--json"]) == 0
    js = json.loads(capsys.readouterr().out)
    assert next(r for r in js["summary"] if r["quantity"] == "delta_v")["unit"] == "mph"


def test_a_bound_out_of_range_in_a_us_study_is_one_line_in_file_units(twins, tmp_path, capsys):
    """300 mph is 482.8 km/h, above a speed's 400 km/h: the line names the key, the value as read and says so."""
    text = re.sub(r"upper = 37\.28[0-9]*", "upper = 300.0", twins[1].read_text(), count=1)
    bad = tmp_path / "bad.toml"
    bad.write_text(text)
    assert main(["reconstruct", str(bad)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"{bad}: free.0: upper = 482.803 is outside [0, 400] km/h" in err
    assert 'units = "us"' in err
    bad.write_text(twins[0].read_text().replace('name = "US study twin"', 'units = "imperial"\nname = "x"'))
    assert main(["reconstruct", str(bad)]) == 2
    assert f"{bad}: units: units = 'imperial': give one of 'si', 'us'" in capsys.readouterr().err


def test_one_units_map_names_columns_and_keys_by_pattern():
    """crashlab.units' shown units: a pattern of the units map (`<word>`: any text) gives a column's or a key's
    unit; a column is converted and named with its US unit (a header's bracket, a unit suffix, else appended);
    a CSV written so is read back into file units."""
    from crashlab.units import frame_in, json_in, table_from_shown, unit_of
    units = {"d_<source>_m": "m, distance", "<vehicle>.delta_v": "km/h", "mass": "kg", "t": "s"}
    assert [unit_of(k, units) for k in ("d_pc_crash_m", "V1.delta_v", "mass", "t", "d_pc_deg")] == \
        ["m", "km/h", "kg", "s", ""]
    df = pd.DataFrame({"d_pc_m": [3.048], "V1.delta_v": [16.09344], "mass": [453.59237], "t": [1.5],
                       "x [m]": [0.3048], "distance_m": [30.48]})
    shown = frame_in(df, "us", units | {"distance_m": "m"})
    assert list(shown.columns) == ["d_pc_ft", "V1.delta_v [mph]", "mass [lb]", "t", "x [ft]", "distance_ft"]
    close(shown.iloc[0].to_numpy(), [10.0, 10.0, 1000.0, 1.5, 1.0, 100.0], 1e-12)
    assert frame_in(df, "si", units) is df
    back = table_from_shown(shown)
    assert list(back.columns) == ["d_pc_ft", "V1.delta_v", "mass", "t", "x", "distance_ft"]  # (brackets only)
    close(back[["V1.delta_v", "mass", "x"]].iloc[0].to_numpy(), [16.09344, 453.59237, 0.3048], 1e-12)
    doc = json_in({"comparison": [{"d_pc_m": 3.048, "d_pc_deg": 2.0}], "units": units}, "us")
    # a key named with its unit takes the US one, as a column does (it kept d_pc_m for feet until 2026-11-28)
    assert doc["comparison"][0] == pytest.approx({"d_pc_ft": 10.0, "d_pc_deg": 2.0}, rel=1e-12)
    assert doc["units"]["d_<source>_ft"] == "ft, distance"
