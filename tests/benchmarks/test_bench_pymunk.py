"""Speed of model `pymunk`: side-collision simulations per second on this machine (PC-Crash case 3).

Skipped in the default run (the project's addopts pass --benchmark-skip); run with
    pytest tests/benchmarks/test_bench_pymunk.py --benchmark-only
sims/s = 1 / mean time.
"""
from __future__ import annotations

from pathlib import Path

import pytest

import crashlab

pytest.importorskip("pymunk")

SIDE = Path(__file__).resolve().parents[2] / "studies" / "pc_crash" / "side.toml"


@pytest.mark.benchmark(group="pymunk")
def test_bench_pymunk_side_collision(benchmark):
    scene = crashlab.load_scene(SIDE)
    model = crashlab.get_model("pymunk", record_dt=0.0)
    model.simulate(scene)  # compile the numba tyre-force loop outside the timing
    out = benchmark(model.simulate, scene)
    assert out.outcome_ok and len(out.impacts) >= 2
    benchmark.extra_info["sims_per_s"] = 1.0 / benchmark.stats.stats.mean


@pytest.mark.benchmark(group="pymunk")
def test_bench_pymunk_side_collision_with_trajectory(benchmark):
    scene = crashlab.load_scene(SIDE)
    model = crashlab.get_model("pymunk")
    model.simulate(scene)
    out = benchmark(model.simulate, scene)
    assert out.outcome_ok
