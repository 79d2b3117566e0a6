"""Where simulations of a population run: in this process, in worker processes, or on a Dask cluster.

A population is cut into chunks; each chunk is simulated by `evaluate_in_process`: Variants (one scene,
fields and a block of rows; the model's `simulate_population`, so only the scene and the rows travel) or a
list of Scenes (the model's `simulate_batch`); every chunk comes back as a Population (crashlab.population,
arrays). Results are deterministic and placed by index, so every backend gives the same answer. Compile once:
the first evaluation of a model runs alone on one worker, which compiles it and fills the numba cache
(crashlab.numba_cache); the other workers start after it and load the cache (on a cluster of several machines
give them one NUMBA_CACHE_DIR on a shared file system, or run a model once on each machine first).

Every evaluation ends with a result or with a reason why it failed (`Population.reason`); nothing is
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
One scene with a time limit (`crashlab simulate --timeout`): `simulate_with_timeout` (execution.timed), the
same rule for a single run, which returns the Outcome itself.
With `timeout_s` None or 0 the serial backend simulates in this process (exceptions still fail single
evaluations; a hang then hangs the run).

A scorer (the reconstruction's evidence: reconstruction.evidence.EvidenceSet) scores each Outcome where it was
simulated, so evidence that needs more than rest poses (impact rows, paths) runs on every backend with its
timeout and only its numbers travel back: an object with `n_residuals`, `needs_trajectory` (simulate one by
one: a batch records no paths) and `residuals(outcomes) -> (n, n_residuals)`, picklable; the numbers are in
Population.scores. On Variants the scorer has `population_residuals(population)` instead, scored on the arrays.
"""
from ..population import Population, Variants
from .constants import DEFAULT_TIMEOUT_S, FIRST_CALL_GRACE_S, TIMEOUT_MIN_S
from .evaluate import empty_population, evaluate_in_process, evaluate_variants
from .executor import Executor
from .models import model_for, model_instance
from .pool import WorkerPool, WorkerStartError
from .timed import TimedOut, simulate_with_timeout

__all__ = ["DEFAULT_TIMEOUT_S", "FIRST_CALL_GRACE_S", "TIMEOUT_MIN_S", "Executor", "Population", "TimedOut", "Variants",
           "WorkerPool", "WorkerStartError", "empty_population", "evaluate_in_process", "evaluate_variants",
           "model_for", "model_instance", "simulate_with_timeout"]
