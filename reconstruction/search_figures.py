"""The search's own figures (crashlab reconstruct): objectives.png, every feasible evaluation's first two
objectives with the non-dominated ones, and near_optimal.png, the starts that explain the evidence equally well;
in the shown units (crashlab.units). The top views and time histories: crashlab.tools.plotting."""
from __future__ import annotations

import numpy as np

from crashlab.units import unit_in, value_in

from .problem import evaluation_counts, infeasible_sentence, objective_unit, variable_unit


def objectives_figure(problem, arch, pareto, path, plt, system: str = "si") -> str | None:
    """Every feasible evaluation's first two objectives (grey) and the non-dominated ones (red); log axes where
    every value shown is positive, else linear (a perfect fit has objective 0, which no log axis shows).
    Returns why it is not drawn (no feasible evaluation), or None."""
    names = list(problem.objective_names)
    feas = np.all(arch["G"] <= 0, axis=1) & arch["ok"] if len(arch["X"]) else np.zeros(0, bool)
    unit = objective_unit(problem)
    F = value_in(arch["F"][feas] if feas.any() else np.empty((0, len(names))), unit, system)
    if not len(F):
        return "no feasible evaluation to draw: " + infeasible_sentence(evaluation_counts(problem, arch))
    fig, ax = plt.subplots(figsize=(6, 5))
    ax.scatter(F[:, 0], F[:, 1], s=6, color="0.6", label="dominated / evaluated")
    if len(pareto):
        ax.scatter(value_in(pareto[f"f_{names[0]}"], unit, system), value_in(pareto[f"f_{names[1]}"], unit, system),
                   s=24, color="C3", label="non-dominated")
    shown = F[:, :2][np.isfinite(F[:, :2]).all(axis=1)]
    log = len(shown) > 0 and bool(np.all(shown > 0))
    if log:
        ax.set_xscale("log")
        ax.set_yscale("log")
    ax.set_xlabel(f"f_{names[0]} [{unit_in(unit, system)}]" + ("" if log else " (linear: an objective is 0)"))
    ax.set_ylabel(f"f_{names[1]} [{unit_in(unit, system)}]")
    ax.legend()
    ax.grid(alpha=0.3, which="both")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    return None


def near_optimal_figure(problem, near, path, plt, system: str = "si") -> str:
    """The first two free variables of the near-optimal starts (with their units), coloured by their largest
    objective (m, or sigma for the normalised misfit); in US units with system "us"."""
    fa, fb = problem.free[0], problem.free[1]
    a, b = fa.label, fb.label
    ua, ub, uf = variable_unit(fa), variable_unit(fb), objective_unit(problem)
    worst = value_in(near[[c for c in near.columns if c.startswith("f_")]].max(axis=1), uf, system)
    fig, ax = plt.subplots(figsize=(6, 5))
    sc = ax.scatter(value_in(near[a], ua, system), value_in(near[b], ub, system), c=worst, s=12, cmap="viridis")
    fig.colorbar(sc, ax=ax, label=f"largest objective [{unit_in(uf, system)}]")
    ax.set_xlabel(f"{a} [{unit_in(ua, system)}]")
    ax.set_ylabel(f"{b} [{unit_in(ub, system)}]")
    ax.set_title("starts that explain the evidence equally well")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    return path.name
