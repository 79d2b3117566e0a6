"""Speed of the impulse model (pytest-benchmark). Skipped by default (--benchmark-skip in addopts); run:
    python -m pytest tests/benchmarks --benchmark-only -p no:randomly
Each benchmark also asserts that the timed call produced the physics it should (a fast wrong answer
is not a result)."""
from __future__ import annotations

import math

import numpy as np
import pytest

import crashlab


@pytest.fixture(scope="module")
def side(pc_crash_dir):
    return crashlab.load_scene(pc_crash_dir / "side.toml")


@pytest.fixture(scope="module")
def model(side):
    m = crashlab.get_model("impulse")
    m.simulate(side)  # compile / load the cache outside the timing
    m.simulate_batch([side, side])
    return m


def test_bench_side_single(benchmark, model, side):
    out = benchmark(model.simulate, side)
    assert out.outcome_ok and len(out.impacts) >= 2
    assert np.all(np.isfinite(out.rest_si))


def test_bench_side_batch_1000(benchmark, model, side):
    v = side.vehicle("V1").speed
    scenes = [side.with_vehicle("V1", speed=v * (0.9 + 0.2 * k / 1000)) for k in range(1000)]
    outs = benchmark.pedantic(model.simulate_batch, args=(scenes,), rounds=3, iterations=1, warmup_rounds=1)
    assert len(outs) == 1000 and all(o.outcome_ok for o in outs)
    # the batch is the same computation as single runs
    for k in (0, 500, 999):
        assert np.allclose(outs[k].rest_si, model.simulate(scenes[k]).rest_si, rtol=0, atol=1e-9)
    assert not math.isclose(outs[0].rest_si[0, 0], outs[999].rest_si[0, 0])
