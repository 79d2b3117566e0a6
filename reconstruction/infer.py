"""The posterior of a study's free variables and uncertain parameters given its evidence (`crashlab infer`).

    crashlab infer STUDY --out DIR [--samples N] [--seed S] [--resume] [--workers N]

Model (docs/physics.md, "Evidence and likelihood"; Davis, Law, Probability and Risk 2003):
  parameters  the study's free variables (file units: m, deg, km/h, ...) then its uncertain parameters
              (`[[uncertain]]` in the study file or the base scene's file, crashlab.uncertainty);
  prior       flat within each free variable's bounds; an uncertain parameter's distribution; an
              `[[uncertain]]` entry on a free variable's own field is that variable's prior (within its bounds);
  likelihood  Gaussian in the normalised residuals of the evidence (EvidenceSet.log_likelihood, -0.5 sum r^2);
              a start whose outlines overlap, a run without contact, a failed run, or a vehicle with
              evidence still moving at the end has likelihood 0 (log -inf), as in the search
              (crashlab.reconstruction.problem: "Failed evaluations").

Sampler: emcee's affine-invariant ensemble (Foreman-Mackey et al. 2013) with the differential-evolution move
mix emcee recommends for multi-modal targets (80 % DEMove, 20 % DESnookerMove; ter Braak 2006, ter Braak &
Vrugt 2008), vectorised: every half-ensemble proposal is one batch through the model's simulate_batch. The
README gives the comparison with zeus (ensemble slice sampling) that chose it. The walkers start at the
`walkers` most probable of `init` x walkers draws from the prior (a crude global search, so the burn-in
starts near the modes the evidence allows, several of them if there are several).

Burn-in and thinning: the first `burn` iterations of every walker are discarded; the rest is kept, every
`thin`-th iteration written (default 1: all). The integrated autocorrelation time tau of each variable
(emcee.autocorr.integrated_time, Goodman & Weare 2010) gives the effective sample size
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

Questions (`[[questions]] expr = "V1.speed > 50"`): a boolean expression over the variable labels (V1.speed,
V2.heading, impact.restitution, road.friction, V1.mass, ...), numbers, + - * /, the comparisons < <= > >= ==
!=, and, or, not and parentheses; parsed by the small grammar below (no eval). summary.md gives the posterior
probability of each (the share of the written samples where it holds) with its Monte-Carlo standard error
sqrt(p (1 - p) / ESS) (ESS: the smallest over the variables the question names).
"""
from __future__ import annotations

import hashlib
import math
import os
import pickle
import re
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, Strict, ValidationError
from typing_extensions import Annotated

from crashlab import fields, uncertainty
from crashlab.errors import InputError
from crashlab.execution import Executor
from crashlab.vehicle import pydantic_error

from .evidence import log_likelihood_of
from .problem import variable_label
from .run import read_checkpoint
from .schema import SEED_MAX, WORKERS_MAX
from .study import Study, _canonical, load_study

CHECKPOINT_FORMAT = "crashlab posterior checkpoint 1"
Int = Annotated[int, Strict()]


class InferSection(BaseModel):
    """`[infer]` of a study file: the sampler's settings (module docstring)."""
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)
    sampler: Literal["emcee", "zeus"] = Field(  # zeus: the comparison (README); no --resume
        default="emcee", description="ensemble MCMC sampler; zeus cannot --resume")
    walkers: Int | None = Field(default=None, ge=8, le=10_000,
                                description="[8, 10000]; default max(32, 6 x dims), even")
    samples: Int = Field(default=20_000, ge=10, le=10_000_000,
                         description="kept samples (walkers x iterations); [10, 1e7]")
    burn: Int = Field(default=500, ge=0, le=1_000_000, description="iterations discarded; [0, 1e6]")
    thin: Int = Field(default=1, ge=1, le=10_000, description="keep every thin-th iteration; [1, 10000]")
    init: Int = Field(default=20, ge=1, le=10_000, description="prior draws per walker to start from; [1, 10000]")
    seed: Int = Field(default=1, ge=0, le=SEED_MAX, description=f"seed of the sampler; [0, {SEED_MAX}]")
    checkpoint_every: Int = Field(default=100, ge=1, le=1_000_000, description="iterations; [1, 1e6]")
    draws_plotted: Int = Field(default=20, ge=0, le=1000, description="posterior draws in the top view; [0, 1000]")


