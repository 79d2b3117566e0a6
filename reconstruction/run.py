"""The run of a study: the search, driven by pymoo, then the least-squares polish, then the outputs.

pymoo runs the algorithm (`Algorithm.run`); a pymoo Callback, called after every generation, writes the
checkpoint, moves the progress bar and ends a test's run early (`stop_after`). `pymoo.optimize.minimize`
is not used: it deep-copies the algorithm and sets it up only when it has no problem yet, then calls
`run`; here a fresh algorithm must be set up before its first evaluation (its first checkpoint refuses
an optimizer whose state cannot be saved before any simulation) and a resumed one is set up already, so
all minimize would add is the copy.

Resume. The checkpoint (DIR/checkpoint.pkl, after every generation) holds a fingerprint of what the
result depends on (Study.fingerprint): the study file's content (without the execution backend and
workers, which do not change results), the base scene and every vehicle's data as loaded (so edits of
comments change nothing), the evidence as used (a twin's evidence is the model's run), the model and its
options, and the crashlab version. `--resume` refuses a checkpoint whose fingerprint differs, or that
cannot be read.
"""
from __future__ import annotations

import copy
import os
import pickle
import time
from pathlib import Path

import numpy as np
from pymoo.core.callback import Callback

from crashlab.errors import InputError
from crashlab.execution import WorkerStartError
from crashlab.outdir import lock_out_dir

from .html_report import write_reconstruction_report
from .polish import polish_archive
from .problem import scored_feasible
from .refine import refine
from .report import ReconstructionResult, pareto_table, write_outputs
from .schema import WORKERS_MAX
from .study_executor import open_executor, refuse_empty_scheduler

CHECKPOINT_FORMAT = "crashlab reconstruction checkpoint 4"  # 3: the archive keeps every residual vector; 4: the
# problem sets its variables through crashlab.fields (uncertain parameters)


def _atomic_pickle(path: Path, obj):
    tmp = path.with_suffix(path.suffix + ".tmp")
    with open(tmp, "wb") as fh:
        pickle.dump(obj, fh, protocol=pickle.HIGHEST_PROTOCOL)
    os.replace(tmp, path)  # atomic: a kill leaves the previous or the new checkpoint, never half of one


def save_checkpoint(ckpt: Path, fingerprint: dict, algorithm, name: str, generation_done: bool = False):
    """Write the algorithm's state. generation_done: called from the Callback, where pymoo has not yet
    counted the generation (n_iter); the state saved is the one `next()` leaves, as a resume expects."""
    state = copy.copy(algorithm)  # shallow: everything but the two attributes below is the live state
    state.callback = Callback()  # the live callback holds a progress bar: no state of the search
    if generation_done:
        state.n_iter += 1
    try:
        _atomic_pickle(ckpt, {"format": CHECKPOINT_FORMAT, "fingerprint": fingerprint, "optimizer": name,
                              "algorithm": state})
    except (pickle.PicklingError, TypeError, AttributeError) as err:
        raise InputError(ckpt, "--out", f"the state of optimizer {name!r} cannot be saved for --resume "
                         f"({err}); run it without --out") from None
    except OSError as err:
        raise InputError(ckpt, "--out", err.strerror or str(err)) from None


def read_checkpoint(ckpt: Path, fingerprint: dict, fmt: int, what: str = "checkpoint") -> dict:
    """The checkpoint file's dict, made by this crashlab (format `fmt`) from this very study (its
    fingerprint); else InputError naming --resume (search and posterior checkpoints alike)."""
    if not ckpt.is_file():
        raise InputError(ckpt, "--resume", "no checkpoint to resume from (give the --out DIR of the run)")
    try:
        with open(ckpt, "rb") as fh:
            data = pickle.load(fh)
    except Exception as err:  # noqa: BLE001 - any unreadable file is the same one line
        raise InputError(ckpt, "--resume", f"cannot read the checkpoint ({type(err).__name__}): the file is "
                         "corrupt or not a checkpoint; start again without --resume") from None
    if not isinstance(data, dict) or data.get("format") != fmt:
        raise InputError(ckpt, "--resume", f"not a {what} of this crashlab version (no study fingerprint); "
                         "start again without --resume")
    theirs = data.get("fingerprint", {})
    changed = [k for k in sorted(set(fingerprint) | set(theirs)) if fingerprint.get(k) != theirs.get(k)]
    if changed:
        raise InputError(ckpt, "--resume", f"the checkpoint was made from a different study ({', '.join(changed)} "
                         "changed); start again without --resume, or give another --out")
    return data


