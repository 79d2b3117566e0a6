"""Benchmark (issue 25): the side collision, 10,000 variants of the speeds and headings, through
`simulate_population` against the scene-per-variant route (fields.setter + simulate_batch + the arrays read
from the Outcomes), both cores. The Python time per variant is the population's wall time minus the compiled
kernel's (the kernel call timed alone), divided by the variants (extra_info)."""
import time
from pathlib import Path

import numpy as np
import pytest

import crashlab
from crashlab import fields
from crashlab.models.impulse import ImpulseModel
from crashlab.models.impulse import kernel as K
from crashlab.population import Population

SIDE = Path(__file__).resolve().parents[2] / "studies" / "pc_crash" / "side.toml"
PATHS = ["vehicles.V1.speed", "vehicles.V1.heading", "vehicles.V2.speed", "vehicles.V2.heading"]
N = 10_000


def _values(n=N):
    rng = np.random.default_rng(7)
    return np.column_stack([rng.uniform(40, 60, n), rng.uniform(-10, 10, n), rng.uniform(20, 40, n),
                            rng.uniform(80, 100, n)])


@pytest.fixture(scope="module")
def setup():
    scene, model = crashlab.load_scene(SIDE), ImpulseModel()
    model.simulate_population(scene, PATHS, _values(10))  # compile
    return scene, model, _values()


def test_bench_population_side_10000(benchmark, setup, monkeypatch):
    scene, model, values = setup
    kernel = [0.0]
    real = K.simulate_many

    def timed(*args):
        t0 = time.perf_counter()
        real(*args)
        kernel[0] += time.perf_counter() - t0
    monkeypatch.setattr(K, "simulate_many", timed)

    def run():
        kernel[0] = 0.0
        t0 = time.perf_counter()
        pop = model.simulate_population(scene, PATHS, values)
        benchmark.extra_info["python_us_per_variant"] = 1e6 * (time.perf_counter() - t0 - kernel[0]) / N
        return pop
    pop = benchmark.pedantic(run, rounds=3, iterations=1)
    benchmark.extra_info["variants_per_s"] = N / benchmark.stats.stats.median
    assert pop.ok.mean() > 0.99


def test_bench_scene_per_variant_side_10000(benchmark, setup):
    scene, model, values = setup
    build = fields.setter(scene, PATHS)

    def run():
        scenes = [build(row) for row in values]
        masses = np.array([[v.spec.mass for v in s.vehicles] for s in scenes])
        return Population.of_outcomes(model.simulate_batch(scenes), scene.vehicle_names, masses)
    pop = benchmark.pedantic(run, rounds=3, iterations=1)
    benchmark.extra_info["variants_per_s"] = N / benchmark.stats.stats.median
    assert pop.ok.mean() > 0.99