class QuestionFile(BaseModel):
    """A `[[questions]]` table: an expression of the posterior's variables answered with its probability or
    distribution (crashlab infer)."""
    model_config = ConfigDict(extra="forbid")
    expr: str = Field(min_length=1, max_length=2000, description="expression of the variables' labels (as in "
                      "posterior.csv), e.g. `car.speed > 50`: numbers, + - * /, comparisons, and, or, not, ( )")
    name: str | None = Field(default=None, description="label of the answer in summary.md; default the expr")


# ---------------------------------------------------------------- questions: a small safe grammar
_TOKEN = re.compile(r"\s*(?:(?P<num>\d+(?:\.\d*)?(?:[eE][+-]?\d+)?|\.\d+(?:[eE][+-]?\d+)?)"
                    r"|(?P<name>[A-Za-z_][A-Za-z0-9_]*(?:\.[A-Za-z0-9_]+)*)"
                    r"|(?P<op><=|>=|==|!=|<|>|\+|-|\*|/|\(|\)))")
_COMPARE = {"<": np.less, "<=": np.less_equal, ">": np.greater, ">=": np.greater_equal, "==": np.equal,
            "!=": np.not_equal}
_ARITH = {"+": np.add, "-": np.subtract, "*": np.multiply, "/": np.divide}


class _Parser:
    """Recursive descent over: or := and ('or' and)*; and := not ('and' not)*; not := 'not' not | cmp;
    cmp := sum (op sum)* (chained as in Python: a < b < c is a < b and b < c); sum := term (+|- term)*;
    term := unary (*|/ unary)*; unary := - unary | number | name | ( or ). Each node is (kind, function of
    the columns dict), kind "bool" or "num"; names must be variable labels."""

    def __init__(self, text: str, names):
        self.text, self.names, self.toks, pos = text, list(names), [], 0
        while pos < len(text):
            if text[pos:].strip() == "":
                break
            m = _TOKEN.match(text, pos)
            if not m or m.end() == pos:
                raise ValueError(f"cannot read {text[pos:].strip()[:20]!r}")
            kind = m.lastgroup
            val = m.group(kind)
            if kind == "name" and val in ("and", "or", "not"):
                kind = "op"
            self.toks.append((kind, val))
            pos = m.end()
        self.i = 0
        self.used: set[str] = set()

    def peek(self):
        return self.toks[self.i] if self.i < len(self.toks) else (None, None)

    def take(self, *ops):
        kind, val = self.peek()
        if kind == "op" and val in ops:
            self.i += 1
            return val
        return None

    def parse(self):
        node = self.p_or()
        if self.i != len(self.toks):
            raise ValueError(f"unexpected {self.peek()[1]!r}")
        if node[0] != "bool":
            raise ValueError("not a comparison (e.g. V1.speed > 50)")
        return node[1]

    def _bool(self, node, word):
        if node[0] != "bool":
            raise ValueError(f"'{word}' needs comparisons on both sides")
        return node[1]

    def p_or(self):
        node = self.p_and()
        while self.take("or"):
            a, b = self._bool(node, "or"), self._bool(self.p_and(), "or")
            node = ("bool", lambda d, a=a, b=b: a(d) | b(d))
        return node

    def p_and(self):
        node = self.p_not()
        while self.take("and"):
            a, b = self._bool(node, "and"), self._bool(self.p_not(), "and")
            node = ("bool", lambda d, a=a, b=b: a(d) & b(d))
        return node

    def p_not(self):
        if self.take("not"):
            a = self._bool(self.p_not(), "not")
            return "bool", lambda d, a=a: ~a(d)
        return self.p_cmp()

    def p_cmp(self):
        left = self.p_sum()
        parts = []
        while (op := self.take(*_COMPARE)) is not None:
            right = self.p_sum()
            if left[0] != "num" or right[0] != "num":
                raise ValueError(f"'{op}' compares numbers")
            parts.append((op, left[1], right[1]))
            left = right
        if not parts:
            return left
        def fn(d, parts=parts):
            out = None
            for op, a, b in parts:
                r = _COMPARE[op](a(d), b(d))
                out = r if out is None else out & r
            return out
        return "bool", fn

    def _arith(self, sub, ops):
        node = sub()
        while (op := self.take(*ops)) is not None:
            right = sub()
            if node[0] != "num" or right[0] != "num":
                raise ValueError(f"'{op}' needs numbers")
            node = ("num", lambda d, f=_ARITH[op], a=node[1], b=right[1]: f(a(d), b(d)))
        return node

    def p_sum(self):
        return self._arith(self.p_term, ("+", "-"))

    def p_term(self):
        return self._arith(self.p_unary, ("*", "/"))

    def p_unary(self):
        if self.take("-"):
            a = self.p_unary()
            if a[0] != "num":
                raise ValueError("'-' needs a number")
            return "num", lambda d, f=a[1]: -f(d)
        kind, val = self.peek()
        if kind is None:
            raise ValueError("the expression ends too early")
        self.i += 1
        if kind == "num":
            v = float(val)
            return "num", lambda d, v=v: v
        if kind == "name":
            if val not in self.names:
                raise ValueError(f"unknown name {val!r} (variables: {', '.join(self.names)})")
            self.used.add(val)
            return "num", lambda d, v=val: np.asarray(d[v], float)
        if val == "(":
            node = self.p_or()
            if not self.take(")"):
                raise ValueError("missing ')'")
            return node
        raise ValueError(f"unexpected {val!r}")


