"""`[infer]` of a study file: the posterior sampler's settings (crashlab infer, docs in
crashlab.reconstruction.posterior), checked by every command that reads the study (`reconstruct` too:
crashlab.reconstruction.study). Its own module so that the study loader checks it without importing the
posterior (which imports the study loader)."""
from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, Strict
from typing_extensions import Annotated

from .schema import SEED_MAX

Int = Annotated[int, Strict()]


class InferSection(BaseModel):
    """`[infer]` of a study file: the sampler's settings (crashlab.reconstruction.posterior's docstring)."""
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)
    sampler: Literal["emcee", "zeus"] = Field(  # zeus: the comparison (README); no --resume
        default="emcee", description="ensemble MCMC sampler; zeus cannot --resume")
    walkers: Int | None = Field(default=None, ge=8, le=10_000, multiple_of=2,  # the stretch move's two halves
                                description="[8, 10000], even; default max(32, 6 x dims), even")
    samples: Int = Field(default=20_000, ge=10, le=10_000_000,
                         description="kept samples after thinning (walkers x kept iterations, rounded up to whole "
                                     "iterations); [10, 1e7]")
    burn: Int = Field(default=500, ge=0, le=1_000_000, description="iterations discarded; [0, 1e6]")
    thin: Int = Field(default=1, ge=1, le=10_000, description="keep every thin-th iteration; [1, 10000]")
    init: Int = Field(default=20, ge=1, le=10_000, description="prior draws per walker to start from; [1, 10000]")
    seed: Int = Field(default=1, ge=0, le=SEED_MAX, description=f"seed of the sampler; [0, {SEED_MAX}]")
    checkpoint_every: Int = Field(default=100, ge=1, le=1_000_000, description="iterations; [1, 1e6]")
    draws_plotted: Int = Field(default=20, ge=0, le=1000, description="posterior draws in the top view; [0, 1000]")
