"""Where simulations of a population run: in this process, in worker processes, or on a Dask cluster.

A population is cut into chunks; each chunk is simulated by `evaluate_scenes` (the model's
`simulate_batch`). Results are deterministic and placed by index, so every backend gives the same answer.

Every evaluation ends with a result or with a reason why it failed (`Evaluations.reason`); nothing is
dropped and nothing stops the run:
  * a model that raises, or returns an Outcome with outcome_ok False (the physics guard's verdict
    included), fails that evaluation with the exception or the Outcome's warnings as the reason;
  * `timeout_s` (study file `[execution] timeout_s`, default DEFAULT_TIMEOUT_S) fails an evaluation that
    runs longer. Python cannot interrupt a compiled kernel (numba, C) from a signal handler, so a timed
    evaluation runs in a worker process, which is killed when it overruns: with a timeout even the
    "serial" backend simulates in one worker process (the population in one batch, numba keeps its
    threads). A model with its own vectorised `simulate_batch` is timed per call: a call on n scenes
    may take n x timeout_s; when it overruns, its scenes are run again one at a time, each with
    timeout_s, so only the ones that hang fail. The first call of each model in each worker gets
    FIRST_CALL_GRACE_S more (numba compiles a model on its first use);
  * a worker process that dies (segfault, out of memory, killed) fails the evaluation it was running,
    with the signal as the reason (a batch is split into single evaluations first, as for a timeout);
    the pool starts a new worker and the run goes on. On Dask a task whose workers died
    (`KilledWorker`, after Dask's own retries) is handled the same way; a timed-out evaluation on Dask
    leaves its thread running, so that worker is restarted;
  * no worker outlives its run: the pool stops its workers when the run ends or raises; on Linux every
    worker process is also killed by the kernel when the process that started it dies, even by SIGKILL
    (prctl PR_SET_PDEATHSIG; elsewhere a watchdog thread polls the parent). Dask's local cluster stops
    its workers when it closes, and they exit when the pipe to their parent closes (distributed.process).
With `timeout_s` None or 0 the serial backend simulates in this process (exceptions still fail single
evaluations; a hang then hangs the run).

A scorer (the reconstruction's evidence: reconstruction.evidence.EvidenceSet) scores each Outcome where it was
simulated, so evidence that needs more than rest poses (impact rows, paths) runs on every backend with its
timeout and only its numbers travel back: an object with `n_residuals`, `needs_trajectory` (simulate one by
one: a batch records no paths) and `residuals(outcomes) -> (n, n_residuals)`, picklable; the numbers are in
Evaluations.scores.
"""
from __future__ import annotations

import collections
import functools
import os
import signal
import sys
import threading
import time
from typing import NamedTuple

import numpy as np

# s per evaluation: the slowest built-in model (exudyn, 1 ms implicit steps) takes about 1 s for a
# two-car crash to rest and 0.1-0.3 s is typical (README, "Speed"); 60 s is 60 x that, so only a hung
# or runaway simulation reaches it, and it bounds what one hang costs a run
DEFAULT_TIMEOUT_S = 60.0
FIRST_CALL_GRACE_S = 600.0  # s on top of the first call in each worker: numba compiles on first use


class WorkerStartError(RuntimeError):
    """Worker processes die before they evaluate anything (an environment problem, not a model's)."""


START_FAILURES = 3  # consecutive workers that die before their first evaluation: the pool gives up


class Evaluations(NamedTuple):
    """Results of n evaluations of scenes with nv vehicles (SI)."""
    ok: np.ndarray  # (n,) bool: the model returned a usable outcome
    rest: np.ndarray  # (n, nv, 3) x, y, heading at the end (NaN where failed)
    contact: np.ndarray  # (n, nv, 4) x, y, heading, speed at first contact
    n_impacts: np.ndarray  # (n,) int
    end_speed: np.ndarray  # (n, nv) speed of each CG at the end [m/s]
    at_rest: np.ndarray  # (n, nv) bool: at rest at the end (crashlab.outcome.REST_SPEED, REST_YAW_RATE)
    reason: np.ndarray  # (n,) object: "" or why the evaluation failed (one line)
    scores: np.ndarray  # (n, k) the caller's scorer's numbers of each outcome (k = 0 without a scorer)


