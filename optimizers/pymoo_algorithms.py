"""pymoo's multi-objective algorithms behind one factory, looked up by name.

``make_algorithm(name, **options)`` builds ``NSGA2``, ``NSGA3``, ``MOEAD``, ``SMSEMOA`` or
``AGEMOEA``; the module-level names ``nsga2``, ``nsga3``, ``moead``, ``sms_emoa`` and ``age_moea``
are partials of it (these are the ``crashlab.optimizers`` entry points).

Options common to all of them (keywords only):

pop_size        population size (pymoo's default if omitted). For MOEA/D the population size is
                the number of reference directions.
repair          pymoo Repair handed to the algorithm.
eta_c, crossover_prob
                build ``SBX(eta=eta_c, prob=crossover_prob)`` (cannot be combined with ``crossover=``).
eta_m, mutation_prob_var
                build ``PM(eta=eta_m, prob_var=mutation_prob_var)`` (cannot be combined with ``mutation=``).
any other keyword the pymoo class or its base classes accept (``sampling``, ``eliminate_duplicates``,
``seed``, ``termination``, ``n_neighbors``, ...).

Conventions a caller (crashlab.reconstruction) reads, and a plugin optimizer may follow: a factory
with ``takes_n_obj = True`` is given the objective count as ``n_obj``; an algorithm with
``handles_constraints = False`` (pymoo's MOEA/D) is given an unconstrained problem whose objectives
carry the constraint violation as a penalty.

NSGA-III and MOEA/D also take ``n_obj`` (default 2) and ``ref_dirs``. Without ``ref_dirs`` the
directions are pymoo's Das-Dennis directions with the largest number of partitions whose
direction count does not exceed ``pop_size`` (100 if omitted); for two objectives that is exactly
``pop_size`` directions. Unknown keywords raise ``TypeError``.

Every algorithm built here pickles (a reconstruction's checkpoint after each generation): pymoo 0.6.2
wraps some module-level functions in a closure (``pymoo.util.default_random_state``), e.g. the
tournament comparison of NSGA-III and SMS-EMOA, which pickle cannot store; they are replaced by a
reference to the module attribute (``ModuleFunction``), which pickles by name. MOEA/D evaluates its
offspring one at a time through a generator, which pickles only between generations (when it is None),
so a caller checkpoints MOEA/D at generation boundaries.

Reproducible from the seed. Every random draw comes from the algorithm's ``random_state`` (seeded by
``setup(seed=...)``, pickled with a checkpoint). pymoo 0.6.2's NSGA-III tournament
(``nsga3.comp_by_cv_then_random``) breaks a tie of two equally infeasible candidates with ``compare(...,
return_random_if_equal=True)`` without passing its random state on, so ``compare`` draws from a fresh unseeded
generator: with many equal violations (a reconstruction's candidates without an impact all have G = 1) two
runs with one seed diverged from the first offspring on (issue 27). NSGA-III is built here with
``comp_by_cv_then_random`` below, the same rule drawing from the algorithm's random state.

pymoo is imported only when a factory is called, so loading the entry points is cheap.
"""

from __future__ import annotations

import importlib
from functools import partial
from math import comb

from ._options import init_parameter_names, reject_unknown_options

# name -> (module, class, uses reference directions, handles constraints)
ALGORITHMS: dict[str, tuple[str, str, bool, bool]] = {
    "nsga2": ("pymoo.algorithms.moo.nsga2", "NSGA2", False, True),
    "nsga3": ("pymoo.algorithms.moo.nsga3", "NSGA3", True, True),
    "moead": ("pymoo.algorithms.moo.moead", "MOEAD", True, False),  # pymoo asserts an unconstrained problem
    "sms-emoa": ("pymoo.algorithms.moo.sms", "SMSEMOA", False, True),
    "age-moea": ("pymoo.algorithms.moo.age", "AGEMOEA", False, True),
}

