"""The plugin interface every collision model implements."""
from __future__ import annotations

import abc
import functools
import math
import types

import numpy as np

from . import fields as scene_fields
from . import guard
from .errors import InputError
from .options import ModelOptions, parse
from .outcome import Outcome
from .population import ARRAYS, Population, Variants
from .scene import APPROACH_GAP, Scene, approach_scene, approach_time, driver_input_key

INVALID = ("raise", "fail", "unchecked")  # what simulate_population does with a row that is no valid scene


def _refuse_unhonoured_inputs(model, scenes) -> None:
    """A model that does not declare `driver_inputs` must not quietly ignore driver actions or friction
    zones: such a scene is refused (InputError naming the scene's key)."""
    for scene in ([scenes] if isinstance(scenes, Scene) else scenes):
        key = driver_input_key(scene)
        if key:
            raise InputError(scene.source, key, f"model {model.name!r} does not honour driver actions and "
                             "friction zones; use a model that does (crashlab models)")


def _runs_otherwise(model, scene: Scene) -> bool:
    """Whether the model runs another scene than the one given (_as_run): one that finds its own contacts given a
    collision position or the impulse model's point = "engagement"."""
    return not model.collision_position and (scene.impact.point is not None or scene.impact.engagement)


def _as_run(model, scene: Scene) -> tuple[Scene, list[str]]:
    """The scene a model runs and what the run's Outcome says about it (docs/physics.md §4 "Approach"): a model
    that finds its own contacts (collision_position False) runs a collision position ([impact] point, outlines
    overlapping by design) from its approach, the vehicles moved back along their velocities until apart (bodies
    started inside each other bear the overlap as crush at once); the impulse model's [impact] point =
    "engagement" it does not read. InputError (impact.point) where the vehicles do not part."""
    if not _runs_otherwise(model, scene):
        return scene, []
    notes = []
    if scene.impact.point is not None:
        try:
            t = approach_time(scene)
        except ValueError as err:
            raise InputError(scene.source, "impact.point", f"{err}: model {model.name!r} finds its own contacts "
                             "and cannot start inside the collision position") from None
        if t == 0.0:
            notes.append(f"{model.name} finds its own contacts: it ignores the given [impact] point, whose outlines "
                         "do not overlap at the start (docs/physics.md §4 \"Approach\")")
        else:
            notes.append(f"{model.name} finds its own contacts: it runs the collision position ([impact] point) "
                         f"from {t:.3f} s before it, each vehicle moved back along its start velocity until the "
                         f"outlines are {APPROACH_GAP:g} m of closing travel apart; its times count from there, the "
                         "scene's duration and driver actions as much later (docs/physics.md §4 \"Approach\")")
            notes += [f"{v.name}'s start yaw rate turns it by {math.degrees(v.yaw_rate * t):.1f} deg on the "
                      "straight approach: it reaches the collision position at another heading"
                      for v in scene.vehicles if abs(math.degrees(v.yaw_rate * t)) >= 0.05]
            notes += [f"{v.name}'s start steer angle curves its path on the approach, which is taken straight: it "
                      "reaches the collision position elsewhere" for v in scene.vehicles if v.steer]
        scene = approach_scene(scene, t=t)
    if scene.impact.engagement:
        notes.append(f'{model.name} ignores [impact] point = "engagement" (an impulse-model setting): it finds '
                     "its own contacts")
    return scene, notes


def _guarded(method, check):
    """`method` (simulate or simulate_batch) on the scenes as the model runs them (_as_run) followed by the
    physics guard's `check` on what it returns."""
    @functools.wraps(method)
    def wrapper(self, scenes, *args, **kwargs):
        if not self.driver_inputs:
            _refuse_unhonoured_inputs(self, scenes)
        one = isinstance(scenes, Scene)
        runs = [_as_run(self, s) for s in ([scenes] if one else scenes)]
        scenes = runs[0][0] if one else [s for s, _ in runs]
        outs = method(self, scenes, *args, **kwargs)
        for out, (_, notes) in zip([outs] if one else outs, runs):
            if notes and isinstance(out, Outcome):  # after the model's own (a failed run's reason comes first); once
                # (a batch's default runs simulate, wrapped too)
                out.warnings += [n for n in notes if n not in out.warnings]
        check(scenes, outs, self.guard_skip)
        return outs
    wrapper.__guarded__ = True
    return wrapper


