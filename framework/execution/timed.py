"""One run of a model on a scene with a time limit (`crashlab simulate --timeout`): the run is in a worker
process that is killed when it overruns (crashlab.execution's rule: Python cannot interrupt a compiled
kernel). The pool (crashlab.execution.pool) does the same for a population; this is its one-scene form,
which returns the Outcome itself (trajectories and all) instead of a Population.
"""
from __future__ import annotations

import multiprocessing
import os
import time
from collections.abc import Callable

from .constants import FIRST_CALL_GRACE_S
from .pool import die_with_parent

WARM_UP_S = 0.05  # s of the scene the worker simulates first, untimed: it loads or compiles the kernels


class TimedOut(Exception):
    """The run took longer than its time limit and its worker process was stopped."""

    def __init__(self, model_name: str, timeout_s: float):
        self.model_name, self.timeout_s = model_name, timeout_s
        super().__init__(f"model {model_name}: the run took longer than {timeout_s:g} s and was stopped")


def _worker(conn, model_name: str, scene) -> None:
    """The worker process: a model that compiles (CollisionModel.compiles) warmed up on the scene's first
    WARM_UP_S (an exception there is left to the run), "ready", then the run, its Outcome (or the exception's
    one line) sent back."""
    from ..registry import get_model
    die_with_parent(conn.recv())
    try:
        model = get_model(model_name)
        if model.compiles is not None:
            try:
                model.simulate(scene.replace(duration=min(scene.duration, WARM_UP_S)))
            except Exception:  # noqa: BLE001 - the run that follows meets it and reports it
                pass
        conn.send(("ready", None))
        conn.send(("done", model.simulate(scene)))
    except Exception as err:  # noqa: BLE001 - sent back as one line
        conn.send(("error", f"{type(err).__name__}: {err}"))


def simulate_with_timeout(model_name: str, scene, timeout_s: float, on_ready: Callable[[], None] | None = None):
    """The Outcome of model `model_name` (a registered name or 'module:Class') on the scene, run in a worker
    process that is killed when the run takes longer than timeout_s: the worker's start and warm-up (loading
    or compiling the kernels) get FIRST_CALL_GRACE_S, the run itself timeout_s. on_ready: called here when the
    warm-up has ended (the command line announces a cold compile's time with it). A run over its time raises
    TimedOut; a worker that fails or dies, RuntimeError with the reason."""
    ctx = multiprocessing.get_context("spawn")  # as the pool: no fork after numba's threads ran
    conn, child = ctx.Pipe()
    proc = ctx.Process(target=_worker, args=(child, model_name, scene), daemon=True)
    proc.start()
    child.close()
    conn.send(os.getpid())
    try:
        deadline = time.monotonic() + FIRST_CALL_GRACE_S + timeout_s
        while True:
            if not conn.poll(max(0.0, deadline - time.monotonic())):
                raise TimedOut(model_name, timeout_s)
            try:
                kind, value = conn.recv()
            except EOFError:  # the worker died (segfault, out of memory, killed)
                proc.join(timeout=5.0)
                raise RuntimeError(f"the run's worker process died (exit {proc.exitcode})") from None
            if kind == "ready":
                deadline = time.monotonic() + timeout_s
                if on_ready is not None:
                    on_ready()
            elif kind == "done":
                return value
            else:
                raise RuntimeError(value)
    finally:
        if proc.is_alive():
            proc.kill()
        proc.join(timeout=5.0)
        conn.close()
