"""Reconstruction: search the pre-impact conditions whose simulated rest poses match the evidence.

One module per reason to change:
  schema   the study file (pydantic): sections, bounds, defaults;
  evidence evidence items with their sigmas, normalised residuals, the Gaussian log-likelihood (the contract
           a posterior builds on);
  study    load_study and the Study: the base scene, the evidence, the pieces a run is built from;
  problem  the pymoo Problem: free variables <-> scenes, objectives, constraints, failed evaluations;
  repair   the pymoo Repair that backs overlapping starts off and brings near misses onto a collision;
  run      the search (pymoo's Algorithm.run with a Callback: checkpoints, resume, progress);
  study_executor  the executor of a run, an unanswering Dask scheduler named by its key;
  polish   the least-squares polish of the best candidates after the search;
  refine   the second opinion ([refine]): the best candidates re-simulated and polished with another model;
  report   the Pareto table, failures.csv, figures, summary.md, the result and its JSON form;
  command  `crashlab reconstruct`;
  infer    the posterior of the free variables and uncertain parameters (`crashlab infer`), infer_report
           its outputs.
The package builds on the framework (crashlab) and reaches optimizers through the registry only.
(The least-squares routine itself is crashlab.reconstruction.polish.polish.)
"""
from .command import run_cli
from .evidence import EvidenceItem, EvidenceSet, log_likelihood_of
from .infer import PosteriorResult, run_posterior
from .polish import POLISH_SPACING, PolishResult, polish_archive, spaced_starts
from .posterior import Posterior, load_posterior
from .problem import (
    FAILED_OBJECTIVE,
    ReconstructionProblem,
    UncertainVariable,
    largest_overlap,
    outline_depth,
    search_bounds,
)
from .questions import parse_question
from .refine import RefineResult, refine
from .repair import CollisionRepair, repair_poses
from .report import (
    DUPLICATE_TOL,
    HEADING_WARN_DEG,
    ReconstructionResult,
    failure_counts,
    pareto_table,
    write_failures,
    write_outputs,
)
from .run import CHECKPOINT_FORMAT, run_study
from .schema import (
    ANGLE_MAX,
    FRICTION_MAX,
    GENERATIONS_MAX,
    IMPACT_FIELDS,
    POLISH_MIN,
    POLISH_SHARE,
    POP_SIZE_RANGE,
    POSITION_MAX,
    SEED_MAX,
    SPEED_MAX,
    VEHICLE_FIELDS,
    WORKERS_MAX,
    Evidence,
    ExecutionSection,
    FreeVariable,
    Int,
    ObjectiveSection,
    OptimizerSection,
    PolishSection,
    Real,
    RefineSection,
    RepairSection,
    RestPose,
    StudyFile,
)
from .study import Study, load_study

__all__ = [
    "ANGLE_MAX", "CHECKPOINT_FORMAT", "DUPLICATE_TOL", "FAILED_OBJECTIVE", "FRICTION_MAX",
    "GENERATIONS_MAX", "HEADING_WARN_DEG", "IMPACT_FIELDS", "POLISH_MIN", "POLISH_SHARE", "POLISH_SPACING",
    "POP_SIZE_RANGE", "POSITION_MAX", "SEED_MAX", "SPEED_MAX", "VEHICLE_FIELDS", "WORKERS_MAX",
    "CollisionRepair", "Evidence", "EvidenceItem", "EvidenceSet", "log_likelihood_of",
    "ExecutionSection", "FreeVariable", "Int", "ObjectiveSection",
    "OptimizerSection", "PolishResult", "PolishSection", "Real", "ReconstructionProblem", "ReconstructionResult",
    "RefineResult", "RefineSection", "RepairSection", "RestPose", "UncertainVariable", "refine",
    "search_bounds", "Study", "StudyFile", "failure_counts", "largest_overlap",
    "load_posterior", "load_study", "outline_depth",
    "parse_question", "Posterior", "PosteriorResult", "run_posterior", "pareto_table", "polish_archive",
    "repair_poses", "run_cli",
    "run_study", "spaced_starts", "write_failures", "write_outputs",
]