@dataclass
class Question:
    name: str
    expr: str
    fn: object
    names: tuple[str, ...]

    def probability(self, columns: dict) -> float:
        hold = np.asarray(self.fn(columns), bool)
        return float(np.mean(hold)) if hold.size else math.nan


def parse_question(expr: str, names, source="<study>", key="questions.0.expr") -> Question:
    """A Question over the variable labels `names`; InputError naming source and key if it does not parse."""
    try:
        p = _Parser(expr, names)
        fn = p.parse()
    except ValueError as err:
        raise InputError(source, key, f"{expr!r} does not parse: {err}") from None
    return Question(expr, expr, fn, tuple(sorted(p.used)))


# ---------------------------------------------------------------- the study file's sections for the posterior
def _extras(spec) -> dict:
    """The sections only the posterior reads (StudyFile keeps them unchecked; checked here)."""
    return {k: getattr(spec, k) for k in ("questions", "uncertain", "infer") if k in spec.model_fields_set}


@dataclass
class Variable:
    label: str  # the name in posterior.csv, summary.md and questions
    path: str  # crashlab.fields path
    lower: float
    upper: float
    unit: str
    prior: object = None  # crashlab.uncertainty.Uncertain, or None: flat within [lower, upper]
    free: bool = True

    def describe_prior(self) -> str:
        if self.prior is None:
            return f"flat on [{self.lower:g}, {self.upper:g}]"
        return self.prior.describe().split(": ", 1)[1] + ("" if not self.free else
                                                          f", within [{self.lower:g}, {self.upper:g}]")