DEFAULT_N_OBJ = 2
DEFAULT_REF_DIR_BUDGET = 100
_OPERATOR_OPTIONS = {"eta_c", "crossover_prob", "eta_m", "mutation_prob_var"}
_NOT_OPTIONS = {"kwargs"}


class ModuleFunction:
    """A module-level function held by its import path: pickles by name, calls the function."""

    def __init__(self, module: str, name: str):
        self.module, self.name = module, name
        self._fn = None

    def __call__(self, *args, **kwargs):
        if self._fn is None:
            self._fn = getattr(importlib.import_module(self.module), self.name)
        return self._fn(*args, **kwargs)

    def __getstate__(self):
        return {"module": self.module, "name": self.name, "_fn": None}

    def __repr__(self):
        return f"ModuleFunction({self.module}.{self.name})"


def by_name(fn):
    """``fn`` if it pickles, else a ModuleFunction for the module attribute that a closure-wrapped
    function (pymoo's default_random_state) stands for; ``fn`` itself when no such attribute is found."""
    import pickle
    try:
        pickle.dumps(fn)
        return fn
    except Exception:  # noqa: BLE001 - find the module attribute it stands for
        pass
    for cell in getattr(fn, "__closure__", None) or ():
        inner = cell.cell_contents
        module, name = getattr(inner, "__module__", None), getattr(inner, "__qualname__", "")
        if callable(inner) and module and "<locals>" not in name:
            try:
                if getattr(importlib.import_module(module), name) is fn:
                    return ModuleFunction(module, name)
            except (ImportError, AttributeError):
                continue
    return fn


def make_picklable(algorithm):
    """Replace closure-wrapped comparison functions of the algorithm's selection operators (in place)."""
    mating = getattr(algorithm, "mating", None)
    for holder in (getattr(algorithm, "selection", None), getattr(mating, "selection", None)):
        if holder is not None and callable(getattr(holder, "func_comp", None)):
            holder.func_comp = by_name(holder.func_comp)
    return algorithm


def comp_by_cv_then_random(pop, P, random_state=None, **kwargs):
    """NSGA-III's binary tournament (pymoo's rule): the smaller constraint violation wins, a tie or two
    feasible candidates are decided at random, by ``random_state``, the algorithm's seeded generator."""
    import numpy as np

    S = np.empty(len(P), dtype=int)
    for i, (a, b) in enumerate(P):
        cv_a, cv_b = pop[a].CV[0], pop[b].CV[0]
        if (cv_a > 0.0 or cv_b > 0.0) and cv_a != cv_b:
            S[i] = a if cv_a < cv_b else b
        else:
            S[i] = random_state.choice([a, b])
    return S[:, None]


def _seeded_defaults(name: str, options: dict) -> None:
    """Operators replacing pymoo defaults that draw from an unseeded generator (module docstring)."""
    if name == "nsga3" and "selection" not in options:
        from pymoo.operators.selection.tournament import TournamentSelection

        options["selection"] = TournamentSelection(func_comp=comp_by_cv_then_random)


def algorithm_class(name: str) -> type:
    """The pymoo class registered under ``name``."""
    try:
        module, cls = ALGORITHMS[name][:2]
    except KeyError:
        raise ValueError(f"unknown pymoo algorithm {name!r}; known: {', '.join(ALGORITHMS)}") from None
    return getattr(importlib.import_module(module), cls)


def das_dennis_partitions(n_obj: int, max_directions: int) -> int:
    """Largest number of partitions p with C(p + n_obj - 1, n_obj - 1) <= max_directions (at least 1)."""
    if n_obj < 1:
        raise ValueError(f"n_obj must be >= 1, got {n_obj}")
    p = 1
    while comb(p + 1 + n_obj - 1, n_obj - 1) <= max_directions:
        p += 1
        if n_obj == 1:
            break
    return p


