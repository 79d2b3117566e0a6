"""The Executor: runs populations on a backend, owning its workers (crashlab.execution)."""
from __future__ import annotations

import numpy as np

from ..population import Population, Variants
from .constants import FIRST_CALL_GRACE_S
from .dask_cluster import _chunks, evaluate_on_dask
from .evaluate import evaluate_in_process
from .pool import WorkerPool

SCHEDULER_CONNECT_TIMEOUT_S = 5.0  # s: an unreachable --scheduler / [execution] scheduler is refused after this


class Executor:
    """Runs populations on a backend ('serial', 'processes', 'dask'); a context manager that owns its
    workers. timeout_s: None or 0 for no limit per evaluation (see the module docstring)."""

    def __init__(self, backend: str = "serial", workers: int | None = None, scheduler: str | None = None,
                 timeout_s: float | None = None, first_call_grace_s: float = FIRST_CALL_GRACE_S):
        self.backend = "dask" if scheduler else backend
        self.first_call_grace_s = first_call_grace_s  # s more for each model's first call in a worker
        self.workers = workers or 2
        self.scheduler = scheduler
        self.timeout_s = timeout_s or None
        self._pool: WorkerPool | None = None
        self._client = None
        self._cluster = None
        self._compiled: set = set()  # (model, options) whose first evaluation has run on a worker

    def __enter__(self):
        if self.backend == "processes" or (self.backend == "serial" and self.timeout_s):
            serial = self.backend == "serial"
            self._pool = WorkerPool(1 if serial else self.workers, self.timeout_s, single_thread=not serial,
                                    grace_s=self.first_call_grace_s)
        elif self.backend == "dask":
            from dask.distributed import Client, LocalCluster
            if self.scheduler:
                try:  # Dask's own default waits 30 s (distributed.comm.timeouts.connect), then a traceback
                    self._client = Client(self.scheduler, timeout=SCHEDULER_CONNECT_TIMEOUT_S)
                except Exception as err:  # noqa: BLE001 - refused, timed out, a bad address, or something else
                    #                          answering there (bytes Dask cannot read: seen as a MemoryError)
                    from ..errors import InputError
                    raise InputError("execution", "scheduler", f"no Dask scheduler answers at {self.scheduler!r} "
                                     f"within {SCHEDULER_CONNECT_TIMEOUT_S:g} s ({type(err).__name__}: {err})") \
                        from None
            else:
                # no PR_SET_PDEATHSIG here: it is bound to the thread that starts a process, and Dask's
                # nanny starts workers from helper threads that come and go; Dask's workers watch their
                # parent through a pipe and exit when it closes (distributed.process)
                self._cluster = LocalCluster(n_workers=self.workers, threads_per_worker=1, processes=True,
                                             dashboard_address=None)
                self._client = Client(self._cluster)
        return self

    def __exit__(self, *exc):
        if self._pool is not None:
            self._pool.close()
        if self._client is not None:
            self._client.close()
        if self._cluster is not None:
            self._cluster.close()
        self._pool = self._client = self._cluster = None

    def evaluate(self, model_name: str, options: dict, work, scorer=None) -> Population:
        """Simulate `work` with the model: Variants (one scene, fields and rows: the model's
        simulate_population, only the scene and blocks of rows travel to the workers) or a list of Scenes
        (simulate_batch); a Population in input order. scorer: scores each row where it was simulated, in
        Population.scores (module docstring)."""
        items = tuple(sorted(options.items()))
        if self._pool is None and self._client is None:
            return evaluate_in_process(model_name, items, work, scorer=scorer)
        if (model_name, items) not in self._compiled and len(work) > 1 and self.backend != "serial":
            # compile once: the first row runs alone on one worker, which compiles the model and fills the numba
            # cache (crashlab.numba_cache); the other workers then load it instead of all compiling at once
            self._compiled.add((model_name, items))
            return Population.concat([self._run(model_name, items, work[:1], scorer),
                                      self._run(model_name, items, work[1:], scorer)])
        self._compiled.add((model_name, items))
        return self._run(model_name, items, work, scorer)

    def _run(self, model_name, items, work, scorer) -> Population:
        if self._pool is not None:
            n_chunks = 1 if self.backend == "serial" else min(len(work), self.workers * 2)
            return self._pool.evaluate(model_name, items, _chunks(work, n_chunks), scorer)
        return evaluate_on_dask(self._client, model_name, items, work, self.workers, self.timeout_s, scorer,
                                self.first_call_grace_s)

    def evaluate_population(self, model_name: str, options: dict, scene, fields, values, scorer=None,
                            invalid: str = "fail") -> Population:
        """`evaluate` of Variants(scene, fields, values, invalid)."""
        return self.evaluate(model_name, options, Variants(scene, tuple(fields), np.asarray(values, float), invalid),
                             scorer)
