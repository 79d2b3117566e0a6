"""Uncertain parameters: a scene field (crashlab.fields) with a probability distribution, in file units.

A scene (or study) file lists them as `[[uncertain]]` tables:

    [[uncertain]]
    field = "road.friction"          # any crashlab.fields path
    distribution = "normal"          # mean, sd (> 0); optional lower, upper: truncation
    mean = 0.75
    sd = 0.05

    distribution = "uniform"         # lower < upper
    distribution = "triangular"      # lower <= mode <= upper, lower < upper

Every bound lies within the field's range in the scene (crashlab.fields.field_range: a friction in
[0, 2], a restitution in [0, 1], a mass within the vehicle's checks, an action's time between its
neighbours). A normal distribution is truncated to [lower, upper] when given, else to the field's range
(a friction cannot go negative), and its mean lies within that interval; so every draw is a valid scene.
The entries are independent: the joint density is the product of theirs (`logpdf` sums the logs).

Sampling and densities are scipy.stats' (uniform, truncnorm, triang) with a seeded numpy Generator:
`sample(entries, n, rng)` gives an (n, k) array in file units, `logpdf(entries, X)` the joint log-density
of its rows (the posterior's log-prior), `ppf(entries, U)` maps the unit cube onto the distributions
(nested samplers), and `apply(scene, entries, row)` / `setter(scene, entries)` make the scenes.
"""
from __future__ import annotations

import dataclasses
import functools
import math
from pathlib import Path
from typing import Literal, Sequence

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError

from . import fields
from .errors import InputError
from .file_numbers import Real
from .input_files import pydantic_error
from .scene import Scene

DISTRIBUTIONS = {"uniform": ("lower", "upper"), "normal": ("mean", "sd"), "triangular": ("lower", "mode", "upper")}
OPTIONAL = {"normal": ("lower", "upper")}  # truncation of a normal


class UncertainFile(BaseModel):
    """One `[[uncertain]]` table as written (file units); the checks that need the scene are in `parse`."""
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)

    field: str = Field(min_length=1, description=f"a scene field: {fields.VALID_FORMS}")
    distribution: Literal["uniform", "normal", "triangular"] = Field(
        description="uniform (lower, upper), normal (mean, sd; optional lower, upper truncate it) or triangular "
        "(lower, mode, upper); in the field's file unit")
    lower: Real | None = Field(default=None, description="uniform, triangular: lowest value; normal: optional "
                               "truncation (default the field's range)")
    upper: Real | None = Field(default=None, description="uniform, triangular: highest value; above lower")
    mode: Real | None = Field(default=None, description="triangular: most likely value, in [lower, upper]")
    mean: Real | None = Field(default=None, description="normal: mean, within [lower, upper]")
    sd: Real | None = Field(default=None, gt=0, description="normal: standard deviation; > 0")


@dataclasses.dataclass(frozen=True)
class Uncertain:
    """A field's distribution (file units). `lower`, `upper` bound its support (for a normal: where it is
    truncated); `mean`, `sd` are a normal's parameters (before truncation), `mode` a triangular's."""
    field: str  # canonical crashlab.fields path
    distribution: str
    lower: float
    upper: float
    mean: float | None = None
    sd: float | None = None
    mode: float | None = None
    replaces: str = ""  # the scene's setting its numbers replace (restitution = "speed": replaced_law), said

    @functools.cached_property
    def dist(self):
        """The scipy.stats frozen distribution."""
        from scipy import stats
        lo, hi = self.lower, self.upper
        if self.distribution == "uniform":
            return stats.uniform(loc=lo, scale=hi - lo)
        if self.distribution == "triangular":
            return stats.triang(c=(self.mode - lo) / (hi - lo), loc=lo, scale=hi - lo)
        return stats.truncnorm(a=(lo - self.mean) / self.sd, b=(hi - self.mean) / self.sd, loc=self.mean,
                               scale=self.sd)

    @property
    def unit(self) -> str:
        return fields.parse(self.field).unit

    def sample(self, n: int, rng) -> np.ndarray:
        return np.asarray(self.dist.rvs(size=n, random_state=rng), dtype=float)

    def logpdf(self, x) -> np.ndarray:
        """Log-density (file units); -inf outside the support."""
        return self.dist.logpdf(x)

    def ppf(self, u) -> np.ndarray:
        return self.dist.ppf(u)

    def interval(self, share: float = 0.998) -> tuple[float, float]:
        """The central interval holding `share` of the distribution (finite bounds for a search that
        treats the parameter as a free variable)."""
        lo, hi = self.dist.interval(share)
        return float(lo), float(hi)

    def describe(self) -> str:
        unit = "" if self.unit == "-" else f" {self.unit}"
        said = f"; its numbers replace {self.replaces}" if self.replaces else ""
        if self.distribution == "uniform":
            return f"{self.field}: uniform on [{self.lower:g}, {self.upper:g}]{unit}{said}"
        if self.distribution == "triangular":
            return f"{self.field}: triangular on [{self.lower:g}, {self.upper:g}]{unit}, mode {self.mode:g}{said}"
        return (f"{self.field}: normal, mean {self.mean:g}, sd {self.sd:g}{unit}, truncated to "
                f"[{self.lower:g}, {self.upper:g}]{said}")


