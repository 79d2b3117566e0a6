"""Plugins found through entry points (groups `crashlab.models`, `crashlab.optimizers`), or named by a
"module:attribute" reference as an entry point is written (`load`).

Listing names reads only package metadata; a plugin's module is imported when it is asked for, so
exudyn or pymunk is imported only by a run that uses it. Unknown names get a "did you mean".
"""
from __future__ import annotations

import difflib
import functools
from importlib.metadata import entry_points

MODELS = "crashlab.models"
OPTIMIZERS = "crashlab.optimizers"


class UnknownPluginError(KeyError):
    def __init__(self, kind: str, name: str, known: list[str]):
        close = difflib.get_close_matches(name, known, n=1, cutoff=0.5)
        hint = f"did you mean {close[0]!r}?" if close else f"known: {', '.join(known)}"
        self.message = f"unknown {kind} {name!r}; {hint}"
        super().__init__(self.message)

    def __str__(self):
        return self.message


@functools.cache
def _entry_points(group: str) -> dict:
    """name -> entry point of a group, read once per process (reading package metadata costs about 2 ms,
    more than a simulation of the impulse model); `refresh()` reads them again."""
    return {ep.name: ep for ep in entry_points(group=group)}


@functools.cache
def _load(group: str, name: str):
    return _entry_points(group)[name].load()


def refresh() -> None:
    """Forget the entry points read so far (after installing a plugin into a running process)."""
    _entry_points.cache_clear()
    _load.cache_clear()


def names(group: str) -> list[str]:
    return sorted(_entry_points(group))


def load(group: str, name: str):
    """The plugin registered as `name`, or the object a reference "package.module:attribute" names (written as
    an entry point's value: a model or optimizer not installed as a plugin, e.g. one defined in a script or a
    test module that worker processes can import)."""
    if ":" in name:
        import importlib
        module, attr = name.split(":", 1)
        return getattr(importlib.import_module(module), attr)  # ImportError, AttributeError say why not
    eps = _entry_points(group)
    if name not in eps:
        kind = "model" if group == MODELS else "optimizer"
        raise UnknownPluginError(kind, name, sorted(eps))
    return _load(group, name)


def origins(group: str) -> dict[str, str]:
    """name -> "module:attribute" of each entry point of the group (without importing it): tells crashlab's
    own plugins (module crashlab.*) from third parties'."""
    return {name: ep.value for name, ep in _entry_points(group).items()}


def available_models() -> list[str]:
    return names(MODELS)


def available_optimizers() -> list[str]:
    return names(OPTIMIZERS)


def listed_models(text: str) -> list[str]:
    """The model names of a comma-separated list (a command line's --models), each once: ValueError for none or
    one named twice (its runs would be kept under one name, the second dropped)."""
    models = [m.strip() for m in text.split(",") if m.strip()]
    if not models:
        raise ValueError("give at least one model name")
    twice = next((m for i, m in enumerate(models) if m in models[:i]), None)
    if twice is not None:
        raise ValueError(f"model {twice!r} named twice in {text!r}; name each model once")
    return models


def get_model(name: str, **options):
    """A CollisionModel instance; options are the model's config keys. A plugin must derive from
    crashlab.CollisionModel: that is where the physics guard checks every Outcome."""
    from .model import CollisionModel
    model = load(MODELS, name)(**options)
    if not isinstance(model, CollisionModel):
        raise TypeError(f"model plugin {name!r} ({type(model).__name__}) does not derive from "
                        "crashlab.CollisionModel, so its results could not be checked")
    return model


def get_optimizer(name: str, **options):
    """A pymoo Algorithm, usable with pymoo.optimize.minimize."""
    return load(OPTIMIZERS, name)(**options)