class Posterior:
    """A study prepared for sampling: its variables, priors, log-likelihood and questions."""

    def __init__(self, path, study: Study, extras: dict):
        self.path, self.study, self.extras = Path(path), study, extras
        if study.evidence_set is None:
            raise InputError(path, "evidence", "the posterior needs the evidence's uncertainty: give the sigmas "
                             "(sigma_xy, ...) and the misfit objective ([objective] mode = \"misfit\")")
        try:
            self.settings = InferSection.model_validate(extras.get("infer", {}))
        except ValidationError as err:
            raise pydantic_error(path, err, "infer.") from None
        scene = study.scene
        declared = uncertainty.parse(extras["uncertain"], scene, path) if "uncertain" in extras else ()
        in_scene = tuple(getattr(scene, "uncertain", ()) or ())
        by_path = {u.field: u for u in in_scene}
        by_path.update({u.field: u for u in declared})  # the study's entry wins over the scene's
        self.variables: list[Variable] = []
        for f in study.spec.free:
            p = fields.parse(fields.study_path(f.vehicle, f.field)).path
            self.variables.append(Variable(f.label, p, float(f.lower), float(f.upper), fields.parse(p).unit,
                                           by_path.pop(p, None)))
        for p, u in by_path.items():
            self.variables.append(Variable(variable_label(p), p, u.lower, u.upper, u.unit, u, free=False))
        self.labels = [v.label for v in self.variables]
        self.n_free = len(study.spec.free)
        self.setter = fields.setter(scene, [v.path for v in self.variables])
        self.problem = study.make_problem()
        self.truth = self._truth()
        qs = extras.get("questions", [])
        if not isinstance(qs, list):
            raise InputError(path, "questions", "a list of tables ([[questions]] expr = \"V1.speed > 50\")")
        self.questions = []
        for k, q in enumerate(qs):
            try:
                qf = QuestionFile.model_validate(q)
            except ValidationError as err:
                raise pydantic_error(path, err, f"questions.{k}.") from None
            question = parse_question(qf.expr, self.labels, path, f"questions.{k}.expr")
            question.name = qf.name or qf.expr
            self.questions.append(question)
        self.evaluations = 0

    def _truth(self):
        """The base scene's values (file units): the truth of a twin, else None."""
        if not self.study.spec.evidence.twin:
            return None
        return np.array([fields.get(self.study.scene, v.path) for v in self.variables])

    @property
    def ndim(self) -> int:
        return len(self.variables)

    def fingerprint(self) -> dict:
        parts = dict(self.study.fingerprint())
        s = self.settings.model_dump(exclude={"samples", "checkpoint_every", "draws_plotted"})
        parts["sampler settings"] = _digest([s])
        parts["variables and priors"] = _digest([(v.label, v.path, v.lower, v.upper, repr(v.prior))
                                                 for v in self.variables])
        return parts

    # ---------------------------------------------------------------- densities
    def log_prior(self, X) -> np.ndarray:
        X = np.atleast_2d(np.asarray(X, float))
        lp = np.zeros(len(X))
        for j, v in enumerate(self.variables):
            x = X[:, j]
            inside = (x >= v.lower) & (x <= v.upper)
            if v.prior is None:
                lp += np.where(inside, -math.log(v.upper - v.lower), -np.inf)
            else:
                lp += np.where(inside, v.prior.logpdf(np.clip(x, v.lower, v.upper)), -np.inf)
        return lp

    def sample_prior(self, n: int, rng) -> np.ndarray:
        X = np.empty((n, self.ndim))
        for j, v in enumerate(self.variables):
            if v.prior is None:
                X[:, j] = rng.uniform(v.lower, v.upper, n)
            else:  # a free variable's prior within its bounds: its quantiles between the bounds' ones
                lo, hi = v.prior.dist.cdf(v.lower), v.prior.dist.cdf(v.upper)
                X[:, j] = v.prior.ppf(rng.uniform(lo, hi, n))
        return X

    def log_likelihood(self, X) -> np.ndarray:
        """(n,) Gaussian log-likelihood of rows X (file units); -inf where a candidate cannot be scored or
        is no valid collision (module docstring)."""
        X = np.atleast_2d(np.asarray(X, float))
        out = np.full(len(X), -np.inf)
        scenes, idx = [], []
        for k, row in enumerate(X):
            try:
                scenes.append(self.setter(row))
                idx.append(k)
            except ValueError:  # outside a field's range or a mass the vehicle's checks refuse
                pass
        if not scenes:
            return out
        idx = np.asarray(idx)
        self.evaluations += len(scenes)
        ev, R = self.problem._simulate(scenes)  # the search's own evaluation path (executor, evidence scored there)
        L = log_likelihood_of(R)
        bad = ~ev.ok | (ev.n_impacts <= 0)
        for name in self.study.evidence_set.objective_names:
            bad |= ~ev.at_rest[:, self.problem.names.index(name)]
        bad |= self.problem.start_overlap(X[idx, :self.n_free]) > 0
        L[bad] = -np.inf
        out[idx] = L
        return out

    def log_posterior(self, X) -> np.ndarray:
        X = np.atleast_2d(np.asarray(X, float))
        lp = self.log_prior(X)
        ok = np.isfinite(lp)
        if ok.any():
            lp[ok] += self.log_likelihood(X[ok])
        return lp


def _digest(obj) -> str:
    return hashlib.sha256(_canonical(obj).encode()).hexdigest()[:16]


