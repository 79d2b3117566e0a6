"""crashlab.execution: every evaluation ends with a result or a reason. A model that raises, hangs past
`timeout_s` or kills its worker process fails only its own evaluations and the run goes on, on every
backend; no worker process outlives its run, even when the run is killed with SIGKILL.

The misbehaving models are classes of this module, given to the executor as 'test_execution:Class'
(spawned workers import this module by name)."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

import crashlab
from crashlab import execution
from crashlab.execution import Executor, evaluate_in_process
from crashlab.model import simulate_each
from crashlab.population import Population

REPO = Path(__file__).resolve().parent.parent
SIDE = REPO / "studies" / "pc_crash" / "side.toml"
HERE = Path(__file__).resolve().parent
SPEEDS = [40.0, 45.0, 65.0, 50.0, 70.0, 55.0]  # V1 km/h; above 60 the misbehaving models misbehave


def _bad(scene) -> bool:
    return scene.vehicles[0].speed * 3.6 > 60.0


class EchoModel(crashlab.CollisionModel):
    """Pure Python, instant (no numba to load in a fresh worker): every vehicle ends 1 m per km/h of V1's
    speed further along x, at rest."""
    name = "echo"

    def simulate(self, scene):
        shift = scene.vehicles[0].speed * 3.6
        rest = [(v.x + shift, v.y, v.heading) for v in scene.vehicles]
        return crashlab.Outcome(scene.vehicle_names, rest, np.zeros((len(rest), 3)), model=self.name,
                                impact_rows=[{"t": 0.1, "vehicle": "V1", "other": "V2", "energy": 0.0,
                                              "side": "front"}])


class RaisingModel(EchoModel):
    def simulate(self, scene):
        if _bad(scene):
            raise RuntimeError("solver blew up")
        return super().simulate(scene)


class ImpactTimeScorer:
    """Scores each outcome by what only the Outcome carries (its first impact row's time, V1's rest x), as the
    reconstruction's evidence does with the point of impact or a mark (crashlab.execution, scorer)."""
    n_residuals, needs_trajectory = 2, False

    def residuals(self, outcomes):
        return np.array([[o.impact_rows[0]["t"], o.rest_si[0][0]] if isinstance(o, crashlab.Outcome)
                         and o.outcome_ok else [np.nan, np.nan] for o in outcomes])


class SlowFirstCallModel(EchoModel):
    """Its first call in a process takes 2.5 s (as a model that numba compiles on first use)."""
    compiled = False

    def simulate(self, scene):
        if not SlowFirstCallModel.compiled:
            time.sleep(2.5)
            SlowFirstCallModel.compiled = True
        return super().simulate(scene)


class HangingModel(EchoModel):
    """Hangs (sleeps for an hour) where V1 is faster than 60 km/h."""

    def simulate(self, scene):
        if _bad(scene):
            time.sleep(3600)
        return super().simulate(scene)


class LoggingModel(EchoModel):
    """Appends (pid, start, end, scenes) of every batch to the file named by CRASHLAB_TEST_LOG."""

    def simulate_batch(self, scenes):
        t0 = time.time()
        out = [self.simulate(s) for s in scenes]
        time.sleep(0.2)
        with open(os.environ["CRASHLAB_TEST_LOG"], "a") as f:
            f.write(f"{os.getpid()} {t0} {time.time()} {len(scenes)}\n")
        return out


class DyingModel(EchoModel):
    """Kills its own process (SIGKILL, as the out-of-memory killer would) where V1 is faster than 60 km/h."""

    def simulate(self, scene):
        if _bad(scene):
            os.kill(os.getpid(), signal.SIGKILL)
        return super().simulate(scene)


class HangingBatchModel(HangingModel):
    """A vectorised simulate_batch that hangs when any scene of the batch is bad."""

    def simulate_batch(self, scenes):
        if any(_bad(s) for s in scenes):
            time.sleep(3600)
        return [EchoModel.simulate(self, s) for s in scenes]


class DiesAtStart(EchoModel):
    def __init__(self, **options):
        os.kill(os.getpid(), signal.SIGKILL)