def empty_evaluations(n: int, nv: int, reason: str = "not evaluated", k: int = 0) -> Evaluations:
    return Evaluations(np.zeros(n, bool), np.full((n, nv, 3), np.nan), np.full((n, nv, 4), np.nan),
                       np.zeros(n, int), np.full((n, nv), np.nan), np.zeros((n, nv), bool),
                       np.array([reason] * n, dtype=object), np.full((n, k), np.nan))


def _n_scores(scorer) -> int:
    return 0 if scorer is None else int(scorer.n_residuals)


def _put(dst: Evaluations, start: int, src: Evaluations) -> None:
    for a, b in zip(dst, src):
        a[start:start + len(b)] = b


def _fail(dst: Evaluations, idx, reason: str) -> None:
    dst.ok[idx] = False
    dst.reason[idx] = reason


def _one_line(text: str, limit: int = 300) -> str:
    text = " ".join(str(text).split())
    return text if len(text) <= limit else text[:limit - 3] + "..."


def outcome_reason(o) -> str:
    """Why an Outcome with outcome_ok False failed: the physics guard's findings first, else its warnings."""
    warnings = [str(w) for w in getattr(o, "warnings", ()) or ()]
    guard = [w for w in warnings if w.startswith("physics guard")]
    return _one_line("; ".join(guard or warnings) or "the model reported a failed run (no reason given)")


def _exception_reason(err: BaseException) -> str:
    return _one_line(f"model raised {type(err).__name__}: {err}")


@functools.lru_cache(maxsize=8)
def _model(name: str, options_items: tuple):
    """One model instance per worker process and options, kept across generations: a model may cache
    per-vehicle preparation (the multibody model settles each vehicle statically once). A name
    'module:Class' imports a model class that is not an installed plugin (the tests use it)."""
    if ":" in name:
        import importlib
        module, attr = name.split(":", 1)
        return getattr(importlib.import_module(module), attr)(**dict(options_items))
    from .registry import get_model
    return get_model(name, **dict(options_items))


def model_for(name: str, options: dict):
    """This process's model instance for name and options: the one its evaluations use."""
    return _model(name, tuple(sorted(options.items())))


def _vectorised(model) -> bool:
    """Whether the model has a simulate_batch of its own (then a batch is one call, timed as a whole)."""
    from .model import CollisionModel
    own = getattr(type(model), "simulate_batch", None)
    return own is not None and own is not CollisionModel.simulate_batch


def _single_thread():
    try:
        import numba
        numba.set_num_threads(1)
    except Exception:  # noqa: BLE001 - numba is optional for foreign models
        pass


def evaluate_scenes(model_name: str, options_items: tuple, scenes: list, single_thread: bool = False,
                    scorer=None) -> Evaluations:
    """Simulate scenes in this process. A simulation that raises or fails is recorded with its reason,
    never propagated; when the batch call raises, the scenes are simulated one by one so a bad scene
    fails alone. scorer: scores each outcome where it was simulated (module docstring)."""
    if single_thread:
        _single_thread()
    n, nv = len(scenes), len(scenes[0].vehicles)
    res = empty_evaluations(n, nv, k=_n_scores(scorer))
    try:
        model = _model(model_name, options_items)
    except Exception as err:  # noqa: BLE001
        _fail(res, slice(None), _one_line(f"model could not be built: {type(err).__name__}: {err}"))
        return res
    batch = scorer is None or not scorer.needs_trajectory
    return evaluations_of(simulate_each(model, scenes, batch=batch), nv, scorer)


