"""Population on a Dask cluster: deadlines in a thread (a Dask task cannot be killed), dying workers
retried one scene at a time (crashlab.execution, module docstring)."""
from __future__ import annotations

import threading

import numpy as np

from ..population import Population, one_line
from .constants import FIRST_CALL_GRACE_S
from .evaluate import _single_thread, _vectorised, empty_population, evaluate_in_process
from .models import model_instance


def _append_result(box, model_name, options_items, scenes, scorer):
    box.append(evaluate_in_process(model_name, options_items, scenes, scorer=scorer))


_DASK_CALLS = [0]  # evaluations begun in this (Dask worker) process
_DASK_RESTART_S = 120.0  # s: a restarted Dask worker is back within this (measured 5-40 s on a loaded machine)


def _dask_evaluate(model_name: str, options_items: tuple, scenes: list, timeout_s: float | None,
                   split: bool, grace_s: float = FIRST_CALL_GRACE_S, scorer=None):
    """A Dask task: evaluate scenes with per-evaluation deadlines (in a thread, since a Dask task cannot
    be killed). Returns (Population, begun, hung_worker): begun (n,) bool marks the scenes evaluated
    or failed; the others are to be run again, one at a time; hung_worker is this worker's address when
    an evaluation overran (its thread still runs: the worker is to be restarted)."""
    _single_thread()
    n = len(scenes)
    if not timeout_s:
        return evaluate_in_process(model_name, options_items, scenes, scorer=scorer), np.ones(n, bool), None
    res = empty_population(scenes, scorer=scorer)
    begun = np.zeros(n, bool)
    try:
        vectorised = _vectorised(model_instance(model_name, options_items))
    except Exception:  # noqa: BLE001
        vectorised = True
    units = [(0, n)] if vectorised and not split else [(k, 1) for k in range(n)]
    for k0, m in units:
        box: list = []
        th = threading.Thread(target=_append_result, daemon=True,
                              args=(box, model_name, options_items, scenes[k0:k0 + m], scorer))
        th.start()
        th.join(timeout_s * m + (grace_s if _DASK_CALLS[0] == 0 else 0.0))
        _DASK_CALLS[0] += 1
        if th.is_alive():
            if m == 1:
                begun[k0] = True
                res.fail(k0, f"timeout: evaluation ran longer than {timeout_s:g} s")
            from distributed import get_worker
            return res, begun, get_worker().address
        res.put(k0, box[0])
        begun[k0:k0 + m] = True
    return res, begun, None


def evaluate_on_dask(client, model_name, items, scenes, workers, timeout_s, scorer=None,
                     grace_s: float = FIRST_CALL_GRACE_S) -> Population:
    """Population of scenes on a Dask client: chunks in parallel; the scenes of a task whose workers died
    (KilledWorker: Dask retried it on other workers and they died too) are then run one at a time, alone on
    the cluster, so a scene that merely shared a dying worker is evaluated and only the deadly ones fail."""
    from distributed import KilledWorker
    res = empty_population(scenes, scorer=scorer)
    tasks = []  # (offset, scenes, split)
    offset = 0
    for c in _chunks(scenes, min(len(scenes), workers * 2)):
        tasks.append((offset, c, False))
        offset += len(c)
    alone = False  # the second phase: one task at a time
    while tasks:
        batch = tasks[:1] if alone else tasks
        tasks = tasks[1:] if alone else []
        futures = client.map(_dask_evaluate, [model_name] * len(batch), [items] * len(batch),
                                   [t[1] for t in batch], [timeout_s] * len(batch),
                                   [t[2] for t in batch], [grace_s] * len(batch),
                                   [scorer] * len(batch), pure=False)
        # the longest a round can legitimately take: every scene of it one after the other, after the
        # first-call grace and a restart of the workers (Dask closes a worker gracefully first)
        bound = None if timeout_s is None else grace_s + _DASK_RESTART_S + timeout_s * sum(
            len(t[1]) for t in batch)
        hung = set()
        for (offset, chunk, _), fut in zip(batch, futures):
            try:
                part, begun, hung_worker = fut.result(timeout=bound)
            except KilledWorker:
                if alone and len(chunk) == 1:
                    res.fail(offset, "Dask worker died while evaluating (KilledWorker)")
                else:
                    tasks += [(offset + k, chunk[k:k + 1], True) for k in range(len(chunk))]
                continue
            except Exception as err:  # noqa: BLE001 - lost connection, a task that cannot run, no answer
                fut.cancel()
                res.fail(slice(offset, offset + len(chunk)), one_line(f"Dask task failed: {err!r}"))
                continue
            res.put(offset, part)
            tasks += [(offset + k, chunk[k:k + 1], True) for k in np.flatnonzero(~begun)]
            if hung_worker:
                hung.add(hung_worker)
        if hung:
            try:
                client.restart_workers(sorted(hung), raise_for_error=False)
            except Exception:  # noqa: BLE001 - the run goes on with the workers it has
                pass
        alone = True
    return res


def _chunks(work, n_chunks: int) -> list:
    """work (Variants or a list of Scenes) cut into n_chunks consecutive parts of nearly equal size."""
    bounds = np.linspace(0, len(work), n_chunks + 1).round().astype(int)
    return [work[a:b] for a, b in zip(bounds[:-1], bounds[1:]) if b > a]