def _guarded_population(method):
    """`simulate_population` around a model's own: the fields resolved and the rows checked (crashlab.fields:
    ranges, NaN, action order, mass), the model run on the valid rows, the physics guard on the arrays
    (crashlab.guard.check_population), the source kept for Population.outcome."""
    @functools.wraps(method)
    def wrapper(self, scene, fields, values, invalid: str = "raise"):
        if invalid not in INVALID:
            raise ValueError(f"invalid = {invalid!r}: one of {', '.join(INVALID)}")
        if not self.driver_inputs:
            _refuse_unhonoured_inputs(self, scene)
        fs = []
        for path in fields:
            try:
                fs.append(scene_fields.resolve(scene, path))
            except ValueError as err:
                raise ValueError(f"field {path!r}: {err}") from None
        scene_fields.resolve_all(scene, fs)  # each field once
        values = np.asarray(values, dtype=float)
        if values.ndim == 1 and len(fs) == 1:  # one field: its N values
            values = values.reshape(-1, 1)
        if values.ndim != 2 or values.shape[1] != len(fs):
            raise ValueError(f"values of shape {values.shape}: (N, {len(fs)}) for {len(fs)} field(s)")
        why = scene_fields.row_problems(scene, fs, values) if invalid != "unchecked" \
            else np.full(len(values), "", dtype=object)
        bad = np.flatnonzero(why != "")
        if invalid == "raise" and len(bad):
            raise ValueError(f"row {bad[0]}: {why[bad[0]]}")
        good = np.flatnonzero(why == "")
        pop = Population.empty(len(values), scene.vehicle_names)
        pop.mass[:] = scene_fields.vehicle_columns(scene, fs, values, ("mass",))["mass"]
        if len(good) and _runs_otherwise(self, scene):
            # each row's scene as the model runs it (its approach depends on the row's speeds and poses: _as_run;
            # a model's own simulate_population is not used for them)
            part = Population.of_outcomes(simulate_each(self, Variants(scene, tuple(fs), values[good]).scenes()),
                                          scene.vehicle_names)
        elif len(good):
            part = method(self, scene, fs, values[good])
        if len(good):
            _put_rows(pop, good, part)
        for k in bad:
            pop.fail(k, f"no valid scene: {why[k]}")
        guard.check_population(scene, fs, values, pop, self.guard_skip)
        pop.variants, pop.model = Variants(scene, tuple(fs), values, invalid), self
        return pop
    wrapper.__guarded__ = True
    return wrapper


class _GuardedMethod:
    """simulate / simulate_batch / simulate_population of a model class with the guard around it, as a data
    descriptor: it takes precedence over an instance's attribute of the same name, so a function assigned to
    the instance (`self.simulate = self._fast` in __init__, or written into its __dict__) is guarded too
    (issue 27: such an attribute escaped the class-level wrapper)."""

    def __init__(self, name: str, fn, wrap):
        self.name, self.wrap, self.fn = name, wrap, wrap(fn)

    def __get__(self, obj, cls=None):
        if obj is None:
            return self.fn  # the guarded function (its __wrapped__ the model's own)
        own = getattr(obj, "__dict__", {}).get(self.name)
        if own is None:
            return types.MethodType(self.fn, obj)
        return types.MethodType(self.wrap(functools.wraps(own)(lambda _self, *a, **k: own(*a, **k))), obj)

    def __set__(self, obj, value) -> None:
        obj.__dict__[self.name] = value

    def __delete__(self, obj) -> None:
        obj.__dict__.pop(self.name, None)


_WRAPS = {"simulate": lambda fn: _guarded(fn, guard.check),
          "simulate_batch": lambda fn: _guarded(fn, guard.check_batch),
          "simulate_population": _guarded_population}


def _put_rows(pop: Population, rows, part: Population) -> None:
    """The model's results for the rows (the masses are the wrapper's, from the rows)."""
    for name in ARRAYS:
        if name != "mass":
            getattr(pop, name)[rows] = getattr(part, name)


