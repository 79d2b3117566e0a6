"""The study file (TOML): what a reconstruction searches, against which evidence, with which budget.

Every section is a strict pydantic model: unknown keys, NaN, inf and booleans for numbers are refused,
and every bound is in the field's description, so an error names the key and the allowed range
(crashlab.vehicle.pydantic_error). Ranges are those of a scene file (crashlab.scene) where they describe
the same thing.
"""
from __future__ import annotations

import math
import re
from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, Strict, StrictBool, field_validator, model_validator

from crashlab.execution import DEFAULT_TIMEOUT_S

VEHICLE_FIELDS = ("x", "y", "heading", "speed")
IMPACT_FIELDS = ("restitution", "friction")
# a driver action's value (vehicle given): actions.K.t|brake|steer|ramp; the road: road.friction and a zone's
# friction zones.K.friction (no vehicle); docs/physics.md §2a
ACTION_FIELD = re.compile(r"^actions\.(\d+)\.(t|brake|steer|ramp)$")
ZONE_FIELD = re.compile(r"^zones\.(\d+)\.friction$")
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
FIELD_RANGES = {"x": (-POSITION_MAX, POSITION_MAX), "y": (-POSITION_MAX, POSITION_MAX),
                "heading": (-ANGLE_MAX, ANGLE_MAX), "speed": (0.0, SPEED_MAX),
                "restitution": (0.0, 1.0), "friction": (0.0, FRICTION_MAX),
                "t": (0.0, DURATION_MAX), "brake": (0.0, 1.0), "steer": (-45.0, 45.0), "ramp": (0.0, DURATION_MAX)}
UNITS = {"x": " m", "y": " m", "heading": " deg", "speed": " km/h", "t": " s", "steer": " deg", "ramp": " s"}


def field_parts(field: str) -> tuple[str, int | None, str]:
    """(kind, index, quantity) of a free field: ("vehicle", None, "speed"), ("impact", None, "friction"),
    ("action", 0, "t"), ("road", None, "friction"), ("zone", 1, "friction"). ValueError for anything else."""
    if field in VEHICLE_FIELDS:
        return "vehicle", None, field
    if field in IMPACT_FIELDS:
        return "impact", None, field
    if field in ROAD_FIELDS:
        return "road", None, "friction"
    m = ACTION_FIELD.match(field)
    if m:
        return "action", int(m.group(1)), m.group(2)
    m = ZONE_FIELD.match(field)
    if m:
        return "zone", int(m.group(1)), "friction"
    raise ValueError(f"unknown field {field!r}: one of {', '.join(VEHICLE_FIELDS + IMPACT_FIELDS + ROAD_FIELDS)}, "
                     "actions.K.t|brake|steer|ramp, zones.K.friction")
POP_SIZE_RANGE = (4, 100_000)  # 4: two mating pairs; 1e5 x the largest sensible number of free variables
GENERATIONS_MAX = 100_000
SEED_MAX = 2**32 - 1  # numpy's seed range
WORKERS_MAX = 1024

Real = Annotated[float, Strict()]  # int or float, never a bool or a string; NaN and inf refused
Int = Annotated[int, Strict()]  # an integer: 1e9 (a float) and true are refused


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)


class OptimizerSection(_Strict):
    name: str = "nsga2"
    pop_size: Int = Field(default=75, ge=POP_SIZE_RANGE[0], le=POP_SIZE_RANGE[1],
                          description=f"[{POP_SIZE_RANGE[0]}, {POP_SIZE_RANGE[1]}]")
    generations: Int = Field(default=20, ge=1, le=GENERATIONS_MAX, description=f"[1, {GENERATIONS_MAX}]")
    seed: Int = Field(default=1, ge=0, le=SEED_MAX, description=f"[0, {SEED_MAX}]")
    options: dict = Field(default_factory=dict)