def load_posterior(path) -> Posterior:
    """The study at `path` prepared for sampling; InputError (file, key, problem) for bad input."""
    path = Path(path)
    study = load_study(path)
    return Posterior(path, study, _extras(study.spec))


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

    def interval(self, q=(0.05, 0.5, 0.95)) -> np.ndarray:
        return np.quantile(self.samples, q, axis=0)


def _atomic_pickle(path: Path, obj):
    tmp = path.with_suffix(path.suffix + ".tmp")
    with open(tmp, "wb") as fh:
        pickle.dump(obj, fh, protocol=pickle.HIGHEST_PROTOCOL)
    os.replace(tmp, path)


def _autocorr(chain: np.ndarray) -> np.ndarray:
    """(d,) integrated autocorrelation time of a chain (iterations, walkers, d) [iterations]."""
    import emcee
    if len(chain) < 2:
        return np.full(chain.shape[2], np.nan)
    return np.asarray(emcee.autocorr.integrated_time(chain, c=5, tol=0, quiet=True), float)


def _progress(post, it, total, acc, lp, t0, stream):
    if stream is None:
        return
    best = np.max(lp) if np.isfinite(lp).any() else -np.inf
    stream.write(f"\rinfer: iteration {it}/{total}  evaluations {post.evaluations}  acceptance {acc:.2f}  "
                 f"best log-posterior {best:.2f}  {time.time() - t0:.0f} s   ")
    stream.flush()


def run_posterior(post: Posterior, out_dir=None, samples: int | None = None, seed: int | None = None,
                  resume: bool = False, workers: int | None = None, progress: bool = True,
                  stop_after: int | None = None) -> PosteriorResult | None:
    """Sample the posterior (module docstring); with out_dir, checkpoints and the outputs (infer_report).
    stop_after: stop after that many iterations as a kill would (checkpoint written, no outputs; returns
    None): tests."""
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
    nw += nw % 2
    if nw < 2 * d:
        raise InputError(post.path, "infer.walkers", f"{nw} walkers for {d} variables: at least {2 * d}")
    keep_iters = math.ceil(s.samples / nw)
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
    stream = sys.stderr if progress else None
    t0 = time.time()
    with Executor(backend, nworkers, ex.scheduler, ex.timeout_s if backend != "serial" else 0) as executor:
        post.problem.executor = executor
        try:
            if s.sampler == "zeus":
                res = _run_zeus(post, nw, total, s, stream, t0)
            else:
                res = _run_emcee(post, nw, total, s, ckpt, fingerprint, resume, stream, t0, stop_after)
        finally:
            post.problem.executor = None
            if stream is not None:
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
        from .html_report import write_posterior_report
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
        raise InputError(post.path, "free", f"only {int(np.isfinite(lp).sum())} of {n} draws from the prior are "
                         "collisions the evidence can score: narrow the bounds to where the vehicles collide "
                         "(or raise infer.init)")
    return X[order], lp[order]


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


# ---------------------------------------------------------------- command line
def cmd_infer(args) -> int:
    """`crashlab infer` (its options: crashlab.cli): bad input raises InputError (the CLI prints its one line
    and exits 2)."""
    post = load_posterior(args.study)
    if args.samples is not None and not 10 <= args.samples <= 10_000_000:
        raise InputError(args.study, "--samples", f"{args.samples} is outside [10, 10000000]")
    if args.seed is not None and not 0 <= args.seed <= SEED_MAX:
        raise InputError(args.study, "--seed", f"{args.seed} is outside [0, {SEED_MAX}]")
    res = run_posterior(post, args.out, args.samples, args.seed, args.resume, args.workers,
                        progress=not getattr(args, "no_progress", False))
    lo, med, hi = res.interval()
    for j, lab in enumerate(res.labels):
        print(f"{lab:24s} {med[j]:10.3f}  90 % [{lo[j]:.3f}, {hi[j]:.3f}]  ESS {res.ess[j]:.0f}")
    print(f"{len(res.samples)} samples, {res.evaluations} model evaluations, {res.wall_time_s:.1f} s, "
          f"outputs in {args.out}")
    if res.refine is not None:
        print(res.refine.summary_line(post.study.variables, wrote=True))
    return 0


__all__ = ["CHECKPOINT_FORMAT", "InferSection", "Posterior", "PosteriorResult", "Question",
           "cmd_infer", "load_posterior", "parse_question", "run_posterior"]
