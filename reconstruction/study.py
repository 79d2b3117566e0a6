"""A reconstruction study: its file loaded and checked (crashlab.reconstruction.schema), the base scene,
the evidence (measured, or a twin's: the model's own run of the base scene), and what a run is built from.

A study file names a base scene, a model, an optimizer, the free variables with bounds and the evidence:
measured rest poses, and optionally (each with its sigma) the point of impact, marks and event-data-recorder
values (crashlab.reconstruction.evidence); `Study.run` searches (crashlab.reconstruction.run), polishes and
reports.

Twins (`[evidence] twin = true`): the evidence is the model's own run (`model.simulate`) of the base scene,
whose start is the truth. A file that gives no other evidence gets every vehicle's rest pose (the thesis's
twins). Otherwise the run fills every value of the items the file names, which give only their sigmas: a
rest pose's x, y (and its heading where sigma_heading is given, or with the thesis objective), the point of
impact, a mark's points (n_points CG positions of the run, evenly spaced in time, default 4) and the EDR
values whose sigma is given; a value given as well is refused. `noise_seed` adds Gaussian noise with the
given sigmas to every filled value (calibration experiments: evidence = a known start's run + noise).
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
from pathlib import Path

import numpy as np
from pydantic import ValidationError

from crashlab import uncertainty
from crashlab.errors import InputError
from crashlab.input_files import check_kind, pydantic_error, read_toml
from crashlab.options import OptionError
from crashlab.population import outcome_reason
from crashlab.registry import (
    OPTIMIZERS,
    UnknownPluginError,
    available_models,
    available_optimizers,
    get_model,
    load,
)
from crashlab.scene import Scene
from crashlab.scene_file import load_scene
from crashlab.units import ms_to_kmh
from crashlab.version import package_version

from . import counterfactual
from .evidence import build_evidence
from .infer_settings import InferSection
from .problem import ReconstructionProblem, UncertainVariable
from .questions import parse_questions
from .repair import CollisionRepair
from .run import run_study
from .schema import StudyFile
from .study_executor import refuse_empty_scheduler
from .study_units import in_file_units


def _canonical(obj) -> str:
    def default(o):
        if isinstance(o, np.ndarray):
            return o.tolist()
        if isinstance(o, (np.floating, np.integer, np.bool_)):
            return o.item()
        return repr(o)
    return json.dumps(obj, sort_keys=True, default=default)


def _digest(obj) -> str:
    return hashlib.sha256(_canonical(obj).encode()).hexdigest()[:16]


class Study:
    """A loaded study: its file (spec), base scene, measured rest poses (evidence: vehicle -> x, y [m],
    heading [deg] or None) and, with the misfit objective, every evidence item with its sigmas
    (evidence_set, crashlab.reconstruction.evidence; None with the thesis objective)."""

    def __init__(self, path: Path, spec: StudyFile, scene: Scene, evidence: dict, evidence_set=None,
                 uncertain: tuple = ()):
        self.path, self.spec, self.scene, self.evidence = path, spec, scene, evidence
        self.evidence_set = evidence_set
        # the uncertain parameters the search takes as extra free variables (problem.UncertainVariable)
        self.uncertain = tuple(uncertain)
        self.notes: list[str] = []  # said once when the study is run (free_and_uncertain)
        # [[questions]] and [[counterfactuals]], checked for every command, answered by crashlab infer and avoid
        self.questions: list = []  # crashlab.reconstruction.questions.Question
        self.counterfactuals: list = []  # crashlab.reconstruction.counterfactual.Counterfactual
        # the units of every table, CSV file, figure and report its runs write: "si" (file units) or "us" (ft, mph,
        # lb; crashlab.units, shown units); the command line's --units sets it, the computation never reads it
        self.shown_units = "si"

    @property
    def variables(self) -> list:
        """The search's variables, the columns of pareto.csv: the free variables, then the uncertain
        parameters (each with label, path, lower, upper in file units)."""
        return list(self.spec.free) + list(self.uncertain)

    @property
    def mode(self) -> str:
        """The objective: "thesis" or "misfit" ([objective] mode, schema.ObjectiveSection)."""
        return "thesis" if self.evidence_set is None else "misfit"

    @property
    def objective_names(self) -> list[str]:
        """The vehicles with an objective f_<vehicle>, in objective order."""
        return list(self.evidence) if self.evidence_set is None else self.evidence_set.objective_names

    def fingerprint(self) -> dict:
        """What a result depends on, part by part (crashlab.reconstruction.run, "Resume"): part -> digest."""
        # [refine] runs after the search and the posterior and changes neither
        study = self.spec.model_dump(exclude={"execution": {"backend", "workers", "scheduler"}, "refine": True,
                                              "case": True, "counterfactuals": True, "units": True})
        # (the case's description changes no result; the counterfactuals run after the search and the posterior;
        # the numbers are in file units whatever units the file was written in)
        scene = dataclasses.asdict(self.scene)
        for key in ("source", "references"):
            scene.pop(key, None)
        scene["road"].pop("lines", None)  # road lines are drawn, never simulated
        for v in scene["vehicles"]:
            v.pop("spec", None)
        parts = {"study file": _digest(study), "scene file": _digest(scene)}
        for v in self.scene.vehicles:
            parts[f"vehicle data of {v.name}"] = _digest(dataclasses.asdict(v.spec))
        parts["evidence"] = _digest({n: [None if e is None else float(e) for e in ev]
                                     for n, ev in self.evidence.items()})
        if self.evidence_set is not None:
            parts["evidence"] = _digest([parts["evidence"]] + [
                [it.label, it.components, it.values, it.sigmas, it.points] for it in self.evidence_set.items])
        parts["model and its options"] = _digest([self.spec.model, self.spec.model_options])
        parts["crashlab version"] = package_version()
        return parts

    def make_problem(self, constraints_as_penalty: bool = False) -> ReconstructionProblem:
        return self.problem_for(self.spec.model, self.spec.model_options, constraints_as_penalty)

    def problem_for(self, model: str, model_options: dict, constraints_as_penalty: bool = False
                    ) -> ReconstructionProblem:
        """The study's problem simulated by another model (the refine step's second opinion)."""
        return ReconstructionProblem(self.scene, self.variables, self.evidence, self.spec.objective.heading_weight,
                                     model, model_options, constraints_as_penalty, evidence_set=self.evidence_set)

    def make_repair(self):
        """The study's CollisionRepair, or None (switched off, or a scene at its collision position)."""
        if not self.spec.repair.enabled or self.scene.impact.point is not None:
            return None
        return CollisionRepair(max_shift=self.spec.repair.max_shift)

    def make_algorithm(self, optimizer: str | None = None):
        o = self.spec.optimizer
        name = optimizer or o.name
        opts = dict(o.options)
        repair = self.make_repair()
        if repair is not None:
            opts["repair"] = repair
        try:
            factory = load(OPTIMIZERS, name)
            if getattr(factory, "takes_n_obj", False):  # conventions: optimizers/pymoo_algorithms.py
                opts.setdefault("n_obj", len(self.objective_names))
            return name, factory(pop_size=o.pop_size, **opts)
        except UnknownPluginError as err:
            raise InputError(self.path, "optimizer.name", str(err)) from None
        except (TypeError, ValueError) as err:
            raise InputError(self.path, "optimizer.options", str(err)) from None

    def polish_budget(self) -> int:
        o = self.spec.optimizer
        return self.spec.polish.budget(o.pop_size, o.generations)

    def run(self, optimizer: str | None = None, workers: int | None = None, scheduler: str | None = None,
            out_dir: str | Path | None = None, resume: bool = False, progress: bool = False,
            stop_after: int | None = None, started=None):
        """Search, polish, and (with out_dir) write the outputs. stop_after: stop after that many
        generations as a kill would (checkpoint written, no polish, no outputs; returns None): tests.
        started: called once the inputs are checked and the executor is up, before the first evaluation."""
        return run_study(self, optimizer, workers, scheduler, out_dir, resume, progress, stop_after, started)


