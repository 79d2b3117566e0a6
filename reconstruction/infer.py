"""The posterior of a study's free variables and uncertain parameters given its evidence (`crashlab infer`).

    crashlab infer STUDY --out DIR [--samples N] [--seed S] [--resume] [--workers N]

Sampler: emcee's affine-invariant ensemble (Foreman-Mackey et al. 2013) with the differential-evolution move
mix emcee recommends for multi-modal targets (80 % DEMove, 20 % DESnookerMove; ter Braak 2006, ter Braak &
Vrugt 2008), vectorised: every half-ensemble proposal is one batch through the model's simulate_batch. The
README gives the comparison with zeus (ensemble slice sampling) that chose it. The walkers start at the
`walkers` most probable of `init` x walkers draws from the prior (a crude global search, so the burn-in
starts near the modes the evidence allows, several of them if there are several).

Burn-in and thinning: the first `burn` iterations of every walker are discarded; the rest is kept, every
`thin`-th iteration written (default 1: all), `samples` of them (the chain runs thin times as long). The
integrated autocorrelation time tau of each variable (emcee.autocorr.integrated_time, Goodman & Weare 2010) gives
the effective sample size
ESS = walkers x kept iterations / tau; summary.md reports both and warns when the chain is shorter than
50 tau (emcee's own reliability threshold for tau) or the burn-in shorter than 5 tau.

Execution: evidence of rest poses and EDR speeds is scored from the study's executor ([execution]:
serial, processes, Dask, as `crashlab reconstruct`; --workers N: N processes). Evidence that needs the whole
Outcome (the point of impact, a delta-V, a mark) is scored in this process as in the search
(crashlab.reconstruction.problem); with N > 1 workers each batch is then split over N spawned processes
(without the executor's per-evaluation timeout). The results do not depend on the backend.

Checkpoints (DIR/infer_checkpoint.pkl, every `checkpoint_every` iterations, written atomically): the chain
so far, the ensemble state and the random generator's state, and the fingerprint of what the posterior
depends on (Study.fingerprint plus the uncertain parameters and the sampler settings). `--resume` continues
the same chain: the result is byte-identical to an uninterrupted run's. A checkpoint of a changed study is
refused with one line. `--samples` may be raised on resume (the chain is lengthened).

The posterior itself (prior, likelihood, questions): crashlab.reconstruction.posterior.
"""
from __future__ import annotations

import math
import os
import pickle
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from crashlab.errors import InputError

from .posterior import Posterior
from .run import read_checkpoint
from .schema import WORKERS_MAX
from .study_executor import open_executor

CHECKPOINT_FORMAT = "crashlab posterior checkpoint 1"


# ---------------------------------------------------------------- the run
@dataclass
class PosteriorResult:
    labels: list
    samples: np.ndarray  # (n, d) kept, thinned, file units
    log_likelihood: np.ndarray  # (n,)
    tau: np.ndarray  # (d,) integrated autocorrelation time [iterations]
    ess: np.ndarray  # (d,)
    walkers: int
    iterations: int  # total, burn-in included
    burn: int
    thin: int
    evaluations: int  # model evaluations (this process; a resumed run counts those before it too)
    acceptance: float
    wall_time_s: float
    sampler: str
    truth: np.ndarray | None = None
    chain: np.ndarray | None = None  # (iterations, walkers, d), every iteration
    refine: object = None  # refine.RefineResult of the study's [refine] on the best draws
    counterfactuals: list | None = None  # counterfactual.answer's rows of the study's [[counterfactuals]]
    answers: list | None = None  # counterfactual.Answer of each (the populations and per-draw numbers)

    def interval(self, q=(0.05, 0.5, 0.95)) -> np.ndarray:
        return np.quantile(self.samples, q, axis=0)


def _atomic_pickle(path: Path, obj):
    tmp = path.with_suffix(path.suffix + ".tmp")
    with open(tmp, "wb") as fh:
        pickle.dump(obj, fh, protocol=pickle.HIGHEST_PROTOCOL)
    os.replace(tmp, path)


def _autocorr(chain: np.ndarray) -> np.ndarray:
    """(d,) integrated autocorrelation time of a chain (iterations, walkers, d) [iterations]; NaN where it cannot
    be estimated: fewer than 2 iterations, or a walker that never moved in them (its autocorrelation is 0 / 0;
    a short chain at a low acceptance). The reports show a dash and say why (infer_report.chain_warnings)."""
    import emcee
    if len(chain) < 2:
        return np.full(chain.shape[2], np.nan)
    with np.errstate(divide="ignore", invalid="ignore"):  # that 0 / 0 gives NaN, not numpy's warning
        return np.asarray(emcee.autocorr.integrated_time(chain, c=5, tol=0, quiet=True), float)