def reference_directions(n_obj: int, max_directions: int):
    """Das-Dennis reference directions, as many as possible but no more than ``max_directions``."""
    from pymoo.util.ref_dirs import get_reference_directions

    return get_reference_directions(
        "das-dennis", n_obj, n_partitions=das_dennis_partitions(n_obj, max_directions)
    )


def _operators(options: dict) -> dict:
    """Turn the SBX / PM shorthand options into pymoo operator objects."""
    out = {}
    cross = {k: options.pop(k) for k in ("eta_c", "crossover_prob") if k in options}
    mut = {k: options.pop(k) for k in ("eta_m", "mutation_prob_var") if k in options}
    if cross:
        if "crossover" in options:
            raise TypeError("give either crossover= or eta_c/crossover_prob, not both")
        from pymoo.operators.crossover.sbx import SBX

        sbx = {"eta": cross.get("eta_c", 15)}
        if "crossover_prob" in cross:
            sbx["prob"] = cross["crossover_prob"]
        out["crossover"] = SBX(**sbx)
    if mut:
        if "mutation" in options:
            raise TypeError("give either mutation= or eta_m/mutation_prob_var, not both")
        from pymoo.operators.mutation.pm import PM

        out["mutation"] = PM(eta=mut.get("eta_m", 20), prob_var=mut.get("mutation_prob_var"))
    return out


def make_algorithm(name: str, /, **options):
    """Build the pymoo algorithm ``name`` (a key of ``ALGORITHMS``) from keyword options."""
    cls = algorithm_class(name)
    uses_ref_dirs = ALGORITHMS[name][2]
    allowed = (init_parameter_names(cls) - _NOT_OPTIONS) | _OPERATOR_OPTIONS | {"pop_size", "repair"}
    if uses_ref_dirs:
        allowed |= {"n_obj", "ref_dirs"}
    reject_unknown_options(name, options, allowed)

    options = dict(options)
    options.update(_operators(options))
    if uses_ref_dirs:
        _set_reference_directions(name, options)
    _seeded_defaults(name, options)
    algorithm = make_picklable(cls(**options))
    algorithm.handles_constraints = ALGORITHMS[name][3]
    return algorithm


def _set_reference_directions(name: str, options: dict) -> None:
    """Fill ``options["ref_dirs"]`` from ``n_obj``/``pop_size`` and check they agree."""
    n_obj = options.pop("n_obj", None)
    if name == "moead" and n_obj is not None and n_obj < 2:
        raise ValueError(f"MOEA/D decomposes two or more objectives; this problem has {n_obj}")
    pop_size = options.get("pop_size")
    ref_dirs = options.get("ref_dirs")
    if ref_dirs is None:
        ref_dirs = reference_directions(
            DEFAULT_N_OBJ if n_obj is None else int(n_obj),
            DEFAULT_REF_DIR_BUDGET if pop_size is None else int(pop_size),
        )
        options["ref_dirs"] = ref_dirs
    else:
        if n_obj is not None and ref_dirs.shape[1] != n_obj:
            raise ValueError(f"ref_dirs have {ref_dirs.shape[1]} objectives but n_obj={n_obj}")
        if name == "moead" and pop_size is not None and pop_size != len(ref_dirs):
            raise ValueError(
                f"MOEA/D uses one individual per reference direction: pop_size={pop_size} "
                f"but {len(ref_dirs)} ref_dirs were given"
            )
    if name == "moead":
        # pymoo's MOEAD takes no pop_size: it is len(ref_dirs), chosen above from pop_size
        options.pop("pop_size", None)


def _factory(name: str):
    f = partial(make_algorithm, name)
    f.__doc__ = f"Build pymoo's {ALGORITHMS[name][1]} from keyword options (see crashlab.optimizers.pymoo_algorithms)."
    f.takes_n_obj = ALGORITHMS[name][2]  # its reference directions need the objective count
    return f


nsga2 = _factory("nsga2")
nsga3 = _factory("nsga3")
moead = _factory("moead")
sms_emoa = _factory("sms-emoa")
age_moea = _factory("age-moea")
