"""What a run cost and how it went, filled the same way by every model (`Outcome.diagnostics`).

The core fields mean the same in every model, so studies can compare models on them; anything else a
model reports (wheel loads, sleeping times, ...) goes into `extra`. Diagnostics is also a mapping:
`d["steps"]` reads a core field or an extra, `d["wheel_loads"] = ...` writes one.
"""
from __future__ import annotations

import dataclasses
import math
from collections.abc import MutableMapping


def _core(meaning: str):
    """A core field: None until the model (or the guard, or Outcome) reports it; `meaning` documents it."""
    return dataclasses.field(default=None, metadata={"meaning": meaning})


@dataclasses.dataclass
class Diagnostics(MutableMapping):
    steps: int | None = _core("accepted integration steps (an event-driven model: its fixed or fine steps)")
    rejected_steps: int | None = _core("steps rejected and repeated shorter (error control, contact onset, "
                                       "load iteration)")
    episodes: int | None = _core("impacts or contact episodes between vehicles, or vehicles and barriers")
    t_end: float | None = _core("simulated time reached [s]")
    max_penetration: float | None = _core("deepest contact overlap during the run [m] (0: an impulse model)")
    energy_start: float | None = _core("kinetic energy of all vehicles at the start [J] (filled by the guard)")
    energy_end: float | None = _core("kinetic energy of all vehicles at the end [J] (filled by the guard)")
    energy_impacts: float | None = _core("energy dissipated by the impacts or contact episodes [J] (filled by "
                                         "the guard)")
    wall_time_s: float | None = _core("wall-clock time of the simulation [s]")
    extra: dict = dataclasses.field(default_factory=dict)

    @classmethod
    def of(cls, value) -> Diagnostics:
        """A Diagnostics from a Diagnostics (returned as is), a dict (core keys to the fields) or None."""
        if isinstance(value, Diagnostics):
            return value
        d = cls()
        for k, v in (value or {}).items():
            d[k] = v
        return d

    def __getitem__(self, key):
        if key in CORE:
            v = getattr(self, key)
            if v is None:
                raise KeyError(key)
            return v
        return self.extra[key]

    def __setitem__(self, key, value):
        if key in CORE:
            value = None if value is None else CORE[key](value)
            setattr(self, key, value)
        else:
            self.extra[key] = value

    def __delitem__(self, key):
        if key in CORE:
            setattr(self, key, None)
        else:
            del self.extra[key]

    def __iter__(self):
        yield from (k for k in CORE if getattr(self, k) is not None)
        yield from self.extra

    def __len__(self):
        return sum(1 for _ in self)

    def core(self) -> dict:
        """The core fields, None for those a model did not report."""
        return {k: getattr(self, k) for k in CORE}

    def to_json_dict(self) -> dict:
        def clean(v):
            if isinstance(v, float) and not math.isfinite(v):
                return None
            if hasattr(v, "tolist"):
                return v.tolist()
            return v
        return {k: clean(v) for k, v in self.items()}


# core field -> its type (int or float); the meanings are in the fields' metadata
CORE = {f.name: (int if f.type.startswith("int") else float) for f in dataclasses.fields(Diagnostics)
        if f.name != "extra"}