def _check_free_driver_fields(path, free, scene) -> None:
    """Free action and zone fields name an existing action or zone, and no value within the bounds can put
    a vehicle's actions out of time order, a ramp past the next action or an action past the duration
    (docs/physics.md §2a): such a candidate would be no valid scene."""
    for k, f in enumerate(free):
        kind, index, _ = f.parts
        have = len(scene.vehicle(f.vehicle).actions) if kind == "action" else \
            len(scene.road.zones) if kind == "zone" else None
        if have is not None and index >= have:
            what = f"vehicle {f.vehicle!r} has {have} action(s)" if kind == "action" else \
                f"the scene has {have} zone(s)"
            raise InputError(path, f"free.{k}.field", f"{f.field}: {what} (counted from 0)")
    for name in scene.vehicle_names:
        acts = scene.vehicle(name).actions
        if not acts:
            continue
        span = {(j, q): [getattr(a, q), getattr(a, q), None] for j, a in enumerate(acts) for q in ("t", "ramp")}
        for k, f in enumerate(free):
            kind, index, quantity = f.parts
            if kind == "action" and f.vehicle == name and quantity in ("t", "ramp"):
                span[(index, quantity)] = [f.lower, f.upper, k]
        for j in range(len(acts)):
            t_lo, t_hi, kt = span[(j, "t")]
            _, r_hi, kr = span[(j, "ramp")]
            if t_hi > scene.duration:
                raise InputError(path, f"free.{kt}.upper", f"action {j} of {name} could start after the end of "
                                 f"the run ({scene.duration:g} s)")
            if j + 1 < len(acts):
                n_lo, _, kn = span[(j + 1, "t")]
                if t_hi + r_hi > n_lo:
                    key = next(f"free.{c}.{b}" for c, b in ((kt, "upper"), (kr, "upper"), (kn, "lower"))
                               if c is not None)
                    raise InputError(path, key, f"within the bounds action {j} of {name} (and its ramp) could "
                                     f"reach past action {j + 1}: keep the actions in time order")