def replaced_law(scene, path: str) -> str:
    """The scene's setting that a number given to the field `path` (free, uncertain) replaces, in words, or "":
    a restitution number replaces restitution = "speed" (crashlab.fields.setter, docs/physics.md §13b)."""
    if path == "impact.restitution" and scene.impact.restitution_law == "speed":
        return 'the scene\'s restitution = "speed" (docs/physics.md §13b)'
    return ""


def parse(raw: Sequence, scene, source: str | Path = "<scene>", prefix: str = "uncertain") -> tuple[Uncertain, ...]:
    """The `[[uncertain]]` tables `raw` (a list of dicts, file units) checked against `scene`; bad input
    raises InputError naming `source` and the key (`uncertain.N.sd`, ...)."""
    if not isinstance(raw, list):
        raise InputError(source, prefix, "a list of tables ([[uncertain]])")
    out, seen = [], {}
    for k, entry in enumerate(raw):
        key = f"{prefix}.{k}"
        if not isinstance(entry, dict):
            raise InputError(source, key, "a table with field, distribution and its parameters")
        try:
            e = UncertainFile.model_validate(entry)
        except ValidationError as err:
            raise pydantic_error(source, err, key + ".", UncertainFile) from None
        try:
            f = fields.resolve(scene, e.field)
            lo, hi = fields.field_range(scene, f)
        except ValueError as err:
            raise InputError(source, f"{key}.field", str(err)) from None
        if f.path in seen:
            raise InputError(source, f"{key}.field", f"{f.path} is already uncertain ({prefix}.{seen[f.path]})")
        seen[f.path] = k
        need, allowed = DISTRIBUTIONS[e.distribution], DISTRIBUTIONS[e.distribution] + OPTIONAL.get(e.distribution, ())
        for p in ("lower", "upper", "mode", "mean", "sd"):
            given = getattr(e, p) is not None
            if p in need and not given:
                raise InputError(source, f"{key}.{p}", f"missing key: a {e.distribution} distribution needs "
                                 f"{', '.join(need)}")
            if given and p not in allowed:
                raise InputError(source, f"{key}.{p}", f"not a parameter of a {e.distribution} distribution "
                                 f"({', '.join(allowed)})")
        unit = "" if f.unit == "-" else f" {f.unit}"
        lower = lo if e.lower is None else e.lower
        upper = hi if e.upper is None else e.upper
        if e.lower is not None and not lo <= e.lower <= hi:
            raise InputError(source, f"{key}.lower", f"{e.lower:g} is outside the range of {f.path}, "
                             f"[{lo:g}, {hi:g}]{unit}")
        if e.upper is not None and not lo <= e.upper <= hi:
            raise InputError(source, f"{key}.upper", f"{e.upper:g} is outside the range of {f.path}, "
                             f"[{lo:g}, {hi:g}]{unit}")
        if not lower < upper:
            raise InputError(source, f"{key}.upper", f"upper ({upper:g}) must be above lower ({lower:g})")
        if e.mode is not None and not lower <= e.mode <= upper:
            raise InputError(source, f"{key}.mode", f"mode {e.mode:g} is outside [lower, upper] = "
                             f"[{lower:g}, {upper:g}]")
        if e.mean is not None and not lower <= e.mean <= upper:
            what = "[lower, upper]" if (e.lower, e.upper) != (None, None) else f"the range of {f.path}"
            raise InputError(source, f"{key}.mean", f"mean {e.mean:g} is outside {what}, [{lower:g}, {upper:g}]{unit}")
        if e.sd is not None and not math.isfinite((upper - lower) / e.sd):
            raise InputError(source, f"{key}.sd", f"sd {e.sd:g} is too small for the interval")
        out.append(Uncertain(f.path, e.distribution, float(lower), float(upper), mean=e.mean, sd=e.sd, mode=e.mode,
                             replaces=replaced_law(scene, f.path)))
    return tuple(out)


def _rng(rng) -> np.random.Generator:
    return rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)


def sample(entries: Sequence[Uncertain], n: int, rng=None) -> np.ndarray:
    """(n, k) independent draws, a column per entry (file units); `rng` a numpy Generator or a seed."""
    rng = _rng(rng)
    out = np.empty((int(n), len(entries)))
    for j, e in enumerate(entries):
        out[:, j] = e.sample(int(n), rng)
    return out


def logpdf(entries: Sequence[Uncertain], X) -> np.ndarray:
    """Joint log-density of rows X (n, k) or one row (k,), file units: the sum over the independent entries;
    -inf where a value lies outside its support."""
    X = np.asarray(X, dtype=float)
    one = X.ndim == 1
    X = np.atleast_2d(X)
    out = np.zeros(X.shape[0])
    for j, e in enumerate(entries):
        out += e.logpdf(X[:, j])
    return out[0] if one else out


def ppf(entries: Sequence[Uncertain], U) -> np.ndarray:
    """The unit cube mapped onto the distributions (column j by entry j's quantile function)."""
    U = np.asarray(U, dtype=float)
    out = np.empty_like(U)
    for j, e in enumerate(entries):
        out[..., j] = e.ppf(U[..., j])
    return out


def setter(scene, entries: Sequence[Uncertain], check: bool = True):
    """A function row -> Scene setting the entries' fields (crashlab.fields.setter)."""
    return fields.setter(scene, [e.field for e in entries], check=check)


def apply(scene, entries: Sequence[Uncertain], row) -> Scene:
    """The scene with the entries' fields set to one row of values (file units)."""
    return setter(scene, entries)(row)
