"""The plugin interface every collision model implements."""
from __future__ import annotations

import abc
import functools

from . import guard
from .outcome import Outcome
from .scene import Scene


def _guarded_simulate(simulate):
    @functools.wraps(simulate)
    def wrapper(self, scene, *args, **kwargs):
        out = simulate(self, scene, *args, **kwargs)
        guard.check(scene, out, self.guard_skip)
        return out
    wrapper.__guarded__ = True
    return wrapper


def _guarded_batch(simulate_batch):
    @functools.wraps(simulate_batch)
    def wrapper(self, scenes, *args, **kwargs):
        outs = simulate_batch(self, scenes, *args, **kwargs)
        guard.check_batch(scenes, outs, self.guard_skip)
        return outs
    wrapper.__guarded__ = True
    return wrapper


class CollisionModel(abc.ABC):
    """A collision model knows physics only: it takes a Scene and returns an Outcome.

    The constructor takes only the model's options (the keys of its config table), as in scikit-learn.
    `simulate` never raises for a physically failed run: it returns an Outcome with outcome_ok False.

    Every Outcome a model returns passes the physics guard (crashlab.guard): the base class wraps the
    `simulate` and `simulate_batch` of every subclass, built-in or plugin. `guard_skip` names the
    guard's checks that do not apply to a model (crashlab.guard.CHECKS).
    """

    name: str = ""
    guard_skip: frozenset = frozenset()

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        for attr, wrap in (("simulate", _guarded_simulate), ("simulate_batch", _guarded_batch)):
            fn = getattr(cls, attr, None)  # also a method a mixin brings along
            if fn is not None and not getattr(fn, "__guarded__", False) \
                    and not getattr(fn, "__isabstractmethod__", False):
                setattr(cls, attr, wrap(fn))
        unknown = set(cls.guard_skip) - set(guard.CHECKS)
        if unknown:
            raise TypeError(f"model {cls.name!r}: unknown guard checks in guard_skip: {sorted(unknown)}")

    def __init__(self, **options):
        if options:
            raise TypeError(f"model {self.name!r} takes no option {', '.join(sorted(options))}")

    @abc.abstractmethod
    def simulate(self, scene: Scene) -> Outcome:
        ...

    def simulate_batch(self, scenes: list[Scene]) -> list[Outcome]:
        """Simulate many scenes; models override this to vectorise or parallelise."""
        return [self.simulate(s) for s in scenes]

    simulate_batch = _guarded_batch(simulate_batch)

    def get_options(self) -> dict:
        return {}