US_NOTE = "(units = \"us\": the file's numbers are read into the units said here)"


def load_study(path) -> Study:
    """The study in a TOML file, checked; InputError (file, key, problem) when it is not right (for a file
    written in US units, its own lines say that their numbers are in file units: US_NOTE)."""
    path = Path(path)
    data = read_toml(path, "study")
    check_kind(path, data, "study")
    data = in_file_units(data, path)  # a study written in ft, mph, lb: read once, here
    try:
        return _load_study(path, data)
    except InputError as err:
        if data.get("units") != "us" or str(err.file) != str(path):
            raise
        raise InputError(err.file, err.key, f"{err.problem} {US_NOTE}") from None


def _load_study(path: Path, data: dict) -> Study:
    try:
        spec = StudyFile.model_validate(data)
    except ValidationError as err:
        raise pydantic_error(path, err, schema=StudyFile) from None
    if spec.model not in available_models():
        raise InputError(path, "model", str(UnknownPluginError("model", spec.model, available_models())))
    if spec.optimizer.name not in available_optimizers():
        raise InputError(path, "optimizer.name",
                         str(UnknownPluginError("optimizer", spec.optimizer.name, available_optimizers())))
    _check_infer_table(path, spec)
    check_execution(path, spec)
    model = _checked_model(path, spec.model, spec.model_options, "model_options")
    if spec.refine is not None:
        if spec.refine.model not in available_models():
            raise InputError(path, "refine.model", str(UnknownPluginError("model", spec.refine.model,
                                                                          available_models())))
        _checked_model(path, spec.refine.model, spec.refine.model_options, "refine.model_options")
    scene_path = path.parent / spec.scene
    try:
        found = scene_path.is_file()
    except OSError as err:  # a name too long for the system (more than 255 bytes)
        raise InputError(path, "scene", f"scene file {spec.scene!r}: {err.strerror or err}") from None
    if not found:
        raise InputError(path, "scene", f"scene file {spec.scene!r} not found")
    scene = load_scene(scene_path)
    names = scene.vehicle_names
    seen = {}  # field path -> the [[free]] entry that first searches it
    for k, f in enumerate(spec.free):
        if f.vehicle is not None and f.vehicle not in names:
            raise InputError(path, f"free.{k}.vehicle", f"no vehicle {f.vehicle!r} in the scene ({', '.join(names)})")
        if f.path in seen:  # two columns of one field, each set in turn: the first's bounds would do nothing
            raise InputError(path, f"free.{k}", f"{f.label} is already free (free.{seen[f.path]})")
        seen[f.path] = k
    _check_free_driver_fields(path, spec.free, scene)
    uncertain = uncertain_variables(path, spec, scene)
    # checked here, not only by crashlab infer: reconstruct must not accept what infer refuses (before a twin's run)
    questions = parse_questions(spec.questions, [v.label for v in list(spec.free) + uncertain], path)
    counterfactuals = counterfactual.parse(spec.counterfactuals, scene, path)
    out = None
    if spec.evidence.twin:
        out = model.simulate(scene)  # simulate, not simulate_batch: a mark needs the recorded CG path
        if not out.outcome_ok:
            raise InputError(path, "evidence.twin", f"the model's run of the base scene failed: {outcome_reason(out)}")
        moving = [f"{n} still moving at {ms_to_kmh(out.end_speed_si[i]):.0f} km/h"
                  for i, n in enumerate(names) if not out.at_rest_mask[i]]
        if moving:
            raise InputError(path, "evidence.twin", f"{', '.join(moving)} at the end of the base scene: an end pose "
                             "is no rest pose (lengthen the scene's duration)")
    evidence_set, evidence, mode = build_evidence(path, spec, names, out,
                                                  specs={v.name: v.spec for v in scene.vehicles})
    study = Study(path, spec, scene, evidence, evidence_set if mode == "misfit" else None, uncertain)
    study.notes = free_and_uncertain(path, spec, scene, scene_path)
    study.questions, study.counterfactuals = questions, counterfactuals
    study.make_algorithm()  # [optimizer.options] checked for every command, as reconstruct's search takes them
    return study