def simulate_each(model, scenes, batch: bool = True) -> list:
    """The Outcome of every scene, an exception in place of the outcome of a scene whose simulation raised:
    model.simulate_batch (batch=True), or, when it raises or returns another count, model.simulate scene by
    scene, so that a bad scene fails alone."""
    scenes = list(scenes)
    if batch:
        try:
            outs = list(model.simulate_batch(scenes))
            if len(outs) == len(scenes):
                return outs
        except Exception:  # noqa: BLE001 - one by one, so one bad scene fails alone
            pass
    outs = []
    for s in scenes:
        try:
            outs.append(model.simulate(s))
        except Exception as err:  # noqa: BLE001
            outs.append(err)
    return outs


def evaluations_of(outcomes, nv: int, scorer=None) -> Evaluations:
    """Evaluations of Outcomes (or exceptions in their place): an exception or a failed Outcome fails with its
    reason; a non-finite rest pose fails; an Outcome without final velocities counts as at rest. With a
    scorer, its numbers of the outcomes (a scorer that raises fails them all, with its reason)."""
    res = empty_evaluations(len(outcomes), nv, k=_n_scores(scorer))
    for k, o in enumerate(outcomes):
        if isinstance(o, BaseException):
            res.reason[k] = _exception_reason(o)
            continue
        if o is None:
            res.reason[k] = "the model returned no outcome"
            continue
        if not getattr(o, "outcome_ok", False):
            res.reason[k] = outcome_reason(o)
            continue
        rest = np.asarray(o.rest_si, float)
        if rest.shape != (nv, 3) or not np.all(np.isfinite(rest)):
            res.reason[k] = "non-finite rest pose"
            continue
        res.ok[k], res.reason[k] = True, ""
        res.rest[k] = rest
        contact = getattr(o, "contact_si", None)
        if contact is not None:
            res.contact[k] = contact
        diag = getattr(o, "diagnostics", {}) or {}
        res.n_impacts[k] = diag["episodes"] if "episodes" in diag else len(o.impact_rows)
        final = getattr(o, "final_si", None)
        if final is None:  # an outcome without velocities: nothing says it moves
            res.at_rest[k] = True
            continue
        final = np.asarray(final, float)
        speed = getattr(o, "end_speed_si", None)
        res.end_speed[k] = np.hypot(final[:, 0], final[:, 1]) if speed is None else speed
        mask = getattr(o, "at_rest_mask", None)
        if mask is None:  # an Outcome of an earlier crashlab: the same rule as crashlab.outcome
            mask = (res.end_speed[k] <= 0.1) & (np.abs(final[:, 2]) <= 0.1)
        res.at_rest[k] = mask
    if scorer is not None:
        try:
            res.scores[:] = scorer.residuals(outcomes)
        except Exception as err:  # noqa: BLE001 - the batch is unscored: failed, with the reason
            _fail(res, slice(None), _one_line(f"scoring the outcome raised {type(err).__name__}: {err}"))
    return res


# ---------------------------------------------------------------- worker processes
def _die_with_parent(parent_pid: int) -> None:
    """Make this process end when its parent does, whatever kills the parent."""
    if sys.platform.startswith("linux"):
        try:
            import ctypes
            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG: the kernel sends SIGKILL when the parent dies
        except Exception:  # noqa: BLE001 - fall back to the watchdog
            pass
    if os.getppid() != parent_pid:  # the parent died before prctl took effect
        os._exit(1)

    def watchdog():  # portable fallback (needs the GIL; the prctl above does not)
        while True:
            time.sleep(1.0)
            if os.getppid() != parent_pid:
                os._exit(1)
    threading.Thread(target=watchdog, daemon=True).start()


def _worker_main(conn, parent_pid: int, single_thread: bool) -> None:
    """Loop of a worker process: tasks (id, model, options, scenes, split, scorer) in, messages out:
    ("start", id, k0, m) before evaluating scenes k0..k0+m, ("done", id, k0, Evaluations) after."""
    _die_with_parent(parent_pid)
    if single_thread:
        _single_thread()
    while True:
        try:
            task = conn.recv()
        except (EOFError, OSError):
            break
        if task is None:
            break
        tid, model_name, items, scenes, split, scorer = task
        try:
            model = _model(model_name, items)
            units = [(k, 1) for k in range(len(scenes))] if split or not _vectorised(model) else [(0, len(scenes))]
        except Exception:  # noqa: BLE001 - evaluate_scenes records why
            units = [(0, len(scenes))]
        for k0, m in units:
            conn.send(("start", tid, k0, m))
            conn.send(("done", tid, k0, evaluate_scenes(model_name, items, scenes[k0:k0 + m], scorer=scorer)))


