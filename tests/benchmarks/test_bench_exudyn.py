"""Benchmark: PC-Crash case 3 (side collision, two Clios, wheels locked after the impact) with the exudyn model,
from the start to rest."""
from pathlib import Path

import pytest

pytest.importorskip("exudyn")

import crashlab  # noqa: E402
from crashlab.models.exudyn import ExudynModel  # noqa: E402

SIDE = Path(__file__).resolve().parents[2] / "studies" / "pc_crash" / "side.toml"


def test_bench_exudyn_pc_crash_case3(benchmark):
    sc = crashlab.load_scene(SIDE)
    model = ExudynModel()
    model.simulate(sc)                      # load the numba contact kernels once
    out = benchmark(model.simulate, sc)
    assert out.outcome_ok
    assert len(out.impact_rows) >= 2
    assert out.diagnostics["t_end"] < sc.duration     # both cars came to rest