def load_checkpoint(ckpt: Path, fingerprint: dict, optimizer: str | None):
    """The algorithm and optimizer name of a search checkpoint of this very study, else InputError."""
    data = read_checkpoint(ckpt, fingerprint, CHECKPOINT_FORMAT)
    if optimizer and optimizer != data["optimizer"]:
        raise InputError(ckpt, "--optimizer", f"the checkpoint was made with optimizer {data['optimizer']!r}, "
                         f"not {optimizer!r}")
    return data["algorithm"], data["optimizer"]


def status(problem, hv_ref) -> str:
    """One line of progress: evaluations, the feasible share of all of them (ok and within the constraints: the
    summary's feasible_fraction, so the last line and the summary say the same), best objectives, HV."""
    from pymoo.indicators.hv import HV
    allF = np.concatenate(problem.archive["F"])
    allfeas = np.all(np.concatenate(problem.archive["G"]) <= 0, axis=1) & np.concatenate(problem.archive["ok"])
    evals = len(allF)
    if allfeas.any():
        best = allF[allfeas].min(axis=0)
        hv = HV(ref_point=np.full(allF.shape[1], hv_ref))(allF[allfeas])
        best_s = " ".join(f"{b:.2f}" for b in best)
    else:
        hv, best_s = 0.0, "-"
    unit = "m" if getattr(problem, "evidence_set", None) is None else "sigma"  # the misfit is normalised
    return f"evals {evals} feasible {allfeas.mean():.1%} best [{best_s}] {unit} HV {hv:.2f}"


class _Stopped(Exception):
    """The run reached stop_after: it ends as a kill would."""


class GenerationEnd(Callback):
    """pymoo calls this after every generation (a loop-wise algorithm such as MOEA/D: after its last
    step of a generation only): checkpoint, progress bar, stop_after."""

    def __init__(self, ckpt: Path | None, fingerprint: dict, name: str, bar, hv_ref: float, done: int,
                 stop_after: int | None):
        super().__init__()
        self.ckpt, self.fingerprint, self.name = ckpt, fingerprint, name
        self.bar, self.hv_ref, self.done, self.stop_after = bar, hv_ref, done, stop_after

    def notify(self, algorithm):
        gen = int(algorithm.n_iter)  # the generation just done (pymoo counts n_iter up after the callback)
        if self.ckpt is not None:
            save_checkpoint(self.ckpt, self.fingerprint, algorithm, self.name, generation_done=True)
        if self.bar is not None:
            self.bar.set_postfix_str(status(algorithm.problem, self.hv_ref))
            self.bar.update(gen - self.done)
        self.done = gen
        if self.stop_after is not None and gen >= self.stop_after and algorithm.has_next():
            raise _Stopped


def _backend(study, workers, scheduler) -> str:
    ex = study.spec.execution
    if workers is not None and not 1 <= workers <= WORKERS_MAX:
        raise InputError(study.path, "--workers", f"must be in [1, {WORKERS_MAX}], got {workers}")
    refuse_empty_scheduler(study.path, "--scheduler", scheduler, "leave the option out for the study's [execution]")
    # (a study's own scheduler comes with backend = "dask" only: crashlab.reconstruction.study.check_execution)
    if scheduler or ex.scheduler or (workers and ex.backend == "serial"):
        return "dask"
    return ex.backend


def _start(study, optimizer, out_dir: Path | None, resume: bool, fingerprint: dict):
    """(optimizer name, algorithm set up on its problem): new, or from the checkpoint in out_dir."""
    ckpt = out_dir / "checkpoint.pkl" if out_dir else None
    if resume:
        if ckpt is None:
            raise InputError(study.path, "--resume", "no checkpoint to resume from (give --out DIR)")
        algorithm, name = load_checkpoint(ckpt, fingerprint, optimizer)
    else:
        name, algorithm = study.make_algorithm(optimizer)
        problem = study.make_problem(constraints_as_penalty=not getattr(algorithm, "handles_constraints", True))
        algorithm.setup(problem, termination=("n_gen", study.spec.optimizer.generations),
                        seed=study.spec.optimizer.seed, verbose=False)
    if out_dir:
        try:
            out_dir.mkdir(parents=True, exist_ok=True)
        except OSError as err:
            raise InputError(out_dir, "--out", err.strerror or str(err)) from None
        if not resume:  # before any evaluation: an optimizer whose state cannot be saved is refused now
            save_checkpoint(ckpt, fingerprint, algorithm, name)
    return name, algorithm


