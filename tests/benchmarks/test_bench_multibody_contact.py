"""Benchmark (issue 5): PC-Crash case 3 (side collision, two Clios, wheels locked after the impact) with the
multibody model, from the start to rest. Goal <= 0.2 s on the 2-core machine (issue 25; 0.44 s before the
block-sparse constraint solve, the Brent gap search and the PI step control, CPU time, alternated)."""
from pathlib import Path

import crashlab
from crashlab.models.multibody import MultibodyModel

SIDE = Path(__file__).resolve().parents[2] / "studies" / "pc_crash" / "side.toml"


def test_bench_multibody_pc_crash_case3(benchmark):
    sc = crashlab.load_scene(SIDE)
    model = MultibodyModel()
    model.simulate(sc)                      # compile (numba cache) and settle the vehicles once
    out = benchmark(model.simulate, sc)
    assert out.outcome_ok
    assert len(out.impact_rows) >= 2
    assert out.diagnostics["t_end"] < sc.duration     # both cars came to rest