class _Stream:
    """stderr for the progress line, knowing whether it was written to."""

    def __init__(self, stream):
        self.stream, self.used = stream, False

    def write(self, text: str) -> None:
        self.used = True
        self.stream.write(text)

    def flush(self) -> None:
        self.stream.flush()


def _progress(post, it, total, acc, lp, t0, stream):
    if stream is None:
        return
    best = np.max(lp) if np.isfinite(lp).any() else -np.inf
    stream.write(f"\rinfer: iteration {it}/{total}  evaluations {post.evaluations}  acceptance {acc:.2f}  "
                 f"best log-posterior {best:.2f}  {time.time() - t0:.0f} s   ")
    stream.flush()


def run_posterior(post: Posterior, out_dir=None, samples: int | None = None, seed: int | None = None,
                  resume: bool = False, workers: int | None = None, progress: bool = True,
                  stop_after: int | None = None, started=None) -> PosteriorResult | None:
    """Sample the posterior (module docstring); with out_dir, checkpoints and the outputs (infer_report).
    stop_after: stop after that many iterations as a kill would (checkpoint written, no outputs; returns
    None): tests. started: called once the settings are checked and the executor is up, before sampling."""
    s = post.settings
    if samples is not None:
        s = s.model_copy(update={"samples": int(samples)})
    if seed is not None:
        s = s.model_copy(update={"seed": int(seed)})
    post.settings = s
    if workers is not None and not 1 <= workers <= WORKERS_MAX:
        raise InputError(post.path, "--workers", f"{workers} is outside [1, {WORKERS_MAX}]")
    d = post.ndim
    nw = s.walkers or max(32, 6 * d)
    if nw < 2 * d:
        raise InputError(post.path, "infer.walkers", f"{nw} walkers for {d} variables: at least {2 * d}")
    keep_iters = math.ceil(s.samples / nw) * s.thin  # `samples` are the ones kept after thinning
    total = s.burn + keep_iters
    out = Path(out_dir) if out_dir is not None else None
    ckpt = None
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        ckpt = out / "infer_checkpoint.pkl"
    if resume and s.sampler != "emcee":
        raise InputError(post.path, "infer.sampler", "--resume needs the emcee sampler")
    fingerprint = post.fingerprint()
    ex = post.study.spec.execution
    backend, nworkers = ex.backend, ex.workers
    if workers is not None:
        backend, nworkers = ("processes" if workers > 1 else "serial"), workers
    stream = _Stream(sys.stderr) if progress else None
    t0 = time.time()
    # --workers N: N local processes; the study's Dask scheduler only without it (to Executor any scheduler is Dask)
    with open_executor(post.path, backend, nworkers, ex.scheduler if backend == "dask" else None,
                       ex.timeout_s if backend != "serial" else 0, "execution.scheduler") as executor, \
            post.problem.running_on(executor):
        if started is not None:
            started()
        try:
            if s.sampler == "zeus":
                res = _run_zeus(post, nw, total, s, stream, t0)
            else:
                res = _run_emcee(post, nw, total, s, ckpt, fingerprint, resume, stream, t0, stop_after)
        finally:
            if stream is not None and stream.used:  # ends the progress line; none before an error: one line
                stream.write("\n")
    if res is None:
        return None
    chain, lp, acc, evaluations = res
    tau = _autocorr(chain[s.burn:])
    kept = chain[s.burn::s.thin]
    flat = kept.reshape(-1, d)
    loglik = (lp[s.burn::s.thin].reshape(-1) - post.log_prior(flat))
    n_kept_iters = len(chain) - s.burn
    result = PosteriorResult(post.labels, flat, loglik, tau, nw * n_kept_iters / np.maximum(tau, 1.0), nw,
                             len(chain), s.burn, s.thin, evaluations, acc, time.time() - t0, s.sampler,
                             post.truth, chain)
    if post.counterfactuals:  # what if ... on the kept draws (counterfactual.py), before the outputs show it
        from . import counterfactual
        result.answers = counterfactual.run(post, result.samples)
        result.counterfactuals = [a.row for a in result.answers]
    page = None
    if out is not None:
        from .infer_report import write_outputs
        page = write_outputs(post, result, out)
    if post.study.spec.refine is not None:  # the second opinion on the most likely draws (refine.py)
        import pandas as pd

        from .refine import refine
        draws = pd.DataFrame(result.samples, columns=result.labels).assign(log_likelihood=result.log_likelihood)
        draws = draws.sort_values("log_likelihood", ascending=False, kind="stable")
        result.refine = refine(post.study, draws, out, source="posterior draws", progress=progress)
    if page is not None:  # report.html last: it shows every file above
        from .html_posterior import write_posterior_report
        try:
            write_posterior_report(post, result, out, **page)
        except OSError as err:
            raise InputError(out, "--out", err.strerror or str(err)) from None
    return result


