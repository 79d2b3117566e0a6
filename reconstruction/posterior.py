"""The posterior of a study's free variables and uncertain parameters given its evidence: the study file's
[infer] and [[questions]] sections, the variables and the log-posterior (sampled by crashlab.reconstruction.infer).

Model (docs/physics.md, "Evidence and likelihood"; Davis, Law, Probability and Risk 2003):
  parameters  the study's free variables (file units: m, deg, km/h, ...) then its uncertain parameters
              (`[[uncertain]]` in the study file or the base scene's file, crashlab.uncertainty);
  prior       flat within each free variable's bounds; an uncertain parameter's distribution; an
              `[[uncertain]]` entry on a free variable's own field is that variable's prior (within its bounds);
  likelihood  Gaussian in the normalised residuals of the evidence (EvidenceSet.log_likelihood, -0.5 sum r^2);
              a start whose outlines overlap, a run without contact, a failed run, or a vehicle with
              evidence still moving at the end has likelihood 0 (log -inf), as in the search
              (crashlab.reconstruction.problem: "Failed evaluations").

Questions (`[[questions]] expr = "V1.speed > 50"`): a boolean expression over the variable labels (V1.speed,
V2.heading, impact.restitution, road.friction, V1.mass, ...), numbers, + - * /, the comparisons < <= > >= ==
!=, and, or, not and parentheses; parsed with Python's ast and a whitelist (crashlab.reconstruction.questions,
never evaluated). summary.md gives the posterior
probability of each (the share of the written samples where it holds) with its Monte-Carlo standard error
sqrt(p (1 - p) / ESS) (ESS: the smallest over the variables the question names).
"""
from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pydantic import Strict, ValidationError
from typing_extensions import Annotated

from crashlab import fields, uncertainty
from crashlab.errors import InputError
from crashlab.input_files import pydantic_error

from .evidence import log_likelihood_of
from .infer_settings import InferSection
from .problem import variable_label
from .questions import QuestionFile  # noqa: F401 - the reference's schema (crashlab.cli.schema_docs)
from .study import Study, _canonical, load_study

Int = Annotated[int, Strict()]


# ---------------------------------------------------------------- the study file's sections for the posterior
def _extras(spec) -> dict:
    """The sections only the posterior reads (StudyFile keeps them unchecked; checked here, the questions and the
    counterfactuals by the study loader, crashlab.reconstruction.study)."""
    return {k: getattr(spec, k) for k in ("questions", "uncertain", "infer", "counterfactuals")
            if k in spec.model_fields_set}


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
            raise pydantic_error(path, err, "infer.", InferSection) from None
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
        self.fields = [fields.resolve(scene, v.path) for v in self.variables]
        self.problem = study.make_problem()
        self.truth = self._truth()
        # checked when the study was loaded, for every command (crashlab.reconstruction.study): its labels are these
        self.questions, self.counterfactuals = list(study.questions), list(study.counterfactuals)
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

    @property
    def setter(self):
        """row -> Scene with the posterior's variables set (crashlab.fields.setter, checked): the scene of a draw
        for the reports."""
        return fields.setter(self.study.scene, self.fields)

    def log_likelihood(self, X) -> np.ndarray:
        """(n,) Gaussian log-likelihood of rows X (file units); -inf where a candidate cannot be scored or
        is no valid collision (module docstring)."""
        X = np.atleast_2d(np.asarray(X, float))
        out = np.full(len(X), -np.inf)
        # outside a field's range or a mass the vehicle's checks refuse: no valid scene, not simulated
        idx = np.flatnonzero(fields.row_problems(self.study.scene, self.fields, X) == "")
        if not len(idx):
            return out
        self.evaluations += len(idx)
        # the search's own evaluation path (executor, evidence scored there)
        ev, R = self.problem.simulate(X[idx], self.fields)
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