def run_study(study, optimizer=None, workers=None, scheduler=None, out_dir=None, resume=False, progress=False,
              stop_after=None, started=None) -> ReconstructionResult | None:
    """Search, polish, and (with out_dir) write the outputs (Study.run)."""
    try:
        with lock_out_dir(out_dir, "reconstruct --resume" if resume else "reconstruct"):  # one writer per DIR
            return _run(study, optimizer, workers, scheduler, out_dir, resume, progress, stop_after, started)
    except WorkerStartError as err:
        raise InputError(study.path, "execution", str(err)) from None


def _run(study, optimizer, workers, scheduler, out_dir, resume, progress, stop_after, started=None):
    t0 = time.perf_counter()
    ex, spec = study.spec.execution, study.spec
    backend = _backend(study, workers, scheduler)
    out_dir = Path(out_dir) if out_dir else None
    fingerprint = study.fingerprint() if out_dir else {}  # only a checkpoint needs it
    name, algorithm = _start(study, optimizer, out_dir, resume, fingerprint)
    problem = algorithm.problem
    done = max(int(algorithm.n_iter or 1) - 1, 0) if algorithm.is_initialized else 0
    algorithm.callback = GenerationEnd(out_dir / "checkpoint.pkl" if out_dir else None, fingerprint, name, None,
                                       spec.objective.hv_reference, done, stop_after)
    with open_executor(study.path, backend, workers or ex.workers, scheduler or ex.scheduler, ex.timeout_s,
                       "--scheduler" if scheduler else "execution.scheduler") as executor:
        # the run starts: its notes and progress bar only now, so bad input found above stays one line
        if started is not None:
            started()
        bar = None
        if progress:
            from tqdm import tqdm
            bar = algorithm.callback.bar = tqdm(total=spec.optimizer.generations, unit="gen", dynamic_ncols=True)
            if done:
                bar.update(done)  # generations done before a resume
        with problem.running_on(executor):
            try:
                algorithm.run()
            except _Stopped:
                if bar is not None:
                    bar.close()
                return None
            n_search = sum(len(x) for x in problem.archive["X"])
            budget = study.polish_budget()
            if budget:
                polish_archive(problem, spec.polish, study.make_repair(), budget)
                if bar is not None:
                    bar.set_postfix_str("polished: " + status(problem, spec.objective.hv_reference))
        if bar is not None:
            bar.close()
        result = _result(study, problem, algorithm, name, n_search, budget, t0)
        page = write_outputs(study, result, problem.archive_arrays(), out_dir) if out_dir else None
        result.report_warnings = list(page["warnings"]) if page is not None else []  # (the CLI says them too)
        if spec.refine is not None:  # the second opinion (refine.py); the search model on the same executor
            result.refine = refine(study, result.pareto, out_dir, executor=executor, progress=progress)
        if page is not None:  # report.html last: it shows every file above
            write_reconstruction_report(study, result, out_dir, **page)
    return result


def _result(study, problem, algorithm, name, n_search, budget, t0) -> ReconstructionResult:
    """The search's ReconstructionResult (its wall time: search and polish)."""
    spec = study.spec
    info = {"optimizer": name, "generations": int(algorithm.n_gen or 1) - 1,
            "pop_size": int(getattr(algorithm, "pop_size", None) or spec.optimizer.pop_size),
            "search_evaluations": n_search, "polish_evaluations": sum(len(x) for x in problem.archive["X"])
            - n_search, "polish_budget": budget}
    if getattr(algorithm, "sigma_share", None) is not None:
        info["sigma_share"] = float(algorithm.sigma_share)
    repair = getattr(algorithm, "repair", None)
    if repair is not None and hasattr(repair, "repaired"):
        info["repaired"] = int(repair.repaired)
    arch = problem.archive_arrays()
    feasible = np.all(arch["G"] <= 0, axis=1) & arch["ok"]
    scored = scored_feasible(arch)
    # unscored rows (objectives FAILED_OBJECTIVE) would dominate a larger real misfit: only when nothing scored
    shown = {**arch, "ok": arch["ok"] & scored} if scored.any() else arch
    return ReconstructionResult(pareto_table(problem, shown), int(len(arch["X"])), int((~arch["ok"]).sum()),
                                float(feasible.mean()) if len(feasible) else 0.0,
                                time.perf_counter() - t0, problem, info)