def _initial(post: Posterior, nw: int, rng) -> tuple[np.ndarray, np.ndarray]:
    """The nw most probable of init x nw prior draws (module docstring)."""
    n = post.settings.init * nw
    X = post.sample_prior(n, rng)
    lp = post.log_posterior(X)
    order = np.argsort(-lp)[:nw]
    if not np.isfinite(lp[order]).all():
        for key, why in _unscored_damage(post, X[np.isfinite(post.log_prior(X))][:64]):
            raise InputError(post.path, key, why)
        raise InputError(post.path, "free", f"only {int(np.isfinite(lp).sum())} of {n} draws from the prior are "
                         "collisions the evidence can score: narrow the bounds to where the vehicles collide "
                         "(or raise infer.init)")
    return X[order], lp[order]


def _unscored_damage(post: Posterior, X) -> list[tuple[str, str]]:
    """(key, reason) of each [evidence.damage.<vehicle>] that no collision among the draws X can score: none of
    them strikes the vehicle on the damaged side (EvidenceSet.unstruck_damage, docs/physics.md §28)."""
    from crashlab import fields
    X = X[fields.row_problems(post.study.scene, post.fields, X) == ""]
    if not len(X):
        return []
    pop, _ = post.problem.simulate(X, post.fields)
    n = int((pop.ok & (pop.n_impacts > 0)).sum())
    if not n:
        return []
    return [(f"evidence.damage.{it.vehicles[0]}.side",
             f"{it.side}: none of {n} collisions drawn from the prior strikes {it.vehicles[0]} there (they strike "
             f"its {', '.join(struck) or 'nothing'}); damage on a side no run strikes cannot be scored "
             "(docs/physics.md §28): check the side and pdof")
            for it, struck in post.study.evidence_set.unstruck_damage(pop)]


def _run_emcee(post, nw, total, s, ckpt, fingerprint, resume, stream, t0, stop_after):
    import emcee
    d = post.ndim
    moves = [(emcee.moves.DEMove(), 0.8), (emcee.moves.DESnookerMove(), 0.2)]
    sampler = emcee.EnsembleSampler(nw, d, post.log_posterior, moves=moves, vectorize=True)
    if resume:
        data = read_checkpoint(ckpt, fingerprint, CHECKPOINT_FORMAT, "posterior checkpoint")
        chain, lps, state = data["chain"], data["log_prob"], data["state"]
        n_acc, post.evaluations = data["accepted"], data["evaluations"]
    else:
        rng = np.random.default_rng(s.seed)
        x0, lp0 = _initial(post, nw, rng)
        sampler._random.seed(s.seed)  # the sampler's own generator (emcee: numpy RandomState)
        state = emcee.State(x0, log_prob=lp0, random_state=sampler._random.get_state())
        chain, lps, n_acc = np.empty((0, nw, d)), np.empty((0, nw)), np.zeros(nw)
    done = len(chain)
    while done < total:
        k = min(s.checkpoint_every, total - done)
        if stop_after is not None:
            k = min(k, stop_after - done)
        sampler.reset()
        state = sampler.run_mcmc(state, k, progress=False)
        chain = np.concatenate([chain, sampler.get_chain()])
        lps = np.concatenate([lps, sampler.get_log_prob()])
        n_acc = n_acc + sampler.backend.accepted
        done = len(chain)
        if ckpt is not None:
            _atomic_pickle(ckpt, {"format": CHECKPOINT_FORMAT, "fingerprint": fingerprint, "chain": chain,
                                  "log_prob": lps, "state": state, "accepted": n_acc,
                                  "evaluations": post.evaluations})
        _progress(post, done, total, float(np.mean(n_acc) / max(done, 1)), state.log_prob, t0, stream)
        if stop_after is not None and done >= stop_after and done < total:
            return None
    return chain, lps, float(np.mean(n_acc) / max(done, 1)), post.evaluations


def _run_zeus(post, nw, total, s, stream, t0):
    """The comparison sampler (README): zeus's ensemble slice sampling, vectorised; no checkpoints."""
    import logging

    import zeus
    logging.getLogger().setLevel(logging.WARNING)
    rng = np.random.default_rng(s.seed)
    x0, _ = _initial(post, nw, rng)
    np.random.seed(s.seed)  # zeus draws from numpy's global generator
    sampler = zeus.EnsembleSampler(nw, post.ndim, post.log_posterior, vectorize=True, verbose=False)
    sampler.run_mcmc(x0, total, progress=False)
    chain = sampler.get_chain()
    lps = sampler.get_log_prob()
    _progress(post, total, total, 1.0, lps[-1], t0, stream)
    return chain, lps, 1.0, post.evaluations


__all__ = ["CHECKPOINT_FORMAT", "PosteriorResult", "run_posterior"]
