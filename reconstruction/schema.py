"""The study file (TOML): what a reconstruction searches, against which evidence, with which budget.

Every section is a strict pydantic model: unknown keys, NaN, inf and booleans for numbers are refused,
and every bound is in the field's description, so an error names the key and the allowed range
(crashlab.input_files.pydantic_error). Ranges are those of a scene file (crashlab.scene) where they describe
the same thing.
"""
from __future__ import annotations

import math
from typing import Annotated, Literal

from pydantic import (
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Field,
    Strict,
    StrictBool,
    field_validator,
    model_validator,
)

from crashlab import fields
from crashlab.damage import DamageEvidence
from crashlab.execution import DEFAULT_TIMEOUT_S, TIMEOUT_MIN_S
from crashlab.fields import study_path
from crashlab.file_numbers import Real

VEHICLE_FIELDS = ("x", "y", "heading", "speed")
IMPACT_FIELDS = ("restitution", "friction", "engagement_depth")
# also a driver action's value (vehicle given): actions.K.t|brake|steer|ramp; the road: road.friction and a
# zone's friction zones.K.friction (no vehicle); docs/physics.md §2a; read by crashlab.fields (field_parts)
ROAD_FIELDS = ("road.friction",)
DURATION_MAX = 120.0  # s, as a scene's duration
# default polish budget: this share of pop_size x generations, at least POLISH_MIN evaluations (a
# least-squares iteration costs n_var + 1 evaluations: 100 are ~10 iterations with all eight variables
# of case 5 free). The twins need it: the search alone leaves 0.16-0.23 m on twin 4 (README)
POLISH_SHARE = 0.10
POLISH_MIN = 100

# Bounds of a study file (file units): finite numbers (true/false are not numbers) in these ranges, the
# ranges of a scene file (crashlab.scene) where they describe the same thing
POSITION_MAX = 1e5  # m: |x|, |y| of free bounds and evidence (a local site frame)
ANGLE_MAX = 3600.0  # deg: |heading|
SPEED_MAX = 400.0  # km/h
FRICTION_MAX = 2.0


def field_parts(field: str) -> tuple[str, int | None, str]:
    """(kind, index, quantity) of a free field, read as crashlab.fields reads it (the one vocabulary of a
    scene's numbers): ("vehicle", None, "speed"), ("impact", None, "friction"), ("action", 0, "t"),
    ("road", None, "friction"), ("zone", 1, "friction"); a vehicle's field is relative to the variable's
    vehicle and one of its start state's VEHICLE_FIELDS. ValueError for anything else."""
    if field in IMPACT_FIELDS:
        return "impact", None, field
    try:
        f = fields.parse(field if field.startswith(("road.", "zones.")) else f"vehicles.V.{field}")
    except ValueError:
        f = None
    if f is None or f.kind == "spec" or (f.kind == "vehicle" and f.quantity not in VEHICLE_FIELDS):
        raise ValueError(f"unknown field {field!r}: one of {', '.join(VEHICLE_FIELDS + IMPACT_FIELDS + ROAD_FIELDS)}, "
                         "actions.K.t|brake|steer|ramp, zones.K.friction")
    return f.kind, f.index, f.quantity


POP_SIZE_RANGE = (4, 100_000)  # 4: two mating pairs; 1e5 x the largest sensible number of free variables
GENERATIONS_MAX = 100_000
SEED_MAX = 2**32 - 1  # numpy's seed range
WORKERS_MAX = 1024

Int = Annotated[int, Strict()]  # an integer: 1e9 (a float) and true are refused


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)


class OptimizerSection(_Strict):
    """[optimizer]: the multi-objective search."""
    name: str = Field(default="nsga2", description="a registered optimizer (crashlab models lists them)")
    pop_size: Int = Field(default=75, ge=POP_SIZE_RANGE[0], le=POP_SIZE_RANGE[1],
                          description=f"population size; [{POP_SIZE_RANGE[0]}, {POP_SIZE_RANGE[1]}]")
    generations: Int = Field(default=20, ge=1, le=GENERATIONS_MAX,
                             description=f"number of generations; [1, {GENERATIONS_MAX}]")
    seed: Int = Field(default=1, ge=0, le=SEED_MAX, description=f"seed of the search; [0, {SEED_MAX}]")
    options: dict = Field(default_factory=dict, description="[optimizer.options]: passed to the optimizer "
                          "as its own settings")


