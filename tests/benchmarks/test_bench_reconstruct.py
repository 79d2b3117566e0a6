"""Benchmark: the whole `crashlab reconstruct` process on thesis case 5 (250 x 40 = 10,000 impulse-model
simulations, then a 250-evaluation least-squares polish), as a user runs it. The thesis needed 53 h for
40 x 40 with its multibody model.
Run: python -m pytest tests/benchmarks/test_bench_reconstruct.py --benchmark-only"""
import json
import subprocess
import sys

import pytest


@pytest.mark.benchmark(group="reconstruct")
def test_case5_reconstruct_process(benchmark, repo_root, tmp_path):
    study = repo_root / "studies" / "reconstruction" / "case5.toml"
    cmd = [sys.executable, "-m", "crashlab.cli", "reconstruct", str(study), "--out", str(tmp_path / "out"),
           "--json"]
    subprocess.run(cmd, check=True, capture_output=True)  # compile and cache the kernels once

    def run():
        return subprocess.run(cmd, check=True, capture_output=True, text=True)

    res = benchmark.pedantic(run, rounds=3, iterations=1)
    out = json.loads(res.stdout)
    assert out["search_evaluations"] == 250 * 40 and out["evaluations"] <= 250 * 40 + 250  # + the polish
    assert out["pareto"], "a non-empty Pareto set"