def _death_reason(exitcode) -> str:
    if exitcode is not None and exitcode < 0:
        try:
            return f"worker process died ({signal.Signals(-exitcode).name})"
        except ValueError:
            pass
    return f"worker process died (exit code {exitcode})"


class _Worker:
    def __init__(self, ctx, single_thread: bool):
        self.conn, child = ctx.Pipe()
        self.proc = ctx.Process(target=_worker_main, args=(child, os.getpid(), single_thread), daemon=True)
        self.proc.start()
        child.close()
        self.task = None  # (tid, offset, scenes, split) being run
        self.unit = None  # (k0, m, deadline) being evaluated
        self.calls = 0  # units finished
        self.model = None  # the model of the task being run
        self.compiled: set[str] = set()  # models with a finished unit in this worker (compiled)

    def stop(self, kill: bool = False):
        if not kill:
            try:
                self.conn.send(None)
            except (OSError, ValueError):
                pass
            self.proc.join(timeout=5.0)
        if self.proc.is_alive():
            self.proc.kill()
            self.proc.join(timeout=5.0)
        self.conn.close()


class WorkerPool:
    """Worker processes (spawned: a forked child of a process whose numba kernels ran on GNU OpenMP
    threads aborts), each running one task at a time, with per-evaluation deadlines and restarts."""

    def __init__(self, workers: int, timeout_s: float | None, single_thread: bool):
        import multiprocessing
        self.ctx = multiprocessing.get_context("spawn")
        self.n, self.timeout_s, self.single_thread = workers, timeout_s or None, single_thread
        self.workers: list[_Worker] = []
        self.restarts = 0
        self._tid = 0
        self._start_deaths = 0  # consecutive workers lost before their first message

    def close(self):
        for w in self.workers:
            w.stop(kill=w.task is not None)
        self.workers = []

    def _deadline(self, w: _Worker, m: int) -> float:
        if self.timeout_s is None:
            return float("inf")
        grace = FIRST_CALL_GRACE_S if w.model not in w.compiled else 0.0  # each model compiles on its first use
        return time.monotonic() + self.timeout_s * m + grace

    def evaluate(self, model_name: str, items: tuple, chunks: list[list], nv: int, scorer=None) -> Evaluations:
        n = sum(len(c) for c in chunks)
        res = empty_evaluations(n, nv, k=_n_scores(scorer))
        pending = collections.deque()
        offset = 0
        for c in chunks:
            pending.append((offset, c, False))
            offset += len(c)
        from multiprocessing.connection import wait
        while pending or any(w.task is not None for w in self.workers):
            for w in [w for w in self.workers if w.task is None and not w.proc.is_alive()]:
                w.stop(kill=True)  # died while idle
                self.workers.remove(w)
            busy_n = sum(w.task is not None for w in self.workers)
            while len(self.workers) < min(self.n, busy_n + len(pending)):
                self.workers.append(_Worker(self.ctx, self.single_thread))
            for w in self.workers:
                if w.task is None and pending:
                    offset, scenes, split = pending.popleft()
                    self._tid += 1
                    try:
                        w.conn.send((self._tid, model_name, items, scenes, split, scorer))
                    except OSError:  # died just now: the task goes back, the worker is replaced
                        pending.appendleft((offset, scenes, split))
                        w.proc.kill()
                        continue
                    w.task, w.model = (self._tid, offset, scenes, split), model_name
                    # the worker's first message must come within the grace (start, imports, model)
                    w.unit = (0, 0, time.monotonic() + FIRST_CALL_GRACE_S if self.timeout_s else float("inf"))
            busy = [w for w in self.workers if w.task is not None]
            if not busy:
                continue
            now = time.monotonic()
            wait_s = max(0.0, min(w.unit[2] for w in busy) - now)
            ready = wait([x for w in busy for x in (w.conn, w.proc.sentinel)],
                         timeout=None if wait_s == float("inf") else wait_s)
            for w in busy:
                if w.conn in ready or w.proc.sentinel in ready:
                    self._receive(w, res, pending)
                elif time.monotonic() >= w.unit[2]:
                    w.proc.kill()
                    w.proc.join(timeout=5.0)
                    self._lost(w, res, pending, f"timeout: evaluation ran longer than {self.timeout_s:g} s")
        return res

    def _receive(self, w: _Worker, res: Evaluations, pending) -> None:
        while w.task is not None:
            try:
                if not w.conn.poll():
                    if not w.proc.is_alive():
                        w.proc.join(timeout=5.0)
                        self._lost(w, res, pending, _death_reason(w.proc.exitcode))
                    return
                msg = w.conn.recv()
            except (EOFError, OSError):
                w.proc.join(timeout=5.0)
                self._lost(w, res, pending, _death_reason(w.proc.exitcode))
                return
            tid, offset, scenes, split = w.task
            if msg[1] != tid:
                continue
            if msg[0] == "start":
                self._start_deaths = 0
                w.unit = (msg[2], msg[3], self._deadline(w, msg[3]))
            elif msg[0] == "done":
                k0, part = msg[2], msg[3]
                _put(res, offset + k0, part)
                w.calls += 1
                w.compiled.add(w.model)
                w.unit = (k0 + len(part.ok), 0, float("inf"))
                if k0 + len(part.ok) >= len(scenes):
                    w.task = w.unit = None

    def _lost(self, w: _Worker, res: Evaluations, pending, reason: str) -> None:
        """Worker w died or was killed: fail its unit (or split a batch), requeue what it had not begun."""
        tid, offset, scenes, split = w.task
        k0, m, _ = w.unit
        self.restarts += 1
        if m == 0 and k0 == 0:  # died before it began: the model could not even be loaded
            _fail(res, slice(offset, offset + len(scenes)), reason)
            if w.calls == 0:
                self._start_deaths += 1
                if self._start_deaths >= START_FAILURES:
                    raise WorkerStartError(f"{START_FAILURES} worker processes in a row ended before their first "
                                           f"evaluation ({reason}); set [execution] timeout_s = 0 and "
                                           "backend = \"serial\" to simulate in this process")
        elif m == 1:
            _fail(res, offset + k0, reason)
            if k0 + 1 < len(scenes):
                pending.appendleft((offset + k0 + 1, scenes[k0 + 1:], split))
        else:  # a batch (or the rest of the task): again one scene at a time, so only the culprit fails
            pending.appendleft((offset + k0, scenes[k0:], True))
        w.task = w.unit = None
        try:
            w.conn.close()
        except OSError:
            pass