class FreeVariable(_Strict):
    vehicle: str | None = Field(default=None, description="the vehicle's name; absent for the impact's and "
                                "the road's fields")  # None for the impact's and the road's fields
    # field_parts: x, y, heading, speed, restitution, friction, road.friction, actions.K.*, zones.K.*
    field: str = Field(description="x, y, heading, speed (a vehicle's start state), restitution, friction "
                       "(the impact), road.friction, zones.K.friction, actions.K.t|brake|steer|ramp")
    lower: Real = Field(description="lowest value searched, in the field's file unit (m, deg, km/h, s); within "
                        "the scene file's range of the field")
    upper: Real = Field(description="highest value searched, in the field's file unit; above lower")

    @field_validator("field")
    @classmethod
    def _known(cls, value: str) -> str:
        field_parts(value)  # ValueError names the fields there are
        return value

    @model_validator(mode="after")
    def _check(self):
        kind, _, quantity = self.parts
        lo, hi = fields.STATIC_RANGES[quantity]  # the scene file's range of the field
        for key in ("lower", "upper"):
            val = getattr(self, key)
            if not lo <= val <= hi:
                unit = "" if fields.UNITS[quantity] == "-" else " " + fields.UNITS[quantity]
                raise ValueError(f"{key} = {val:g} is outside [{lo:g}, {hi:g}]{unit} for "
                                 f"{self.field}")
        if not self.lower < self.upper:
            raise ValueError(f"lower ({self.lower}) must be below upper ({self.upper})")
        if kind in ("vehicle", "action") and self.vehicle is None:
            raise ValueError(f"field {self.field!r} needs a vehicle")
        if kind in ("impact", "road", "zone") and self.vehicle is not None:
            raise ValueError(f"field {self.field!r} belongs to the {kind}: give no vehicle")
        return self

    @property
    def parts(self) -> tuple[str, int | None, str]:
        return field_parts(self.field)

    @property
    def path(self) -> str:
        """The field's crashlab.fields path (vehicles.V1.speed, impact.friction, road.zones.0.friction, ...)."""
        return study_path(self.vehicle, self.field)

    @property
    def label(self) -> str:
        if self.vehicle:
            return f"{self.vehicle}.{self.field}"
        return self.field if self.parts[0] in ("road", "zone") else f"impact.{self.field}"


SIGMA_POSITION_MAX = 1e3  # m: a standard deviation of a measured position
SIGMA_ANGLE_MAX = 180.0  # deg
SIGMA_SPEED_MAX = SPEED_MAX  # km/h
MARK_POINTS_MAX = 10_000


class RestPose(_Strict):
    """A measured rest pose (docs/physics.md, "Evidence and likelihood"). x, y are required unless the study
    is a twin (the model's run fills them); sigma_xy [m] is the standard deviation of each coordinate,
    sigma_heading [deg] that of the heading."""
    x: Real | None = Field(default=None, ge=-POSITION_MAX, le=POSITION_MAX,
                           description=f"m; |value| <= {POSITION_MAX:g}")
    y: Real | None = Field(default=None, ge=-POSITION_MAX, le=POSITION_MAX,
                           description=f"m; |value| <= {POSITION_MAX:g}")
    # deg; without it the heading term is left out for this vehicle (dheading is empty)
    heading: Real | None = Field(default=None, ge=-ANGLE_MAX, le=ANGLE_MAX,
                                 description="deg, measured rest heading; absent: no heading term")
    sigma_xy: Real | None = Field(default=None, gt=0, le=SIGMA_POSITION_MAX,
                                  description=f"m; (0, {SIGMA_POSITION_MAX:g}]")
    sigma_heading: Real | None = Field(default=None, gt=0, le=SIGMA_ANGLE_MAX,
                                       description=f"deg; (0, {SIGMA_ANGLE_MAX:g}]")


class ImpactEvidence(_Strict):
    """The point of impact [m] (debris, gouges): the point of the first impact row (crashlab.outcome);
    sigma [m] per coordinate. x, y may be left to a twin's run."""
    x: Real | None = Field(default=None, ge=-POSITION_MAX, le=POSITION_MAX,
                           description=f"m; |value| <= {POSITION_MAX:g}")
    y: Real | None = Field(default=None, ge=-POSITION_MAX, le=POSITION_MAX,
                           description=f"m; |value| <= {POSITION_MAX:g}")
    sigma: Real = Field(gt=0, le=SIGMA_POSITION_MAX, description=f"m; (0, {SIGMA_POSITION_MAX:g}]")


Point = tuple[Annotated[float, Strict(), Field(ge=-POSITION_MAX, le=POSITION_MAX)],
              Annotated[float, Strict(), Field(ge=-POSITION_MAX, le=POSITION_MAX)]]


