"""Deb & Deb (2012) bounded polynomial mutation (docs/physics.md §24).

For a variable ``y`` in ``[x_l, x_u]`` and ``u ~ U(0, 1)``::

    u <= 0.5:  delta_L = (2u)^(1/(1+eta)) - 1,       y' = y + delta_L (y - x_l)
    u >  0.5:  delta_R = 1 - (2(1-u))^(1/(1+eta)),   y' = y + delta_R (x_u - y)

The child stays in ``[x_l, x_u]`` by construction. The mean displacement is
``((x_u - y) - (y - x_l)) / (2 (eta + 2))``, so a variable near a bound is pushed away from it.
This differs from pymoo's ``PM``, which uses the NSGA-II-code form.
"""

from __future__ import annotations

import numpy as np
from pymoo.core.mutation import Mutation


def deb_deb_displacement(y, xl, xu, u, eta):
    """Displacement ``y' - y`` of the Deb & Deb mutation for uniform draws ``u`` (all broadcast)."""
    y, xl, xu, u = (np.asarray(a, dtype=float) for a in (y, xl, xu, u))
    power = 1.0 / (1.0 + eta)
    lower = u <= 0.5
    # clip the unused branch's argument so that no invalid power is evaluated
    delta_l = np.power(2.0 * np.minimum(u, 0.5), power) - 1.0
    delta_r = 1.0 - np.power(2.0 * (1.0 - np.maximum(u, 0.5)), power)
    return np.where(lower, delta_l * (y - xl), delta_r * (xu - y))


def deb_deb_polynomial_mutation(X, xl, xu, eta, prob_var, random_state):
    """Mutate each entry of ``X`` (n, n_var) with probability ``prob_var``; returns a new array."""
    X = np.asarray(X, dtype=float)
    xl = np.broadcast_to(np.asarray(xl, dtype=float), X.shape[-1:])
    xu = np.broadcast_to(np.asarray(xu, dtype=float), X.shape[-1:])
    mutate = random_state.random(X.shape) < prob_var
    mutate &= (xu > xl)[None, :]
    u = random_state.random(X.shape)
    Y = X + np.where(mutate, deb_deb_displacement(X, xl, xu, u, eta), 0.0)
    # floating-point guard only: the formula itself never leaves the box
    return np.clip(Y, xl, xu)


class DebDebPolynomialMutation(Mutation):
    """pymoo ``Mutation`` applying :func:`deb_deb_polynomial_mutation`.

    Parameters
    ----------
    eta:
        distribution index eta_m (default 20).
    prob_var:
        per-variable mutation probability; ``None`` means ``1 / n_var``.
    prob:
        probability that an individual is considered for mutation at all (default 1.0, so the
        per-variable probability alone decides, as in the classic real-coded GA).
    """

    def __init__(self, eta: float = 20.0, prob_var: float | None = None, prob: float = 1.0, **kwargs):
        super().__init__(prob=prob, prob_var=None, **kwargs)
        if eta < 0:
            raise ValueError(f"eta must be >= 0, got {eta}")
        if prob_var is not None and not 0.0 <= prob_var <= 1.0:
            raise ValueError(f"prob_var must be in [0, 1], got {prob_var}")
        self.eta = float(eta)
        self.per_variable_prob = prob_var

    def variable_probability(self, n_var: int) -> float:
        """Per-variable probability actually used for a problem with ``n_var`` variables."""
        return 1.0 / n_var if self.per_variable_prob is None else float(self.per_variable_prob)

    def _do(self, problem, X, *args, random_state=None, **kwargs):
        xl, xu = problem.bounds()
        return deb_deb_polynomial_mutation(
            X, xl, xu, self.eta, self.variable_probability(problem.n_var), random_state
        )
