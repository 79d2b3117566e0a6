"""The numbers of scene and vehicle files: int or float, never a bool or a string (NaN and inf are refused by
the models' allow_inf_nan=False), and bounded fields whose bounds are part of their description."""
from typing import Annotated

from pydantic import Field, Strict

Real = Annotated[float, Strict()]


def bounded(lo: float, hi: float, what: str, *, lo_open: bool = False, default=...):
    """A Field for a number in [lo, hi] ((lo, hi] with lo_open); the bounds are part of its description."""
    bounds = dict(gt=lo) if lo_open else dict(ge=lo)
    return Field(default, le=hi, description=f"{what}; {'(' if lo_open else '['}{lo:g}, {hi:g}]", **bounds)
