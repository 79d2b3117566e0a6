"""Cost of one impact of each impulse law (docs/physics.md §3): Routh against Kudlich-Slibar, compiled, per call
over 2,000 seeded random impacts (tests/test_impulse_routh.random_impacts). Skipped by default; run:
    python -m pytest tests/benchmarks/test_bench_impulse_laws.py --benchmark-only -p no:randomly
The ratio of the two means is the issue's cost measure (target: Routh within 1.5x)."""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
from numba import njit

from crashlab.models.impulse.laws import BRACH, KUDLICH_SLIBAR, ROUTH, collision_impulse, impact_matrix

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from test_impulse_routh import random_impacts  # noqa: E402


@njit(cache=True)
def _all(K, G, E, MU, law, out):
    for k in range(K.shape[0]):
        pn, pt, kind = collision_impulse(K[k, 0], K[k, 1], K[k, 2], G[k, 0], G[k, 1], E[k], MU[k], law)
        out[k, 0], out[k, 1] = pn, pt


@pytest.fixture(scope="module")
def impacts():
    rows = [(impact_matrix(b.w[0], b.ii[0], b.w[1], b.ii[1], *b.r[0], *b.r[1], *b.n), b.nt(b.g0()), e, mu)
            for b, e, mu in random_impacts()]
    K = np.array([r[0] for r in rows])
    G = np.array([r[1] for r in rows])
    return K, G, np.array([r[2] for r in rows]), np.array([r[3] for r in rows]), np.empty((len(rows), 2))


@pytest.mark.parametrize("law", [KUDLICH_SLIBAR, BRACH, ROUTH], ids=["kudlich-slibar", "brach", "routh"])
def test_bench_impulse_law_2000_impacts(benchmark, impacts, law):
    K, G, E, MU, out = impacts
    _all(K, G, E, MU, law, out)  # compile outside the timing
    benchmark.pedantic(_all, args=(K, G, E, MU, law, out), rounds=200, iterations=5, warmup_rounds=5)
    assert np.all(out[:, 0] > 0.0) and np.all(np.isfinite(out))
