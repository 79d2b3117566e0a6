"""Where simulations of a population run: serially, in local processes, or on a Dask cluster.

One code path: a population is cut into chunks and `Executor.map` runs `evaluate_scenes` on each chunk,
in this process, in a process pool, or through a Dask client (a LocalCluster with `workers`, or an
existing scheduler by address). Results are deterministic, so every backend gives the same answer.
"""
from __future__ import annotations

import functools

import numpy as np


@functools.lru_cache(maxsize=8)
def _model(name: str, options_items: tuple):
    """One model instance per worker process and options, kept across generations: a model may cache
    per-vehicle preparation (the multibody model settles each vehicle statically once)."""
    from .registry import get_model
    return get_model(name, **dict(options_items))


def evaluate_scenes(model_name: str, options_items: tuple, scenes: list, single_thread: bool = False):
    """Simulate scenes; returns compact arrays (ok, rest (n, nv, 3), contact (n, nv, 4), n_impacts).
    A simulation that raises is recorded as failed, never propagated."""
    if single_thread:
        try:
            import numba
            numba.set_num_threads(1)
        except Exception:  # noqa: BLE001 - numba is optional for foreign models
            pass
    model = _model(model_name, options_items)
    n, nv = len(scenes), len(scenes[0].vehicles)
    ok = np.zeros(n, bool)
    rest = np.full((n, nv, 3), np.nan)
    contact = np.full((n, nv, 4), np.nan)
    n_imp = np.zeros(n, int)
    try:
        outs = model.simulate_batch(scenes)
    except Exception:  # noqa: BLE001 - fall back to one by one so one bad scene fails alone
        outs = []
        for s in scenes:
            try:
                outs.append(model.simulate(s))
            except Exception:  # noqa: BLE001
                outs.append(None)
    for k, o in enumerate(outs):
        if o is None or not o.outcome_ok or not np.all(np.isfinite(o.rest_si)):
            continue
        ok[k] = True
        rest[k], contact[k] = o.rest_si, o.contact_si
        n_imp[k] = o.diagnostics["impacts"] if "impacts" in o.diagnostics else len(o.impact_rows)
    return ok, rest, contact, n_imp


class Executor:
    def __init__(self, backend: str = "serial", workers: int | None = None, scheduler: str | None = None):
        self.backend = "dask" if scheduler else backend
        self.workers = workers or 2
        self.scheduler = scheduler
        self._pool = None
        self._client = None
        self._cluster = None

    def __enter__(self):
        if self.backend == "processes":
            import multiprocessing
            from concurrent.futures import ProcessPoolExecutor
            # spawn, as Dask does: a forked child of a process whose numba kernels already ran on
            # GNU OpenMP threads aborts ("fork() called from a process already using GNU OpenMP")
            self._pool = ProcessPoolExecutor(self.workers, mp_context=multiprocessing.get_context("spawn"))
        elif self.backend == "dask":
            from dask.distributed import Client, LocalCluster
            if self.scheduler:
                self._client = Client(self.scheduler)
            else:
                self._cluster = LocalCluster(n_workers=self.workers, threads_per_worker=1,
                                             processes=True, dashboard_address=None)
                self._client = Client(self._cluster)
        return self

    def __exit__(self, *exc):
        if self._pool is not None:
            self._pool.shutdown()
        if self._client is not None:
            self._client.close()
        if self._cluster is not None:
            self._cluster.close()
        self._pool = self._client = self._cluster = None

    def evaluate(self, model_name: str, options: dict, scenes: list):
        """Simulate scenes with the model; arrays as `evaluate_scenes`, in input order."""
        items = tuple(sorted(options.items()))
        if self.backend == "serial" or len(scenes) < 2:
            return evaluate_scenes(model_name, items, scenes)
        n_chunks = min(len(scenes), self.workers * 2)
        chunks = [list(c) for c in np.array_split(np.array(scenes, dtype=object), n_chunks) if len(c)]
        if self.backend == "processes":
            parts = list(self._pool.map(evaluate_scenes, [model_name] * len(chunks), [items] * len(chunks),
                                        chunks, [True] * len(chunks)))
        else:
            futures = self._client.map(evaluate_scenes, [model_name] * len(chunks), [items] * len(chunks),
                                       chunks, [True] * len(chunks), pure=False)
            parts = self._client.gather(futures)
        return tuple(np.concatenate([p[k] for p in parts]) for k in range(4))