# ---------------------------------------------------------------- Dask
def _append_result(box, model_name, options_items, scenes, scorer):
    box.append(evaluate_scenes(model_name, options_items, scenes, scorer=scorer))


_DASK_CALLS = [0]  # evaluations begun in this (Dask worker) process
_DASK_RESTART_S = 120.0  # s: a restarted Dask worker is back within this (measured 5-40 s on a loaded machine)


def _dask_evaluate(model_name: str, options_items: tuple, scenes: list, timeout_s: float | None,
                   split: bool, grace_s: float = FIRST_CALL_GRACE_S, scorer=None):
    """A Dask task: evaluate scenes with per-evaluation deadlines (in a thread, since a Dask task cannot
    be killed). Returns (Evaluations, begun, hung_worker): begun (n,) bool marks the scenes evaluated
    or failed; the others are to be run again, one at a time; hung_worker is this worker's address when
    an evaluation overran (its thread still runs: the worker is to be restarted)."""
    _single_thread()
    n, nv = len(scenes), len(scenes[0].vehicles)
    if not timeout_s:
        return evaluate_scenes(model_name, options_items, scenes, scorer=scorer), np.ones(n, bool), None
    res = empty_evaluations(n, nv, k=_n_scores(scorer))
    begun = np.zeros(n, bool)
    try:
        vectorised = _vectorised(_model(model_name, options_items))
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
                _fail(res, k0, f"timeout: evaluation ran longer than {timeout_s:g} s")
            from distributed import get_worker
            return res, begun, get_worker().address
        _put(res, k0, box[0])
        begun[k0:k0 + m] = True
    return res, begun, None