class FreeVariable(_Strict):
    vehicle: str | None = None  # None for the impact's and the road's fields
    field: str  # field_parts: x, y, heading, speed, restitution, friction, road.friction, actions.K.*, zones.K.*
    lower: Real
    upper: Real

    @field_validator("field")
    @classmethod
    def _known(cls, value: str) -> str:
        field_parts(value)  # ValueError names the fields there are
        return value

    @model_validator(mode="after")
    def _check(self):
        kind, _, quantity = self.parts
        lo, hi = FIELD_RANGES[quantity]
        for key in ("lower", "upper"):
            val = getattr(self, key)
            if not lo <= val <= hi:
                raise ValueError(f"{key} = {val:g} is outside [{lo:g}, {hi:g}]{UNITS.get(quantity, '')} for "
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
    def label(self) -> str:
        if self.vehicle:
            return f"{self.vehicle}.{self.field}"
        return self.field if self.parts[0] in ("road", "zone") else f"impact.{self.field}"


class RestPose(_Strict):
    x: Real = Field(ge=-POSITION_MAX, le=POSITION_MAX, description=f"m; |value| <= {POSITION_MAX:g}")
    y: Real = Field(ge=-POSITION_MAX, le=POSITION_MAX, description=f"m; |value| <= {POSITION_MAX:g}")
    # deg; without it the heading term is left out for this vehicle (dheading is empty)
    heading: Real | None = Field(default=None, ge=-ANGLE_MAX, le=ANGLE_MAX)


class Evidence(_Strict):
    rest: dict[str, RestPose] = Field(default_factory=dict)
    twin: StrictBool = False  # evidence = the model's own simulation of the base scene (twin experiment)


class ObjectiveSection(_Strict):
    # m per deg of rest-heading error; 100 m/deg would already let 0.01 deg outweigh a metre
    heading_weight: Real = Field(default=0.0, ge=0, le=100.0, description="m/deg; [0, 100]")
    hv_reference: Real = Field(default=10.0, gt=0, le=1e6)  # m, hypervolume reference point per objective
    # m: an evaluated start explains the evidence "as well" when every objective is at most this (about the
    # accuracy of a rest position measured on site); summary.md and near_optimal.csv list those starts: the
    # range of answers the evidence leaves open (e.g. brake onset against speed, README)
    near_optimal: Real = Field(default=0.1, gt=0, le=1e3, description="m; (0, 1000]")


class ExecutionSection(_Strict):
    backend: Literal["serial", "processes", "dask"] = "serial"
    workers: Int = Field(default=2, ge=1, le=WORKERS_MAX, description=f"[1, {WORKERS_MAX}]")
    scheduler: str | None = None
    # s per evaluation (crashlab.execution.DEFAULT_TIMEOUT_S); 0: no limit (the serial backend then runs
    # in this process, and a hanging model hangs the run)
    timeout_s: Real = Field(default=DEFAULT_TIMEOUT_S, ge=0, le=86400.0, description="s; [0, 86400], 0 = no limit")


class RepairSection(_Strict):
    enabled: StrictBool = True
    max_shift: Real = Field(default=1.0, ge=0, le=100.0, description="m; [0, 100]")


class PolishSection(_Strict):
    """Least-squares polish after the search (crashlab.reconstruction.polish). evaluations: the budget; absent:
    POLISH_SHARE of pop_size x generations, at least POLISH_MIN; 0: off."""
    evaluations: Int | None = Field(default=None, ge=0, le=10_000_000)
    step: Real = Field(default=0.01, gt=0, lt=0.5)  # forward-difference step, fraction of each bound range

    def budget(self, pop_size: int, generations: int) -> int:
        if self.evaluations is not None:
            return int(self.evaluations)
        return max(POLISH_MIN, math.ceil(POLISH_SHARE * pop_size * generations))


class StudyFile(_Strict):
    name: str = ""
    scene: str
    model: str = "impulse"
    model_options: dict = Field(default_factory=dict)
    optimizer: OptimizerSection = OptimizerSection()
    free: list[FreeVariable] = Field(min_length=1, max_length=1000)
    evidence: Evidence
    objective: ObjectiveSection = ObjectiveSection()
    execution: ExecutionSection = ExecutionSection()
    repair: RepairSection = RepairSection()
    polish: PolishSection = PolishSection()