def simulate_each(model, scenes, batch: bool = True) -> list:
    """The Outcome of every scene, an exception in place of the outcome of a scene whose simulation raised:
    model.simulate_batch (batch=True), or, when it raises or returns another count, model.simulate scene by
    scene, so that a bad scene fails alone."""
    scenes = list(scenes)
    if batch:
        try:
            outs = list(model.simulate_batch(scenes))
            if len(outs) == len(scenes):
                return outs
        except Exception:  # noqa: BLE001 - one by one, so one bad scene fails alone
            pass
    outs = []
    for s in scenes:
        try:
            outs.append(model.simulate(s))
        except Exception as err:  # noqa: BLE001
            outs.append(err)
    return outs


class CollisionModel(abc.ABC):
    """A collision model knows physics only: it takes a Scene and returns an Outcome.

    The constructor takes only the model's options (the keys of its config table), as in scikit-learn,
    declared as a schema in `Options` and validated by this base class into `self.options`.
    `simulate` never raises for a physically failed run: it returns an Outcome with outcome_ok False.

    Every Outcome a model returns passes the physics guard (crashlab.guard): the base class wraps the
    `simulate`, `simulate_batch` and `simulate_population` of every subclass, built-in or plugin, also one
    assigned to an instance (a data descriptor, _GuardedMethod). `guard_skip` names the
    guard's checks that do not apply to a model (crashlab.guard.CHECKS).
    """

    name: str = ""
    guard_skip: frozenset = frozenset()
    # True: the model honours driver actions and friction zones (docs/physics.md §2a); a model that does not
    # is refused scenes that have them instead of quietly ignoring them
    driver_inputs: bool = False
    # True: the model resolves an impact at a given collision position ([impact] point and plane_angle, the outlines
    # overlapping: the impulse model, docs/physics.md §4); False: it finds its own contacts, and the base class runs
    # such a scene from its approach (crashlab.scene.approach_scene, a warning says so: _as_run)
    collision_position: bool = False
    # True: Diagnostics.max_penetration is a contact depth (a crush to compare with a crash test's); False: rigid
    # outlines resolved at first touch (the impulse model), no crush to compare
    contact_depth: bool = True
    # the package (folder name) whose numba kernels the model compiles on first use (about 30 s once per install;
    # the command line says so before a cold compile and keeps the compile out of the simulation's time), or None
    compiles: str | None = None
    # the model's options as a schema (crashlab.options): meaning, unit, range, default, accuracy knobs;
    # None: the model takes no options
    Options: type[ModelOptions] | None = None

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        for attr, wrap in _WRAPS.items():
            fn = getattr(cls, attr, None)  # also a method a mixin brings along
            if fn is not None and not getattr(fn, "__guarded__", False) \
                    and not getattr(fn, "__isabstractmethod__", False):
                setattr(cls, attr, _GuardedMethod(attr, fn, wrap))
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

    simulate_batch = _GuardedMethod("simulate_batch", simulate_batch, _WRAPS["simulate_batch"])

    def simulate_population(self, scene: Scene, fields, values, invalid: str = "raise") -> Population:
        """N variants of `scene` with `fields` (dotted paths, crashlab.fields) set to the rows of `values`
        ((N, k), file units) -> a Population (crashlab.population: arrays, one row per variant).

        invalid: a row that is no valid scene (outside a field's range, NaN, actions out of order, a mass the
        vehicle's checks refuse): "raise" ValueError naming the row and the field, "fail" the row fails with
        the reason, "unchecked" no check (the caller's values lie within the ranges). A field the scene does
        not have: ValueError naming it. Every row passes the physics guard (crashlab.guard.check_population).

        A model overrides it with (scene, fields as resolved Fields, the valid rows) and returns the rows'
        Population; the base class's wrapper does the checks, the guard and the rest. This base
        implementation builds a scene per row and runs `simulate_batch` (a plugin works unchanged)."""
        scenes = Variants(scene, tuple(fields), values).scenes()
        return Population.of_outcomes(simulate_each(self, scenes), scene.vehicle_names)

    simulate_population = _GuardedMethod("simulate_population", simulate_population, _guarded_population)

    def get_options(self) -> dict:
        return {} if self.options is None else self.options.model_dump()