class Executor:
    """Runs populations on a backend ('serial', 'processes', 'dask'); a context manager that owns its
    workers. timeout_s: None or 0 for no limit per evaluation (see the module docstring)."""

    def __init__(self, backend: str = "serial", workers: int | None = None, scheduler: str | None = None,
                 timeout_s: float | None = None):
        self.backend = "dask" if scheduler else backend
        self.workers = workers or 2
        self.scheduler = scheduler
        self.timeout_s = timeout_s or None
        self._pool: WorkerPool | None = None
        self._client = None
        self._cluster = None

    def __enter__(self):
        if self.backend == "processes" or (self.backend == "serial" and self.timeout_s):
            serial = self.backend == "serial"
            self._pool = WorkerPool(1 if serial else self.workers, self.timeout_s, single_thread=not serial)
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
        return self._dask(model_name, items, scenes, nv, scorer)

    def _dask(self, model_name, items, scenes, nv, scorer=None) -> Evaluations:
        """Chunks in parallel; the scenes of a task whose workers died (KilledWorker: Dask retried it on
        other workers and they died too) are then run one at a time, alone on the cluster, so a scene
        that merely shared a dying worker is evaluated and only the deadly ones fail."""
        from distributed import KilledWorker
        res = empty_evaluations(len(scenes), nv, k=_n_scores(scorer))
        tasks = []  # (offset, scenes, split)
        offset = 0
        for c in _chunks(scenes, min(len(scenes), self.workers * 2)):
            tasks.append((offset, c, False))
            offset += len(c)
        alone = False  # the second phase: one task at a time
        while tasks:
            batch = tasks[:1] if alone else tasks
            tasks = tasks[1:] if alone else []
            futures = self._client.map(_dask_evaluate, [model_name] * len(batch), [items] * len(batch),
                                       [t[1] for t in batch], [self.timeout_s] * len(batch),
                                       [t[2] for t in batch], [FIRST_CALL_GRACE_S] * len(batch),
                                       [scorer] * len(batch), pure=False)
            # the longest a round can legitimately take: every scene of it one after the other, after the
            # first-call grace and a restart of the workers (Dask closes a worker gracefully first)
            bound = None if self.timeout_s is None else FIRST_CALL_GRACE_S + _DASK_RESTART_S + self.timeout_s * sum(
                len(t[1]) for t in batch)
            hung = set()
            for (offset, chunk, _), fut in zip(batch, futures):
                try:
                    part, begun, hung_worker = fut.result(timeout=bound)
                except KilledWorker:
                    if alone and len(chunk) == 1:
                        _fail(res, offset, "Dask worker died while evaluating (KilledWorker)")
                    else:
                        tasks += [(offset + k, [s], True) for k, s in enumerate(chunk)]
                    continue
                except Exception as err:  # noqa: BLE001 - lost connection, a task that cannot run, no answer
                    fut.cancel()
                    _fail(res, slice(offset, offset + len(chunk)), _one_line(f"Dask task failed: {err!r}"))
                    continue
                _put(res, offset, part)
                tasks += [(offset + k, [chunk[k]], True) for k in np.flatnonzero(~begun)]
                if hung_worker:
                    hung.add(hung_worker)
            if hung:
                try:
                    self._client.restart_workers(sorted(hung), raise_for_error=False)
                except Exception:  # noqa: BLE001 - the run goes on with the workers it has
                    pass
            alone = True
        return res


def _chunks(scenes: list, n_chunks: int) -> list[list]:
    return [list(c) for c in np.array_split(np.array(scenes, dtype=object), n_chunks) if len(c)]
