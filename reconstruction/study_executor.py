"""A study's executor (crashlab.execution.Executor) for the search, the posterior and the refine step, whose
scheduler, when it does not answer, is refused with one line naming the study file and where the address came
from (--scheduler or execution.scheduler): the executor's own line names neither."""
from __future__ import annotations

from contextlib import ExitStack, contextmanager

from crashlab.errors import InputError
from crashlab.execution import Executor


def refuse_empty_scheduler(path, key: str, scheduler: str | None, instead: str) -> None:
    """InputError naming `key` when a scheduler address is given empty (`instead`: what to do then)."""
    if scheduler is not None and not scheduler.strip():
        raise InputError(path, key, f"an empty address: give a Dask scheduler's (tcp://HOST:8786), or {instead}")


@contextmanager
def open_executor(path, backend: str, workers: int, scheduler: str | None, timeout_s, key: str):
    """The entered Executor; InputError(path, key, ...) when its Dask scheduler does not answer."""
    with ExitStack() as stack:
        try:
            executor = stack.enter_context(Executor(backend, workers, scheduler, timeout_s))
        except InputError as err:
            if err.file != "execution" or err.key != "scheduler":
                raise
            raise InputError(path, key, err.problem) from None
        yield executor
