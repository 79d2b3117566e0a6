"""The plugin interface every collision model implements."""
from __future__ import annotations

import abc
import functools

from . import guard
from .errors import InputError
from .options import ModelOptions, parse
from .outcome import Outcome
from .scene import Scene, driver_input_key


def _refuse_unhonoured_inputs(model, scenes) -> None:
    """A model that does not declare `driver_inputs` must not quietly ignore driver actions or friction
    zones: such a scene is refused (InputError naming the scene's key)."""
    for scene in ([scenes] if isinstance(scenes, Scene) else scenes):
        key = driver_input_key(scene)
        if key:
            raise InputError(scene.source, key, f"model {model.name!r} does not honour driver actions and "
                             "friction zones; use a model that does (crashlab models)")


def _guarded(method, check):
    """`method` (simulate or simulate_batch) followed by the physics guard's `check` on what it returns."""
    @functools.wraps(method)
    def wrapper(self, scenes, *args, **kwargs):
        if not self.driver_inputs:
            _refuse_unhonoured_inputs(self, scenes)
        outs = method(self, scenes, *args, **kwargs)
        check(scenes, outs, self.guard_skip)
        return outs
    wrapper.__guarded__ = True
    return wrapper


class CollisionModel(abc.ABC):
    """A collision model knows physics only: it takes a Scene and returns an Outcome.

    The constructor takes only the model's options (the keys of its config table), as in scikit-learn,
    declared as a schema in `Options` and validated by this base class into `self.options`.
    `simulate` never raises for a physically failed run: it returns an Outcome with outcome_ok False.

    Every Outcome a model returns passes the physics guard (crashlab.guard): the base class wraps the
    `simulate` and `simulate_batch` of every subclass, built-in or plugin. `guard_skip` names the
    guard's checks that do not apply to a model (crashlab.guard.CHECKS).
    """

    name: str = ""
    guard_skip: frozenset = frozenset()
    # True: the model honours driver actions and friction zones (docs/physics.md §2a); a model that does not
    # is refused scenes that have them instead of quietly ignoring them
    driver_inputs: bool = False
    # the model's options as a schema (crashlab.options): meaning, unit, range, default, accuracy knobs;
    # None: the model takes no options
    Options: type[ModelOptions] | None = None

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        for attr, check in (("simulate", guard.check), ("simulate_batch", guard.check_batch)):
            fn = getattr(cls, attr, None)  # also a method a mixin brings along
            if fn is not None and not getattr(fn, "__guarded__", False) \
                    and not getattr(fn, "__isabstractmethod__", False):
                setattr(cls, attr, _guarded(fn, check))
        unknown = set(cls.guard_skip) - set(guard.CHECKS)
        if unknown:
            raise TypeError(f"model {cls.name!r}: unknown guard checks in guard_skip: {sorted(unknown)}")

    def __init__(self, **options):
        """Validate the options against `Options` (OptionError names the key) and keep them as
        `self.options`."""
        self.options = parse(self.name or type(self).__name__, self.Options, options)

    @abc.abstractmethod
    def simulate(self, scene: Scene) -> Outcome:
        ...

    def simulate_batch(self, scenes: list[Scene]) -> list[Outcome]:
        """Simulate many scenes; models override this to vectorise or parallelise."""
        return [self.simulate(s) for s in scenes]

    simulate_batch = _guarded(simulate_batch, guard.check_batch)

    def get_options(self) -> dict:
        return {} if self.options is None else self.options.model_dump()