class MarkEvidence(_Strict):
    """A tyre or CG mark: the vehicle's CG path passes within sigma [m] of each point (x, y) [m]. A twin
    may leave the points out: then n_points points of the run's own CG path, evenly spaced in time."""
    vehicle: str = Field(description="the name of the vehicle that left the mark")
    points: list[Point] | None = Field(default=None, min_length=2, max_length=MARK_POINTS_MAX,
                                       description=f"m; at least 2 points [x, y], at most {MARK_POINTS_MAX}")
    sigma: Real = Field(gt=0, le=SIGMA_POSITION_MAX, description=f"m; (0, {SIGMA_POSITION_MAX:g}]")
    n_points: Int | None = Field(default=None, ge=2, le=MARK_POINTS_MAX,
                                 description=f"twin only: points taken from the run's CG path; [2, {MARK_POINTS_MAX}]")


class EdrEvidence(_Strict):
    """An event data recorder's values [km/h]: the speed at first contact and the delta-V (the magnitude of
    the sum of the vehicle's impact-row velocity changes); each with its sigma [km/h]."""
    speed_at_impact: Real | None = Field(default=None, ge=0, le=SPEED_MAX, description=f"km/h; [0, {SPEED_MAX:g}]")
    sigma_speed: Real | None = Field(default=None, gt=0, le=SIGMA_SPEED_MAX,
                                     description=f"km/h; (0, {SIGMA_SPEED_MAX:g}]")
    delta_v: Real | None = Field(default=None, ge=0, le=SPEED_MAX, description=f"km/h; [0, {SPEED_MAX:g}]")
    sigma_delta_v: Real | None = Field(default=None, gt=0, le=SIGMA_SPEED_MAX,
                                       description=f"km/h; (0, {SIGMA_SPEED_MAX:g}]")


class Evidence(_Strict):
    """[evidence]: what was measured on site (docs/physics.md, "Evidence and likelihood")."""
    rest: dict[str, RestPose] = Field(default_factory=dict, description="[evidence.rest.<vehicle>]: measured "
                                      "rest poses by vehicle name")
    impact: ImpactEvidence | None = Field(default=None, description="[evidence.impact]: the measured point of "
                                          "impact")
    marks: list[MarkEvidence] = Field(default_factory=list, max_length=1000,
                                      description="[[evidence.marks]]: tyre or CG marks")
    edr: dict[str, EdrEvidence] = Field(default_factory=dict, description="[evidence.edr.<vehicle>]: event data "
                                        "recorder values by vehicle name")
    damage: dict[str, DamageEvidence] = Field(default_factory=dict, description="[evidence.damage.<vehicle>]: "
                                              "measured crush profiles by vehicle name, as evidence of the "
                                              "impact's severity (its EES, CRASH3)")
    # evidence = the model's own simulation of the base scene (twin experiment): it fills every value the
    # file leaves out (all rest poses when the file gives no other evidence)
    twin: StrictBool = Field(default=False, description="twin experiment: the model's own run of the base "
                             "scene fills every value the file leaves out")
    # twin only: Gaussian noise with the given sigmas is added to every value the run fills (calibration)
    noise_seed: Int | None = Field(default=None, ge=0, le=SEED_MAX,
                                   description=f"twin only: seed of Gaussian noise (the sigmas) added to the "
                                   f"values the run fills; [0, {SEED_MAX}]")

    @property
    def has_uncertainty(self) -> bool:
        """Any sigma or any evidence besides rest poses: the normalised misfit is then the default objective."""
        return bool(self.impact or self.marks or self.edr or self.damage or any(
            p.sigma_xy is not None or p.sigma_heading is not None for p in self.rest.values()))


