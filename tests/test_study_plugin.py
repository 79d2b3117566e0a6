"""The comparison studies on a third-party model: a plugin found through its entry point only
(tests/thirdparty: a dist-info with the entry point and its module, put on sys.path here), with accuracy
knobs of its own names. Every study finds its knobs in its option schema and runs it."""
import sys
from pathlib import Path

import pandas as pd
import pytest

from crashlab import registry
from crashlab.comparison import scaling, stability, validation
from crashlab.comparison import workprecision as wp
from crashlab.comparison.base import resolve_models

THIRDPARTY = str(Path(__file__).resolve().parent / "thirdparty")


@pytest.fixture
def plugin():
    sys.path.insert(0, THIRDPARTY)
    registry.refresh()
    try:
        yield "testplugin"
    finally:
        sys.path.remove(THIRDPARTY)
        registry.refresh()


def test_plugin_is_found_by_its_entry_point(plugin):
    assert plugin in registry.available_models() and resolve_models(plugin) == [plugin]


def test_workprecision_sweeps_the_plugins_own_knob(plugin):
    df, conv = wp.study([plugin], ["side"], factors=(4.0, 1.0, 0.25), repeats=1, knobs={"step"}, slow_run_s=None)
    num = df[(df.error_kind == "numerical") & (df.knob == "step")].sort_values("wall_time_s")
    assert len(num) == 2 and num.ok.all()
    coarse = num[num.setting.str.contains("0.02")].error_m.iloc[0]
    fine = num[~num.setting.str.contains("0.02")].error_m.iloc[0]
    assert fine < coarse  # the error falls as the plugin's step is refined


def test_stability_runs_the_plugin_at_coarser_steps(plugin):
    assert stability.step_knob(plugin) == "step"
    df = stability.measure([plugin], lambda m: (4, 2), all_knobs=False, log=lambda *a: None)
    assert set(df.model) == {plugin} and (df.setting == "{}").sum() == 4 and len(df) > 4


def test_scaling_and_validation_run_the_plugin(plugin):
    rows = pd.DataFrame(scaling.model_rows(plugin, quick=True, sizes=(2, 4), variant_names=["parked"], repeats=1))
    assert set(rows.model) == {plugin} and rows.ok.all()
    tests = [t for t in validation.load_tests() if t["id"] == "nhtsa10146"]
    vrows = validation.validation_rows([plugin], tests=tests)
    assert vrows and all(r["ok"] for r in vrows) and {r["model"] for r in vrows} == {plugin}
