"""Evaluations in this process: every variant or scene ends with a result or the reason it failed.

The work is either `Variants` (one scene, fields and a block of rows: the model's `simulate_population`,
crashlab.population) or a list of Scenes (the model's `simulate_batch`); both give a Population.
"""
from __future__ import annotations

import numpy as np

from ..model import simulate_each
from ..population import Population, Variants, exception_reason, one_line
from .models import model_instance


def _n_scores(scorer) -> int:
    return 0 if scorer is None else int(scorer.n_residuals)


def names_of(work) -> tuple:
    """The vehicle names of a work unit (Variants or a list of Scenes)."""
    scene = work.scene if isinstance(work, Variants) else work[0]
    return tuple(scene.vehicle_names)


def empty_population(work, reason: str = "not evaluated", scorer=None) -> Population:
    return Population.empty(len(work), names_of(work), reason, _n_scores(scorer))


def _vectorised(model) -> bool:
    """Whether the model evaluates a block in one call of its own (then a block is timed as a whole): its own
    simulate_batch or simulate_population."""
    from ..model import CollisionModel
    return any(getattr(type(model), m, None) is not getattr(CollisionModel, m)
               for m in ("simulate_batch", "simulate_population"))


def _single_thread():
    try:
        import numba
        numba.set_num_threads(1)
    except Exception:  # noqa: BLE001 - numba is optional for foreign models
        pass


def evaluate_in_process(model_name: str, options_items: tuple, work, single_thread: bool = False,
                        scorer=None) -> Population:
    """Simulate a work unit (Variants or a list of Scenes) in this process. A simulation that raises or fails
    is recorded with its reason, never propagated: when a block raises, its rows are simulated one by one so a
    bad one fails alone. scorer: scores each row where it was simulated (crashlab.execution)."""
    if single_thread:
        _single_thread()
    try:
        model = model_instance(model_name, options_items)
    except Exception as err:  # noqa: BLE001
        return empty_population(work, one_line(f"model could not be built: {type(err).__name__}: {err}"), scorer)
    if isinstance(work, Variants) and hasattr(model, "simulate_population"):
        return evaluate_variants(model, work, scorer)
    if isinstance(work, Variants):  # a duck-typed model (no CollisionModel): a scene per row
        work = work.scenes()
    batch = scorer is None or not scorer.needs_trajectory
    masses = np.array([[v.spec.mass for v in s.vehicles] for s in work])
    return Population.of_outcomes(simulate_each(model, work, batch=batch), names_of(work), masses, scorer)


def evaluate_variants(model, work: Variants, scorer=None) -> Population:
    """The Population of Variants with a model instance; a block that raises is run row by row, so a bad row
    fails alone with the exception as its reason."""
    try:
        pops = [work.simulate(model)]
    except Exception:  # noqa: BLE001 - row by row, so one bad row fails alone
        pops = []
        for k in range(len(work)):
            try:
                pops.append(work[k:k + 1].simulate(model))
            except Exception as err:  # noqa: BLE001
                pop = empty_population(work[k:k + 1], exception_reason(err))
                pops.append(pop)
    pop = pops[0] if len(pops) == 1 else Population.concat(pops)
    if scorer is not None:
        pop.score(_n_scores(scorer), lambda: scorer.population_residuals(pop))
    return pop
