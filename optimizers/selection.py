"""Fitness-proportionate selection for NSGA: roulette wheel and stochastic remainder.

docs/physics.md §22: ``p_i = f_i / sum f_j``; roulette draws ``r ~ U[0, 1)`` and takes the first
``i`` whose cumulative probability exceeds ``r``; stochastic remainder first gives every
individual ``floor(N p_i)`` copies and fills the rest by roulette on the fractional parts.
Parents are then paired so that no individual mates with itself.
"""

from __future__ import annotations

import numpy as np
from pymoo.core.selection import Selection

SELECTION_METHODS = ("roulette", "stochastic-remainder")


def selection_probabilities(fitness):
    """``p_i = f_i / sum_j f_j`` for non-negative, not all zero, finite fitness values."""
    fitness = np.asarray(fitness, dtype=float)
    if fitness.ndim != 1 or len(fitness) == 0:
        raise ValueError("fitness must be a non-empty 1-D array")
    if not np.all(np.isfinite(fitness)) or np.any(fitness < 0):
        raise ValueError("fitness must be finite and non-negative")
    total = fitness.sum()
    if total <= 0:
        raise ValueError("fitness must not be all zero")
    return fitness / total


def roulette_select(fitness, n_select: int, random_state):
    """``n_select`` indices drawn with replacement, each with probability ``p_i``."""
    cumulative = np.cumsum(selection_probabilities(fitness))
    r = random_state.random(n_select) * cumulative[-1]
    idx = np.searchsorted(cumulative, r, side="right")
    return np.minimum(idx, len(cumulative) - 1)


def stochastic_remainder_select(fitness, n_select: int, random_state):
    """``floor(n_select p_i)`` guaranteed copies of each ``i``, the rest by roulette on the fractions.

    The returned pool is shuffled.
    """
    expected = n_select * selection_probabilities(fitness)
    copies = np.floor(expected + 1e-9).astype(int)  # 1e-9: 2.9999999 expected copies are 3
    pool = np.repeat(np.arange(len(expected)), copies)
    n_rest = n_select - len(pool)
    if n_rest > 0:
        fractions = np.clip(expected - copies, 0.0, None)
        if fractions.sum() <= 0:
            fractions = expected
        pool = np.concatenate([pool, roulette_select(fractions, n_rest, random_state)])
    return random_state.permutation(pool[:n_select])


def pair_without_selfing(pool, random_state, fitness=None):
    """Pair consecutive entries of ``pool`` so that the two parents of a pair are different individuals.

    A pair ``(a, a)`` swaps its second parent with the first parent of another pair ``(c, d)``
    where ``c != a`` and ``d != a``; if no such pair exists the partner is redrawn by roulette
    among the other individuals (uniformly if ``fitness`` is None). Returns an (n, 2) array.
    """
    pairs = np.array(pool, dtype=int).reshape(-1, 2)
    n_individuals = int(pairs.max()) + 1 if fitness is None else len(fitness)
    if n_individuals < 2 and np.any(pairs[:, 0] == pairs[:, 1]):
        raise ValueError("cannot avoid self-mating with fewer than two individuals")
    for i in np.flatnonzero(pairs[:, 0] == pairs[:, 1]):
        a = pairs[i, 0]
        if pairs[i, 1] != a:  # already repaired as the partner pair of an earlier swap
            continue
        candidates = np.flatnonzero((pairs[:, 0] != a) & (pairs[:, 1] != a))
        if len(candidates):
            j = random_state.choice(candidates)
            pairs[i, 1], pairs[j, 0] = pairs[j, 0], a
        else:
            weights = np.ones(n_individuals) if fitness is None else np.array(fitness, dtype=float)
            weights[a] = 0.0
            if weights.sum() <= 0:
                weights = np.ones(n_individuals)
                weights[a] = 0.0
            pairs[i, 1] = roulette_select(weights, 1, random_state)[0]
    return pairs


SELECTORS = {"roulette": roulette_select, "stochastic-remainder": stochastic_remainder_select}


class SharedFitnessSelection(Selection):
    """pymoo ``Selection`` drawing mating pairs proportionately to the ``shared_fitness`` attribute."""

    def __init__(self, method: str = "roulette", fitness_key: str = "shared_fitness", **kwargs):
        super().__init__(**kwargs)
        if method not in SELECTORS:
            raise ValueError(f"selection must be one of {SELECTION_METHODS}, got {method!r}")
        self.method = method
        self.fitness_key = fitness_key

    def _do(self, problem, pop, n_select, n_parents, *args, random_state=None, **kwargs):
        if n_parents != 2:
            raise ValueError(f"SharedFitnessSelection pairs parents, got n_parents={n_parents}")
        fitness = np.asarray(pop.get(self.fitness_key), dtype=float)
        pool = SELECTORS[self.method](fitness, n_select * n_parents, random_state)
        return pair_without_selfing(pool, random_state, fitness)
