"""Alternated old/new measurement of issue 25 (README, "Populations"): 10,000 variants of the side collision
(speeds, headings), the route a reconstruction takes (execution in this process), numba threads as given
(NUMBA_NUM_THREADS). Run it with each build's own python, alternating, e.g.
    NUMBA_NUM_THREADS=2 OLD/.venv/bin/python tests/benchmarks/population_old_new.py OLD/studies/pc_crash/side.toml
    NUMBA_NUM_THREADS=2 .venv/bin/python tests/benchmarks/population_old_new.py studies/pc_crash/side.toml
The old route (a scene per variant through execution.evaluate_scenes, as before 8bf719a's successor) is used where
the build has it, else the population route. Prints variants per second of three runs and their median."""

import json
import sys
import time

import numpy as np

import crashlab
from crashlab import execution, fields

PATHS = ["vehicles.V1.speed", "vehicles.V1.heading", "vehicles.V2.speed", "vehicles.V2.heading"]


def main(side: str, n: int = 10000) -> None:
    scene = crashlab.load_scene(side)
    rng = np.random.default_rng(7)
    X = np.column_stack([rng.uniform(40, 60, n), rng.uniform(-10, 10, n), rng.uniform(20, 40, n),
                         rng.uniform(80, 100, n)])
    if hasattr(execution, "evaluate_scenes"):  # the old route: a scene per variant, simulate_batch, Evaluations
        build = fields.setter(scene, PATHS, check=False)

        def run(X):
            return execution.evaluate_scenes("impulse", (), [build(r) for r in X])
        kind = "old"
    else:
        from crashlab.population import Variants

        def run(X):
            return execution.evaluate_in_process("impulse", (), Variants(scene, tuple(PATHS), X, "unchecked"))
        kind = "new"
    run(X[:20])
    ts = []
    for _ in range(3):
        t0 = time.perf_counter()
        ev = run(X)
        ts.append(time.perf_counter() - t0)
    print(json.dumps({"kind": kind, "per_s": [round(n / t) for t in ts], "median_per_s": round(n / sorted(ts)[1]),
                      "ok": float(np.mean(ev.ok)), "rest_sum": float(np.nansum(ev.rest))}))


if __name__ == "__main__":
    main(sys.argv[1], int(sys.argv[2]) if len(sys.argv) > 2 else 10000)
