"""The work-precision study (crashlab.comparison.workprecision) on a tiny configuration: impulse and
pymunk on the side collision, their step `dt` at x 2, x 1, / 2 of the default, one timed run each."""
import json
import math

import pandas as pd
import pytest

from crashlab.comparison import workprecision as wp
from crashlab.comparison.base import resolve_models
from crashlab.errors import InputError
from crashlab.options import ModelOptions, option


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    df, conv = wp.study(["impulse", "pymunk"], ["side"], factors=(2.0, 1.0, 0.5), repeats=1, knobs={"dt"},
                        slow_run_s=None)
    out = tmp_path_factory.mktemp("wp")
    path = wp.write(df, conv, out)
    return path, conv


def test_csv_contract_and_figure(tiny):
    path, conv = tiny
    df = pd.read_csv(path)
    assert list(df.columns) == ["model", "scene", "setting", "wall_time_s", "error_m", "error_deg",
                                "error_kind", "knob", "is_default", "ok"]
    assert set(df.error_kind) == {"numerical", "reference"}  # the side collision has PC-Crash rest poses
    assert set(df.model) == {"impulse", "pymunk"} and set(df.scene) == {"side"}
    for model in ("impulse", "pymunk"):
        d = df[(df.model == model) & (df.error_kind == "numerical")]
        assert len(d) == 3 and d.ok.all() and (d.wall_time_s > 0).all()
        default = d[d.is_default]
        assert len(default) == 1 and default.setting.iloc[0] == "{}" and default.knob.fillna("").iloc[0] == ""
        assert {json.loads(s).get("dt") for s in d.setting} - {None} and set(d.knob.fillna("")) == {"", "dt"}
    assert (path.parent / "workprecision_side.png").stat().st_size > 0
    assert list(conv.columns) == wp.CONVERGED_COLUMNS and conv.ok.all()
    assert (conv.converged_check_m >= 0).all()  # the converged result was checked by a refinement


def test_numerical_error_falls_as_the_step_is_refined(tiny):
    """Error against the model's own converged result: pymunk's coarsest step is further off than its finest;
    impulse's dt is at the floor there (its slides are second order, docs/physics.md §2): 0.05-0.08 mm,
    0.003 deg at 2.5, 5 and 10 ms, measured (while the locked wheels' load transfer lagged a stage: 0.78 mm,
    0.09 deg at 5 and 10 ms, both capped at 3.6 ms by the tyre forces' rate bound, 0.01 mm at 2.5 ms)."""
    path, _ = tiny
    df = pd.read_csv(path)
    for model in ("impulse", "pymunk"):
        d = df[(df.model == model) & (df.error_kind == "numerical")].copy()
        d["dt"] = [json.loads(s).get("dt", math.nan) for s in d.setting]
        d = d[d.knob == "dt"].sort_values("dt")
        if model == "pymunk":
            assert d.error_m.iloc[0] < d.error_m.iloc[-1], (model, d[["dt", "error_m"]])
        else:
            assert (d.error_m < 0.0005).all() and (d.error_deg < 0.05).all(), (model, d[["dt", "error_m"]])


def test_knob_values_stay_in_range_and_round_integers():
    class Opts(ModelOptions):
        dt: float = option(0.004, "step", "s", accuracy="smaller", gt=0, le=0.01)
        iterations: int = option(3, "iterations", accuracy="larger", ge=1, le=10)

    dts = wp.knob_values(Opts, "dt", "smaller", wp.FACTORS)
    assert [v for _, v in dts] == [0.008, 0.004, 0.002, 0.001, 0.0005]  # 0.016 is out of range
    its = wp.knob_values(Opts, "iterations", "larger", wp.FACTORS)
    assert [v for _, v in its] == [1, 2, 3, 6]  # rounded, 12 and 24 out of range, duplicates dropped


def test_unknown_model_and_model_without_knobs_are_input_errors(monkeypatch):
    with pytest.raises(InputError, match="command line: --models"):
        resolve_models("impulse,no_such_model")
    monkeypatch.setattr(wp, "model_schema", lambda name: None)  # a model that declares no options
    with pytest.raises(InputError, match="command line: --models: model 'impulse' declares no accuracy"):
        wp.check_knobs(["impulse"])