class ObjectiveSection(_Strict):
    # "thesis": f = |r - r*| + heading_weight |dpsi| per vehicle with a rest pose [m] (thesis eqs 4.13-4.14);
    # "misfit": per vehicle the normalised misfit sqrt(sum (residual / sigma)^2) of its evidence items
    # (crashlab.reconstruction.evidence). Default: "misfit" as soon as any sigma or any evidence besides
    # rest poses is given, else "thesis"
    mode: Literal["thesis", "misfit"] | None = Field(
        default=None, description="thesis: |r - r*| + heading_weight |dpsi| per vehicle [m]; misfit: the "
        "normalised misfit of each vehicle's evidence [sigmas]; absent: misfit when any sigma or any evidence "
        "besides rest poses is given, else thesis")
    # m per deg of rest-heading error; 100 m/deg would already let 0.01 deg outweigh a metre
    heading_weight: Real = Field(default=0.0, ge=0, le=100.0,
                                 description="m/deg, weight of the rest-heading error (thesis); [0, 100]")
    hv_reference: Real = Field(default=10.0, gt=0, le=1e6,  # m, hypervolume reference point per objective
                               description="m, hypervolume reference point per objective (misfit: sigmas)")
    # m: an evaluated start explains the evidence "as well" when every objective is at most this (about the
    # accuracy of a rest position measured on site); summary.md and near_optimal.csv list those starts: the
    # range of answers the evidence leaves open (e.g. brake onset against speed, README)
    # absent: 0.1 m with the thesis objective; 1.0 with the misfit (every vehicle's evidence within about one
    # sigma), whose objectives are in units of sigma
    near_optimal: Real | None = Field(default=None, gt=0, le=1e3,
                                      description="m (misfit: sigmas), every objective at most this counts as "
                                      "explaining the evidence as well (near_optimal.csv); absent: 0.1 thesis, "
                                      "1.0 misfit; (0, 1000]")

    def near_optimal_tol(self, mode: str) -> float:
        if self.near_optimal is not None:
            return float(self.near_optimal)
        return 0.1 if mode == "thesis" else 1.0


class ExecutionSection(_Strict):
    """[execution]: where the evaluations run."""
    backend: Literal["serial", "processes", "dask"] = Field(
        default="serial", description="serial (one process), processes (a local pool) or dask (a cluster)")
    workers: Int = Field(default=2, ge=1, le=WORKERS_MAX, description=f"worker processes; [1, {WORKERS_MAX}]")
    scheduler: str | None = Field(default=None, description="dask: the scheduler's address; absent: a local "
                                  "cluster")
    # s per evaluation (crashlab.execution.DEFAULT_TIMEOUT_S); 0: no limit (the serial backend then runs
    # in this process, and a hanging model hangs the run)
    timeout_s: Real = Field(default=DEFAULT_TIMEOUT_S, ge=0, le=86400.0,
                            description=f"s per evaluation; [0, 86400], 0 = no limit, else at least {TIMEOUT_MIN_S:g}")

    @field_validator("timeout_s")
    @classmethod
    def _a_limit_or_none(cls, v):
        if 0 < v < TIMEOUT_MIN_S:
            raise ValueError(f"{v:g} s: 0 (no limit) or at least {TIMEOUT_MIN_S:g} s (a worker's round trip takes "
                             "milliseconds: a shorter limit is not what it says)")
        return v


class RepairSection(_Strict):
    """[repair]: candidates whose vehicles overlap at the start are moved back along the heading; candidates
    that miss each other are shifted sideways into contact (reconstruction/repair.py)."""
    enabled: StrictBool = Field(default=True, description="repair infeasible candidates before they are simulated")
    max_shift: Real = Field(default=1.0, ge=0, le=100.0,
                            description="m, the largest sideways shift that brings a missing candidate into "
                            "contact; [0, 100]")


class PolishSection(_Strict):
    """Least-squares polish after the search (crashlab.reconstruction.polish). evaluations: the budget; absent:
    POLISH_SHARE of pop_size x generations, at least POLISH_MIN; 0: off."""
    evaluations: Int | None = Field(default=None, ge=0, le=10_000_000,
                                    description=f"model evaluations of the polish; absent: {POLISH_SHARE:g} x "
                                    f"pop_size x generations, at least {POLISH_MIN}; 0: off")
    step: Real = Field(default=0.01, gt=0, lt=0.5,  # forward-difference step, fraction of each bound range
                       description="forward-difference step, a fraction of each free variable's range")

    def budget(self, pop_size: int, generations: int) -> int:
        if self.evaluations is not None:
            return int(self.evaluations)
        return max(POLISH_MIN, math.ceil(POLISH_SHARE * pop_size * generations))


REFINE_CANDIDATES_DEFAULT = 5
REFINE_EVALUATIONS_DEFAULT = 200


class RefineSection(_Strict):
    """[refine]: a second opinion from another (richer) model after the search (crashlab.reconstruction.refine):
    the best candidates (the Pareto rows, best first; or posterior draws) are simulated again with `model` and
    polished by least squares with it (crashlab.reconstruction.polish) within `evaluations`."""
    model: str = Field(description="the model of the second opinion, e.g. multibody (crashlab models lists them)")
    model_options: dict = Field(default_factory=dict, description="[refine.model_options]: that model's options "
                                "(crashlab models --options NAME)")
    evaluations: Int = Field(default=REFINE_EVALUATIONS_DEFAULT, ge=1, le=10_000_000,
                             description="evaluations of the refine model in all: re-simulating the candidates, "
                             "then the polish; [1, 1e7]")
    candidates: Int = Field(default=REFINE_CANDIDATES_DEFAULT, ge=1, le=10_000,
                            description="how many of the best candidates are simulated again (then polished, best "
                            "first, while the budget lasts); [1, 10000]")