def _scenes():
    base = crashlab.load_scene(SIDE)
    return [base.with_vehicle("V1", speed=v / 3.6) for v in SPEEDS]


@pytest.fixture(scope="module")
def reference() -> Population:
    return evaluate_in_process("test_execution:EchoModel", (), _scenes())


@pytest.fixture
def short_grace():
    """first_call_grace_s for these tests' executors: a worker's first call gets 30 s more (loading the
    model's numba cache), not 600 s; the deadline is kept by this process. The hanging scenes are never a
    worker's first call here."""
    return 30.0


def _check(ev: Population, reference: Population, words: str):
    bad = np.array([v > 60.0 for v in SPEEDS])
    print("\n" + "\n".join(f"  {v:.0f} km/h: {r or 'ok'}" for v, r in zip(SPEEDS, ev.reason)))
    assert not ev.ok[bad].any() and ev.ok[~bad].all()
    assert all(words in r for r in ev.reason[bad]) and all(r == "" for r in ev.reason[~bad])
    np.testing.assert_array_equal(ev.rest[~bad], reference.rest[~bad])  # the others are untouched
    assert np.isnan(ev.rest[bad]).all()


def test_exception_in_this_process_fails_that_evaluation_with_its_reason(reference):
    """The serial backend without timeout (in this process): an exception is a failed evaluation with the
    exception as its reason, never the end of the run."""
    with Executor("serial", timeout_s=0) as ex:
        ev = ex.evaluate("test_execution:RaisingModel", {}, _scenes())
    _check(ev, reference, "model raised RuntimeError: solver blew up")


def test_outcome_failed_by_the_guard_carries_the_guards_reason():
    class Guarded:
        def simulate_batch(self, scenes):
            out = [EchoModel().simulate(s) for s in scenes]
            out[1].fail("interpenetration", "V1 and V2 overlap by 0.40 m at the end")
            return out
    scenes = _scenes()[:3]  # what evaluate_in_process does with the model it builds
    masses = np.array([[v.spec.mass for v in s.vehicles] for s in scenes])
    ev = Population.of_outcomes(simulate_each(Guarded(), scenes), scenes[0].vehicle_names, masses)
    assert list(ev.ok) == [True, False, True]
    assert ev.reason[1] == "physics guard: interpenetration: V1 and V2 overlap by 0.40 m at the end"


@pytest.mark.parametrize("backend", ["serial", pytest.param("processes", marks=pytest.mark.slow)])
def test_the_evidence_is_scored_where_the_scenes_run_with_the_timeout(backend, reference, short_grace):
    """A scorer (the evidence of impact rows or paths) runs in the worker beside the simulation: the hanging
    scenes time out and fail, unscored; the others carry the scores of their own outcomes (scores of the
    same outcomes in this process for comparison)."""
    with Executor(backend, workers=2, first_call_grace_s=short_grace, timeout_s=2.0) as ex:
        ev = ex.evaluate("test_execution:HangingModel", {}, _scenes(), scorer=ImpactTimeScorer())
    _check(ev, reference, "timeout: evaluation ran longer than 2 s")
    bad = np.array([v > 60.0 for v in SPEEDS])
    assert np.isnan(ev.scores[bad]).all()
    want = ImpactTimeScorer().residuals([EchoModel().simulate(s) for s in np.array(_scenes())[~bad]])
    np.testing.assert_array_equal(ev.scores[~bad], want)
    assert ev.scores.shape == (len(SPEEDS), 2) and np.all(ev.scores[~bad, 0] == 0.1)


def test_a_scorer_that_raises_fails_its_batch_with_the_reason():
    class Raising(ImpactTimeScorer):
        def residuals(self, outcomes):
            raise ValueError("no impact row")
    ev = evaluate_in_process("test_execution:EchoModel", (), _scenes()[:2], scorer=Raising())
    assert not ev.ok.any() and all("scoring the outcome raised ValueError: no impact row" in r for r in ev.reason)


