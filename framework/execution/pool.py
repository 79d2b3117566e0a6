"""Worker processes with per-evaluation deadlines and restarts (crashlab.execution, module docstring)."""
from __future__ import annotations

import collections
import os
import signal
import sys
import threading
import time

from ..population import Population
from .constants import FIRST_CALL_GRACE_S
from .evaluate import _n_scores, _single_thread, _vectorised, evaluate_in_process, names_of
from .models import model_instance


class WorkerStartError(RuntimeError):
    """Worker processes die before they evaluate anything (an environment problem, not a model's)."""


START_FAILURES = 3  # consecutive workers that die before their first evaluation: the pool gives up


def die_with_parent(parent_pid: int) -> None:
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
    ("start", id, k0, m) before evaluating scenes k0..k0+m, ("done", id, k0, Population) after."""
    die_with_parent(parent_pid)
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
            model = model_instance(model_name, items)
            units = [(k, 1) for k in range(len(scenes))] if split or not _vectorised(model) else [(0, len(scenes))]
        except Exception:  # noqa: BLE001 - evaluate_in_process records why
            units = [(0, len(scenes))]
        for k0, m in units:
            conn.send(("start", tid, k0, m))
            conn.send(("done", tid, k0, evaluate_in_process(model_name, items, scenes[k0:k0 + m], scorer=scorer)))


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

    def __init__(self, workers: int, timeout_s: float | None, single_thread: bool,
                 grace_s: float = FIRST_CALL_GRACE_S):
        import multiprocessing
        self.ctx = multiprocessing.get_context("spawn")
        self.n, self.timeout_s, self.single_thread = workers, timeout_s or None, single_thread
        self.grace_s = grace_s  # s on top of each model's first call in a worker (constants.FIRST_CALL_GRACE_S)
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
        grace = self.grace_s if w.model not in w.compiled else 0.0  # each model compiles on its first use
        return time.monotonic() + self.timeout_s * m + grace

    def evaluate(self, model_name: str, items: tuple, chunks: list, scorer=None) -> Population:
        """The Population of the work chunks (Variants blocks or lists of Scenes), in order."""
        n = sum(len(c) for c in chunks)
        res = Population.empty(n, names_of(chunks[0]), k=_n_scores(scorer))
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
                    w.unit = (0, 0, time.monotonic() + self.grace_s if self.timeout_s else float("inf"))
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

    def _receive(self, w: _Worker, res: Population, pending) -> None:
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
                res.put(offset + k0, part)
                w.calls += 1
                w.compiled.add(w.model)
                w.unit = (k0 + len(part), 0, float("inf"))
                if k0 + len(part) >= len(scenes):
                    w.task = w.unit = None

    def _lost(self, w: _Worker, res: Population, pending, reason: str) -> None:
        """Worker w died or was killed: fail its unit (or split a batch), requeue what it had not begun."""
        tid, offset, scenes, split = w.task
        k0, m, _ = w.unit
        self.restarts += 1
        if m == 0 and k0 == 0:  # died before it began: the model could not even be loaded
            res.fail(slice(offset, offset + len(scenes)), reason)
            if w.calls == 0:
                self._start_deaths += 1
                if self._start_deaths >= START_FAILURES:
                    raise WorkerStartError(f"{START_FAILURES} worker processes in a row ended before their first "
                                           f"evaluation ({reason}); set [execution] timeout_s = 0 and "
                                           "backend = \"serial\" to simulate in this process")
        elif m == 1:
            res.fail(offset + k0, reason)
            if k0 + 1 < len(scenes):
                pending.appendleft((offset + k0 + 1, scenes[k0 + 1:], split))
        else:  # a batch (or the rest of the task): again one scene at a time, so only the culprit fails
            pending.appendleft((offset + k0, scenes[k0:], True))
        w.task = w.unit = None
        try:
            w.conn.close()
        except OSError:
            pass