CASE_TEXT_MAX = 10_000  # characters of one note, assumption or limitation


def _iso_date(value):
    """[case] date: a TOML date (2026-11-26) or a string, kept as the text the report prints."""
    import datetime as dt
    return value.isoformat() if isinstance(value, (dt.date, dt.datetime)) else value


CaseText = Annotated[str, Field(max_length=CASE_TEXT_MAX)]


class CaseSection(_Strict):
    """[case]: who reconstructs what, on which assumptions; shown first in report.html (changes no result)."""
    id: CaseText | None = Field(default=None, description="the case number or file reference, as the client gives "
                                "it")
    analyst: CaseText | None = Field(default=None, description="who made the reconstruction")
    date: Annotated[CaseText, BeforeValidator(_iso_date)] | None = Field(
        default=None, description="date of the reconstruction: a TOML date (2026-11-26) or text")
    notes: CaseText | None = Field(default=None, description="free text: the question asked, the material received")
    assumptions: list[CaseText] = Field(default_factory=list, max_length=1000,
                                        description="what the reconstruction takes as given, one string each")
    limitations: list[CaseText] = Field(default_factory=list, max_length=1000,
                                        description="what it cannot tell, one string each")


class StudyFile(_Strict):
    """A study: the base scene, the free variables searched, the evidence, the objective and the budget."""
    units: Literal["si", "us"] = Field(default="si", description="the file's units: \"si\" (m, km/h, kg as every "
                                       "key's unit says) or \"us\" (ft, mph, lb: the US unit column; a [[free]] "
                                       "or [[uncertain]] table's numbers and a counterfactual's set and shift in "
                                       "their field's, a question's numbers in the variables' US units); the base "
                                       "scene says its own")
    name: str = Field(default="", description="title of the study in outputs")
    case: CaseSection | None = Field(default=None, description="[case]: case id, analyst, date, notes, "
                                     "assumptions and limitations, shown first in report.html")
    scene: str = Field(description="the base scene file, a path relative to the study file")
    model: str = Field(default="impulse", description="the collision model (crashlab models lists them)")
    model_options: dict = Field(default_factory=dict, description="[model_options]: the model's options "
                                "(crashlab models --options NAME)")
    optimizer: OptimizerSection = Field(default=OptimizerSection(), description="[optimizer]: the search")
    free: list[FreeVariable] = Field(min_length=1, max_length=1000, description="[[free]]: the variables "
                                     "searched, each with its bounds")
    evidence: Evidence = Field(description="[evidence]: the measurements the solutions must explain")
    objective: ObjectiveSection = Field(default=ObjectiveSection(), description="[objective]: how a start "
                                        "state's misfit is measured")
    execution: ExecutionSection = Field(default=ExecutionSection(), description="[execution]: where the "
                                        "evaluations run")
    repair: RepairSection = Field(default=RepairSection(), description="[repair]: overlapping start states")
    polish: PolishSection = Field(default=PolishSection(), description="[polish]: least-squares polish of "
                                  "the best solutions")
    refine: RefineSection | None = Field(default=None, description="[refine]: re-simulate and polish the best "
                                         "candidates with another model (absent: no second opinion)")
    # infer, questions and counterfactuals are read by `crashlab infer` and checked by every command when the
    # study is loaded (study.py: InferSection, questions.QuestionFile, counterfactual.parse); uncertain is read
    # by both (crashlab.uncertainty checks it when the study is loaded): the
    # posterior's priors, the search's extra free variables within their support (problem.UncertainVariable)
    infer: dict = Field(default_factory=dict, description="the posterior sampler's settings (crashlab infer)")
    questions: list[dict] = Field(default_factory=list, description="[[questions]] expr = ... (crashlab infer)")
    counterfactuals: list[dict] = Field(default_factory=list, description="[[counterfactuals]] name, set, shift, "
                                        "scale, keep: what if ... answered from the posterior's draws (crashlab "
                                        "infer, crashlab avoid; crashlab.reconstruction.counterfactual)")
    uncertain: list[dict] = Field(default_factory=list,
                                  description="[[uncertain]] parameters: priors of crashlab infer; extra free "
                                  "variables of crashlab reconstruct within their support (uniform and "
                                  "triangular: lower..upper; normal: mean +- 3 sd within its truncation); on a "
                                  "[[free]] variable's own field: infer's prior within the free bounds, which the "
                                  "search keeps (reconstruct says so; refused when it has no probability there)")