def test_each_models_first_call_in_a_worker_gets_the_compile_grace(reference, short_grace):
    """A worker that has run one model still compiles the next one on its first call: the grace is per model
    (it was per worker: a refine step's multibody batch timed out in a worker that had run the search)."""
    with Executor("serial", first_call_grace_s=short_grace, timeout_s=1.0) as ex:
        ex.evaluate("test_execution:EchoModel", {}, _scenes())
        ev = ex.evaluate("test_execution:SlowFirstCallModel", {}, _scenes())
    assert ev.ok.all(), ev.reason
    np.testing.assert_array_equal(ev.rest, reference.rest)


@pytest.mark.parametrize("backend", ["serial", pytest.param("processes", marks=pytest.mark.slow)])
def test_a_hanging_evaluation_times_out_and_the_run_goes_on(backend, reference, short_grace):
    t0 = time.perf_counter()
    with Executor(backend, workers=2, first_call_grace_s=short_grace, timeout_s=2.0) as ex:
        ev = ex.evaluate("test_execution:HangingModel", {}, _scenes())
        again = ex.evaluate("test_execution:EchoModel", {}, _scenes())  # the pool still serves
    print(f"\n{backend}: {time.perf_counter() - t0:.1f} s for two hangs of an hour at a 2 s timeout")
    _check(ev, reference, "timeout: evaluation ran longer than 2 s")
    np.testing.assert_array_equal(again.rest, reference.rest)


@pytest.mark.slow  # the hanging batch is the worker's first call: 30 s of grace first
def test_a_vectorised_batch_that_hangs_is_split_so_only_the_culprits_fail(reference, short_grace):
    with Executor("serial", first_call_grace_s=short_grace, timeout_s=1.0) as ex:
        ev = ex.evaluate("test_execution:HangingBatchModel", {}, _scenes())
        assert ex._pool.restarts == 3  # the batch, then each of the two hanging scenes
    _check(ev, reference, "timeout")


@pytest.mark.parametrize("backend", ["serial", "processes"])
def test_a_worker_that_dies_fails_its_evaluation_and_the_run_goes_on(backend, reference):
    with Executor(backend, workers=2, timeout_s=60.0) as ex:
        ev = ex.evaluate("test_execution:DyingModel", {}, _scenes())
    _check(ev, reference, "worker process died (SIGKILL)")


def test_a_model_that_cannot_be_built_fails_every_evaluation_with_the_reason():
    with Executor("serial", timeout_s=5.0) as ex:
        ev = ex.evaluate("no_such_module_anywhere:Model", {}, _scenes())
    assert not ev.ok.any()
    assert all(r.startswith("model could not be built: ModuleNotFoundError") for r in ev.reason)


@pytest.mark.slow
def test_workers_that_die_at_start_stop_the_run():
    with Executor("processes", workers=2, timeout_s=5.0) as ex:
        with pytest.raises(execution.WorkerStartError, match="ended before their first evaluation"):
            ex.evaluate("test_execution:DiesAtStart", {}, _scenes())


def test_the_first_evaluation_runs_alone_so_the_model_compiles_once(tmp_path, monkeypatch, reference):
    """Compile once: the executor's first evaluation of a model runs alone on one worker (which compiles the
    model and fills the numba cache), the other workers start after it and load the cache."""
    log = tmp_path / "calls.txt"
    monkeypatch.setenv("CRASHLAB_TEST_LOG", str(log))
    with Executor("processes", workers=2, timeout_s=60, first_call_grace_s=30) as ex:
        ev = ex.evaluate("test_execution:LoggingModel", {}, _scenes())
    np.testing.assert_array_equal(ev.rest, reference.rest)
    calls = sorted((float(t0), float(t1), int(n), int(pid)) for pid, t0, t1, n in
                   (line.split() for line in log.read_text().splitlines()))
    print("\n" + "\n".join(f"  pid {c[3]}: {c[2]} scenes, {c[0] - calls[0][0]:.2f}-{c[1] - calls[0][0]:.2f} s"
                            for c in calls))
    assert calls[0][2] == 1, "the first call is one evaluation"
    assert all(c[0] >= calls[0][1] for c in calls[1:]), "the others start after it"
    assert len({c[3] for c in calls}) == 2 and sum(c[2] for c in calls) == len(SPEEDS)


