"""The Executor: runs populations on a backend, owning its workers (crashlab.execution)."""
from __future__ import annotations

from .constants import FIRST_CALL_GRACE_S
from .dask_cluster import _chunks, evaluate_on_dask
from .evaluate import Evaluations, evaluate_scenes
from .pool import WorkerPool


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

    def __enter__(self):
        if self.backend == "processes" or (self.backend == "serial" and self.timeout_s):
            serial = self.backend == "serial"
            self._pool = WorkerPool(1 if serial else self.workers, self.timeout_s, single_thread=not serial,
                                    grace_s=self.first_call_grace_s)
        elif self.backend == "dask":
            from dask.distributed import Client, LocalCluster
            if self.scheduler:
                self._client = Client(self.scheduler)
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

    def evaluate(self, model_name: str, options: dict, scenes: list, scorer=None) -> Evaluations:
        """Simulate scenes with the model; `Evaluations` in input order. scorer: scores each outcome where it
        was simulated, in Evaluations.scores (module docstring)."""
        items = tuple(sorted(options.items()))
        if self._pool is None and self._client is None:
            return evaluate_scenes(model_name, items, scenes, scorer=scorer)
        nv = len(scenes[0].vehicles)
        if self._pool is not None:
            n_chunks = 1 if self.backend == "serial" else min(len(scenes), self.workers * 2)
            return self._pool.evaluate(model_name, items, _chunks(scenes, n_chunks), nv, scorer)
        return evaluate_on_dask(self._client, model_name, items, scenes, nv, self.workers, self.timeout_s, scorer,
                                self.first_call_grace_s)