def _checked_model(path, name: str, options: dict, key: str):
    """The model `name` with its options, or InputError naming the option's key under `key`."""
    try:
        return get_model(name, **options)
    except OptionError as err:
        raise InputError(path, f"{key}.{err.key}", err.problem) from None
    except (TypeError, ValueError) as err:
        raise InputError(path, key, str(err)) from None


def check_execution(path, spec: StudyFile) -> None:
    """[execution] scheduler: an address, alone (a Dask run) or with backend = "dask" (any scheduler made the run
    a Dask one, a backend written "serial" included; crashlab.reconstruction.run._backend). InputError naming
    execution.scheduler."""
    ex = spec.execution
    if ex.scheduler is None:
        return
    refuse_empty_scheduler(path, "execution.scheduler", ex.scheduler, "leave the key out")
    if ex.backend != "dask" and "backend" in ex.model_fields_set:  # a scheduler alone: a Dask run (run._backend)
        raise InputError(path, "execution.scheduler", f"a Dask scheduler's address contradicts execution.backend = "
                         f"{ex.backend!r} (a scheduler is for backend = \"dask\"): set that backend to run on it, "
                         "or drop the scheduler")


def _check_infer_table(path, spec: StudyFile) -> None:
    """`[infer]` checked by every command that reads the study, as `crashlab infer` checks it
    (crashlab.reconstruction.infer_settings.InferSection: one line naming infer.KEY), so that `reconstruct`
    does not quietly accept junk there (issue 27)."""
    if "infer" not in spec.model_fields_set:
        return
    try:
        InferSection.model_validate(spec.infer)
    except ValidationError as err:
        raise pydantic_error(path, err, "infer.") from None


def uncertain_variables(path, spec: StudyFile, scene: Scene) -> list[UncertainVariable]:
    """The `[[uncertain]]` parameters of the study file and of its base scene's file (the study's entry wins
    for a field in both, as in the posterior), checked (crashlab.uncertainty.parse: one line naming
    uncertain.N.key), each as an extra free variable of the search, except those on a free variable's own
    field (its bounds stand)."""
    declared = uncertainty.parse(spec.uncertain, scene, path) if spec.uncertain else ()
    by_path = {u.field: u for u in tuple(getattr(scene, "uncertain", ()) or ())}
    by_path.update({u.field: u for u in declared})
    free = {f.path for f in spec.free}
    return [UncertainVariable.of(u) for p, u in by_path.items() if p not in free]


def free_and_uncertain(path, spec: StudyFile, scene: Scene, scene_path) -> list[str]:
    """A free field whose numbers replace a setting of the scene (uncertainty.replaced_law), and a field both free
    (`[[free]]`) and uncertain (`[[uncertain]]` of the study or of its base scene's file): its meaning, one note
    line each (reconstruct prints it): the free bounds are its range in both commands, the
    search ignores the distribution, `crashlab infer` takes the distribution as its prior within the bounds
    (posterior.py). Refused (InputError naming free.K and the uncertain entry) when the distribution has no
    probability within the bounds: the prior would be 0 everywhere."""
    entries = {}  # path -> (key, Uncertain), the study's entry winning as in uncertain_variables
    for j, u in enumerate(getattr(scene, "uncertain", ()) or ()):
        entries[u.field] = (f"uncertain.{j} of {Path(scene_path).name}", u)
    for j, u in enumerate(uncertainty.parse(spec.uncertain, scene, path) if spec.uncertain else ()):
        entries[u.field] = (f"uncertain.{j}", u)
    notes = []
    for k, f in enumerate(spec.free):
        replaced = uncertainty.replaced_law(scene, f.path)
        if replaced:
            notes.append(f"{f.label} is free (free.{k}): its numbers replace {replaced} in the search's runs")
        if f.path not in entries:
            continue
        key, u = entries[f.path]
        unit = f" {u.unit}" if u.unit not in ("", "-") else ""
        lo, hi = max(float(f.lower), u.lower), min(float(f.upper), u.upper)
        if not lo < hi:
            prior = u.describe().split(": ", 1)[1]
            raise InputError(path, f"free.{k}", f"{f.label} is also uncertain ({key}: {prior}) with no probability "
                             f"within its bounds [{f.lower:g}, {f.upper:g}]{unit}: crashlab infer's prior would be 0 "
                             "everywhere; widen the bounds, move the distribution or drop one")
        notes.append(f"{f.label} is free (free.{k}, [{f.lower:g}, {f.upper:g}]{unit}) and uncertain ({key}): the "
                     f"search keeps the free bounds; crashlab infer takes {u.describe().split(': ', 1)[1]} as its "
                     "prior within them")
    return notes