def _children(pid):
    import psutil
    try:
        return psutil.Process(pid).children(recursive=True)
    except psutil.NoSuchProcess:
        return []


@pytest.mark.parametrize("backend", ["serial", "processes",
                                     pytest.param("dask", marks=pytest.mark.slow)])
def test_no_worker_outlives_a_run_killed_with_sigkill(tmp_path, backend):
    """A run whose workers hang is killed with SIGKILL (no cleanup code runs): the kernel ends its
    workers (PR_SET_PDEATHSIG) within seconds."""
    import psutil
    script = tmp_path / "run.py"
    script.write_text(textwrap.dedent(f"""
        import sys
        sys.path.insert(0, {str(HERE)!r})
        import crashlab
        from crashlab.execution import Executor
        if __name__ == "__main__":
            base = crashlab.load_scene({str(SIDE)!r})
            # the first evaluation runs alone (the executor's compile-once), then both workers hang
            scenes = [base.with_vehicle("V1", speed=50 / 3.6)] + [base.with_vehicle("V1", speed=70 / 3.6)] * 4
            with Executor({backend!r}, workers=2, timeout_s=3600) as ex:
                ex.evaluate("test_execution:HangingModel", {{}}, scenes)
    """))
    proc = subprocess.Popen([sys.executable, str(script)])
    want = 1 if backend == "serial" else 2
    if backend == "dask":
        pytest.importorskip("dask.distributed")
    deadline = time.monotonic() + 120
    kids = []
    while time.monotonic() < deadline and len(kids) < want:
        time.sleep(0.5)
        kids = [k for k in _children(proc.pid) if "python" in k.name().lower()
                and "resource_tracker" not in " ".join(k.cmdline())]
    assert len(kids) >= want, f"the run started its workers: {kids}"
    time.sleep(2.0 if backend != "dask" else 8.0)  # the workers are inside their hanging evaluations
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait(timeout=30)
    t0 = time.monotonic()
    alive = kids
    while alive and time.monotonic() - t0 < 30:
        time.sleep(0.2)
        alive = [k for k in kids if k.is_running() and k.status() != psutil.STATUS_ZOMBIE]
    print(f"\n{backend}: {len(kids)} workers; alive {time.monotonic() - t0:.1f} s after the run was killed: "
          f"{len(alive)}")
    for k in alive:
        k.kill()
    assert not alive, "workers outlived their killed run"


def test_pool_stops_its_workers_when_the_run_ends():
    import psutil
    with Executor("processes", workers=2, timeout_s=30.0) as ex:
        ex.evaluate("impulse", {}, _scenes())
        procs = [psutil.Process(w.proc.pid) for w in ex._pool.workers]
        assert len(procs) == 2 and all(p.is_running() for p in procs)
    time.sleep(0.5)
    assert not any(p.is_running() and p.status() != psutil.STATUS_ZOMBIE for p in procs)


@pytest.mark.slow
def test_dask_a_dying_worker_fails_its_evaluations_and_the_run_goes_on(reference):
    """Dask retries a task whose worker died (3 times), then reports KilledWorker: the chunk is split and
    run again scene by scene, so only the deadly scenes fail."""
    _dask_then_echo("DyingModel", 60.0, reference, "Dask worker died")


@pytest.mark.slow
def test_dask_a_hanging_evaluation_times_out(reference, short_grace):
    _dask_then_echo("HangingModel", 2.0, reference, "timeout: evaluation ran longer than 2 s", short_grace)


def _dask_then_echo(model: str, timeout_s: float, reference, words: str, grace_s: float = 600.0):
    """On a local Dask cluster: `model` fails with `words`, and the cluster then evaluates as before."""
    pytest.importorskip("dask.distributed")
    with Executor("dask", workers=2, timeout_s=timeout_s, first_call_grace_s=grace_s) as ex:
        ev = ex.evaluate(f"test_execution:{model}", {}, _scenes())
        again = ex.evaluate("test_execution:EchoModel", {}, _scenes())
    _check(ev, reference, words)
    np.testing.assert_array_equal(again.rest, reference.rest)
