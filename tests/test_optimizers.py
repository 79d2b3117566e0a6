"""Tests of crashlab.optimizers: NSGA with sharing (Srinivas & Deb 1994) and the pymoo adapters."""

from __future__ import annotations

import importlib
import itertools
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pymoo.core.algorithm import Algorithm
from pymoo.core.repair import Repair
from pymoo.indicators.hv import HV
from pymoo.optimize import minimize
from pymoo.problems import get_problem
from pymoo.util.nds.non_dominated_sorting import NonDominatedSorting

from crashlab.optimizers import pymoo_algorithms
from crashlab.optimizers.nsga_sharing import NSGASharing, generation_budget, mutation_active
from crashlab.optimizers.polynomial_mutation import (
    DebDebPolynomialMutation,
    deb_deb_displacement,
    deb_deb_polynomial_mutation,
)
from crashlab.optimizers.selection import (
    SharedFitnessSelection,
    pair_without_selfing,
    roulette_select,
    selection_probabilities,
    stochastic_remainder_select,
)
from crashlab.optimizers.sharing import (
    constrained_fronts,
    deb_sigma_share,
    niche_counts,
    normalise_decision_space,
    pairwise_distances,
    shared_dummy_fitness,
    sharing_function,
)

PYPROJECT = Path(__file__).resolve().parents[1] / "pyproject.toml"
FACTORY_NAMES = ["nsga2", "nsga3", "moead", "sms_emoa", "age_moea"]

# hand-made front: pairwise distances d01 = 0.1, d12 = 0.4, d02 = 0.5
THREE_POINTS = np.array([[0.0, 0.0], [0.06, 0.08], [0.30, 0.40]])


def rng(seed=0):
    return np.random.default_rng(seed)


# --------------------------------------------------------------------------- sharing


def test_sharing_function_values():
    sigma = 0.4
    assert sharing_function(0.0, sigma) == pytest.approx(1.0)
    assert sharing_function(sigma / 2, sigma) == pytest.approx(0.75)  # 1 - (1/2)^2
    assert sharing_function(sigma / 2, sigma, alpha=1.0) == pytest.approx(0.5)
    assert sharing_function(sigma, sigma) == 0.0
    np.testing.assert_array_equal(sharing_function([sigma, 1.5 * sigma, 10.0], sigma), 0.0)


@given(st.floats(0.0, 10.0), st.floats(0.01, 5.0), st.floats(0.5, 4.0))
def test_sharing_function_in_unit_interval(d, sigma, alpha):
    assert 0.0 <= sharing_function(d, sigma, alpha) <= 1.0


def test_deb_sigma_share_rule():
    assert deb_sigma_share(5, 10) == pytest.approx(0.5 / 10 ** (1 / 5))
    assert deb_sigma_share(5, 10) == pytest.approx(0.315, abs=5e-4)  # docs/physics.md §22, example
    assert deb_sigma_share(8, 20) == pytest.approx(0.344, abs=5e-4)


def test_pairwise_distances_of_hand_made_front():
    D = pairwise_distances(THREE_POINTS)
    np.testing.assert_allclose(D, [[0, 0.1, 0.5], [0.1, 0, 0.4], [0.5, 0.4, 0]], atol=1e-12)


def test_niche_counts_on_three_point_front():
    m = niche_counts(pairwise_distances(THREE_POINTS), sigma_share=0.5)
    # Sh(0) = 1 (self), Sh(0.1) = 1 - 0.04 = 0.96, Sh(0.4) = 1 - 0.64 = 0.36, Sh(0.5) = 0
    np.testing.assert_allclose(m, [1.96, 2.32, 1.36])


def test_normalised_decision_space_uses_bounds():
    X = THREE_POINTS * [10.0, 100.0] + [5.0, -50.0]
    Xn = normalise_decision_space(X, xl=[5.0, -50.0], xu=[15.0, 50.0])
    np.testing.assert_allclose(Xn, THREE_POINTS, atol=1e-12)
    # unbounded or degenerate variables fall back to the population's spread
    Xn = normalise_decision_space([[1.0, 3.0], [3.0, 3.0]], xl=[-np.inf, 3.0], xu=[np.inf, 3.0])
    np.testing.assert_allclose(Xn, [[0.0, 0.0], [1.0, 0.0]])


def test_constrained_fronts_feasible_first_then_by_violation():
    F = np.array([[1.0, 1.0], [0.0, 2.0], [2.0, 2.0], [0.0, 0.0], [5.0, 5.0], [3.0, 3.0]])
    CV = np.array([0.0, 0.0, 0.0, 2.0, 0.5, 2.0])
    fronts = [sorted(f.tolist()) for f in constrained_fronts(F, CV)]
    assert fronts == [[0, 1], [2], [4], [3, 5]]


def test_dummy_fitness_front_by_front():
    N = 5
    # front 1: the hand-made three points; front 2: two more points 0.1 apart
    X = np.vstack([THREE_POINTS, [[0.9, 0.9], [0.9, 1.0]]])
    fronts = [np.array([0, 1, 2]), np.array([3, 4])]
    eps = 0.01
    fit = shared_dummy_fitness(X, fronts, sigma_share=0.5, epsilon=eps)
    np.testing.assert_allclose(fit[:3], N / np.array([1.96, 2.32, 1.36]))
    f_d2 = (1 - eps) * fit[:3].min()
    np.testing.assert_allclose(fit[3:], f_d2 / 1.96)
    assert fit[3:].max() < fit[:3].min()


def test_dummy_fitness_isolated_first_front_is_population_size():
    X = rng(1).random((40, 3)) * 10.0  # far apart compared with sigma
    F = rng(2).random((40, 2))
    fronts = constrained_fronts(F)
    fit = shared_dummy_fitness(X, fronts, sigma_share=0.01)
    np.testing.assert_allclose(fit[fronts[0]], 40.0)


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 10_000), st.integers(3, 60), st.floats(0.05, 2.0))
def test_each_front_strictly_below_the_previous(seed, n, sigma):
    g = rng(seed)
    X, F = g.random((n, 4)), g.random((n, 2))
    fronts = constrained_fronts(F)
    fit = shared_dummy_fitness(X, fronts, sigma_share=sigma)
    assert fit[fronts[0]].max() <= n
    for better, worse in itertools.pairwise(fronts):
        assert fit[worse].max() < fit[better].min()


# --------------------------------------------------------------------------- selection


def test_roulette_frequencies_proportional_to_fitness():
    fitness = np.array([1.0, 2.0, 3.0, 4.0, 0.0])
    n = 200_000
    counts = np.bincount(roulette_select(fitness, n, rng(3)), minlength=5)
    p = fitness / fitness.sum()
    tol = 5 * np.sqrt(p * (1 - p) / n) + 1e-12  # five binomial standard deviations
    np.testing.assert_array_less(np.abs(counts / n - p), tol)
    assert counts[4] == 0


def test_selection_probabilities_reject_bad_fitness():
    for bad in ([0.0, 0.0], [1.0, -1.0], [1.0, np.nan]):
        with pytest.raises(ValueError):
            selection_probabilities(bad)


def test_stochastic_remainder_guaranteed_copies():
    fitness = np.array([5.0, 3.0, 1.5, 0.5])  # N p_i = 5, 3, 1.5, 0.5 for N = 10
    floors = np.array([5, 3, 1, 0])
    extra = np.zeros(4)
    n_trials = 4000
    g = rng(4)
    for _ in range(n_trials):
        counts = np.bincount(stochastic_remainder_select(fitness, 10, g), minlength=4)
        assert counts.sum() == 10
        assert np.all(counts >= floors)
        extra += counts - floors
    # the one remaining slot goes by roulette on the fractions 0, 0, 0.5, 0.5
    np.testing.assert_allclose(extra / n_trials, [0, 0, 0.5, 0.5], atol=0.04)


def test_pair_without_selfing_repairs_self_pairs():
    pool = np.array([0, 0, 1, 2, 0, 0, 3, 3])
    pairs = pair_without_selfing(pool, rng(5))
    assert pairs.shape == (4, 2)
    assert np.all(pairs[:, 0] != pairs[:, 1])
    assert sorted(pairs.ravel()) == sorted(pool)  # swaps only, nobody lost


def test_pair_without_selfing_when_one_individual_fills_the_pool():
    pairs = pair_without_selfing(np.zeros(6, dtype=int), rng(6), fitness=[10.0, 1.0, 1.0])
    assert np.all(pairs[:, 0] == 0) and np.all(pairs[:, 1] != 0)


@settings(max_examples=50, deadline=None)
@given(st.lists(st.integers(0, 3), min_size=2, max_size=40).filter(lambda v: len(v) % 2 == 0))
def test_pair_without_selfing_never_self(pool):
    pairs = pair_without_selfing(np.array(pool), rng(7), fitness=np.ones(4))
    assert np.all(pairs[:, 0] != pairs[:, 1])


def test_shared_fitness_selection_has_no_self_mating():
    from pymoo.core.population import Population

    pop = Population.new("X", np.zeros((6, 2)))
    pop.set("shared_fitness", np.array([1000.0, 1.0, 1.0, 1.0, 1.0, 1.0]))
    for method in ("roulette", "stochastic-remainder"):
        pairs = SharedFitnessSelection(method).do(None, pop, 500, 2, to_pop=False, random_state=rng(8))
        assert pairs.shape == (500, 2)
        assert np.all(pairs[:, 0] != pairs[:, 1])
        assert np.mean(pairs == 0) > 0.45  # the dominant individual is still in almost every pair


# --------------------------------------------------------------------------- mutation


def test_deb_deb_displacement_end_points():
    y, xl, xu, eta = 0.3, 0.0, 1.0, 20.0
    assert deb_deb_displacement(y, xl, xu, 0.0, eta) == pytest.approx(-(y - xl))  # reaches x_l
    assert deb_deb_displacement(y, xl, xu, 1.0, eta) == pytest.approx(xu - y)  # reaches x_u
    assert deb_deb_displacement(y, xl, xu, 0.5, eta) == pytest.approx(0.0)
    u = 0.25
    assert deb_deb_displacement(y, xl, xu, u, eta) == pytest.approx(((2 * u) ** (1 / 21) - 1) * y)


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 10_000), st.floats(0.0, 100.0))
def test_deb_deb_mutation_stays_in_bounds(seed, eta):
    g = rng(seed)
    xl, xu = np.array([-1.0, 0.0, 10.0]), np.array([1.0, 1e-3, 20.0])
    X = xl + g.random((50, 3)) * (xu - xl)
    X[:5] = xl
    X[5:10] = xu
    Y = deb_deb_polynomial_mutation(X, xl, xu, eta, 1.0, g)
    assert np.all(Y >= xl) and np.all(Y <= xu)


@pytest.mark.parametrize("y, sign", [(0.01, +1), (0.99, -1)])
def test_deb_deb_mean_displacement_points_away_from_near_bound(y, sign):
    eta, n = 20.0, 400_000
    Y = deb_deb_polynomial_mutation(np.full((n, 1), y), [0.0], [1.0], eta, 1.0, rng(9))
    mean = (Y - y).mean()
    expected = ((1.0 - y) - (y - 0.0)) / (2 * (eta + 2))  # analytic mean of the first form
    assert np.sign(mean) == sign
    assert mean == pytest.approx(expected, rel=0.03)


def test_deb_deb_mutation_per_variable_probability():
    X = np.full((2000, 10), 0.5)
    Y = deb_deb_polynomial_mutation(X, np.zeros(10), np.ones(10), 20.0, 0.1, rng(10))
    assert np.mean(Y != X) == pytest.approx(0.1, abs=0.01)
    np.testing.assert_array_equal(deb_deb_polynomial_mutation(X, 0.0, 1.0, 20.0, 0.0, rng(10)), X)
    assert DebDebPolynomialMutation().variable_probability(30) == pytest.approx(1 / 30)


# --------------------------------------------------------------------------- NSGASharing


class SpyMutation(DebDebPolynomialMutation):
    """Records the generation (algorithm.n_iter) whenever it is applied."""

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.generations = []

    def do(self, problem, pop, *args, algorithm=None, **kwargs):
        self.generations.append(algorithm.n_iter)
        return super().do(problem, pop, *args, algorithm=algorithm, **kwargs)


@pytest.mark.parametrize("how", ["termination", "n_gen option", "n_eval"])
def test_no_mutation_in_final_four_generations(how):
    problem = get_problem("zdt1", n_var=5)
    algorithm = NSGASharing(pop_size=10, n_gen=12 if how == "n_gen option" else None)
    algorithm.mutation = SpyMutation()
    termination = {"termination": ("n_gen", 12), "n_gen option": None, "n_eval": ("n_eval", 120)}[how]
    res = minimize(problem, algorithm, termination, seed=1)
    assert res.algorithm.total_generations == 12
    # generation 1 is the initial population; offspring generations 2..12, of which 9..12 unmutated
    assert res.algorithm.mutation.generations == list(range(2, 9))


def test_tail_offspring_are_pure_crossover():
    problem = get_problem("zdt1", n_var=5)
    algorithm = NSGASharing(pop_size=10, crossover_prob=0.0, no_mutation_tail=2, n_gen=6)
    algorithm.setup(problem, seed=3)
    generations = []
    while algorithm.has_next():
        parents = algorithm.pop
        off = algorithm.ask()
        if parents is not None and len(parents):
            # with no crossover every child is a copy of a parent unless it was mutated
            P = parents.get("X")
            copies = np.array([np.any(np.all(P == x, axis=1)) for x in off.get("X")])
            generations.append((algorithm.n_iter, bool(copies.all())))
        algorithm.evaluator.eval(problem, off, algorithm=algorithm)
        algorithm.tell(infills=off)
    assert generations[-2:] == [(5, True), (6, True)]
    assert not any(all_copies for _, all_copies in generations[:-2])


def test_mutation_active_rule():
    assert [mutation_active(g, 200, 4) for g in (196, 197, 200)] == [True, False, False]
    assert mutation_active(500, None, 4)


def test_generation_budget_reads_termination():
    from pymoo.termination import get_termination
    from pymoo.termination.default import DefaultMultiObjectiveTermination

    assert generation_budget(get_termination("n_gen", 200), 100) == 200
    assert generation_budget(get_termination("n_eval", 20_000), 100) == 200
    assert generation_budget(DefaultMultiObjectiveTermination(n_max_gen=300), 100) == 300
    assert generation_budget(get_termination("time", "00:01:00"), 100) is None


def test_no_elitism_offspring_replace_parents():
    problem = get_problem("zdt1", n_var=5)
    algorithm = NSGASharing(pop_size=12, n_gen=5)
    algorithm.setup(problem, seed=2)
    for _ in range(2):
        off = algorithm.ask()
        algorithm.evaluator.eval(problem, off, algorithm=algorithm)
        algorithm.tell(infills=off)
        assert algorithm.pop is off
        np.testing.assert_array_equal(algorithm.pop.get("X"), off.get("X"))
        assert np.all(np.isfinite(algorithm.pop.get("shared_fitness")))


def test_sigma_share_default_and_explicit():
    problem = get_problem("zdt1", n_var=30)
    algorithm = NSGASharing()
    assert algorithm.sigma_share is None
    algorithm.setup(problem, termination=("n_gen", 3))
    assert algorithm.sigma_share == pytest.approx(0.5 / 10 ** (1 / 30))
    algorithm = NSGASharing(n_optima=20).setup(problem, termination=("n_gen", 3))
    assert algorithm.sigma_share == pytest.approx(0.5 / 20 ** (1 / 30))
    assert NSGASharing(sigma_share=0.3).setup(problem).sigma_share == 0.3


def test_nsga_sharing_handles_constraints_and_repair():
    class CountingRepair(Repair):
        calls = 0

        def _do(self, problem, X, **kwargs):
            type(self).calls += 1
            return X

    problem = get_problem("tnk")
    res = minimize(problem, NSGASharing(pop_size=20, repair=CountingRepair()), ("n_gen", 15), seed=1)
    assert CountingRepair.calls >= 15
    fronts = constrained_fronts(res.pop.get("F"), res.pop.get("CV"))
    fit = res.pop.get("shared_fitness")
    cv = res.pop.get("CV")[:, 0]
    if np.any(cv > 0) and np.any(cv <= 0):
        assert fit[cv > 0].max() < fit[cv <= 0].min()
    assert len(fronts) >= 1


def test_nsga_sharing_options_are_checked():
    with pytest.raises(TypeError, match="bogus"):
        NSGASharing(pop_size=10, bogus=1)
    with pytest.raises(ValueError):
        NSGASharing(selection="tournament")
    with pytest.raises(ValueError):
        NSGASharing(epsilon=0.0)
    assert isinstance(NSGASharing(pop_size=10, seed=None, selection="stochastic-remainder"), Algorithm)


# --------------------------------------------------------------------------- pymoo adapters


@pytest.mark.parametrize("name", FACTORY_NAMES)
def test_factories_return_runnable_algorithms_with_repair(name):
    class Identity(Repair):
        def _do(self, problem, X, **kwargs):
            return X

    repair = Identity()
    algorithm = getattr(pymoo_algorithms, name)(pop_size=20, repair=repair)
    assert isinstance(algorithm, Algorithm)
    assert algorithm.repair is repair
    res = minimize(get_problem("zdt1", n_var=5), algorithm, ("n_gen", 3), seed=1)
    assert res.F is not None and res.F.shape[1] == 2


def _generation(algorithm):
    """One generation (MOEA/D: its loop-wise offspring until the generation's generator is done)."""
    algorithm.next()
    while getattr(algorithm, "generator", None) is not None:
        algorithm.next()


@pytest.mark.parametrize("name", FACTORY_NAMES + ["nsga_sharing"])
def test_algorithm_state_pickles_between_generations_and_continues_identically(name):
    """A reconstruction checkpoints the algorithm after every generation. Before: NSGA-III and SMS-EMOA
    held a closure (pymoo's default_random_state wrapper of their tournament comparison) and did not
    pickle. Pickled after generation 2 of 5 and continued: the same final population as without."""
    import pickle

    def build():
        algorithm = NSGASharing(pop_size=12) if name == "nsga_sharing" else getattr(pymoo_algorithms, name)(pop_size=12)
        algorithm.setup(get_problem("zdt1", n_var=4), termination=("n_gen", 5), seed=3, verbose=False)
        return algorithm

    whole = build()
    while whole.has_next():
        _generation(whole)
    cut = build()
    for _ in range(2):
        _generation(cut)
    cut = pickle.loads(pickle.dumps(cut))
    while cut.has_next():
        _generation(cut)
    np.testing.assert_array_equal(cut.pop.get("X"), whole.pop.get("X"))
    np.testing.assert_array_equal(cut.pop.get("F"), whole.pop.get("F"))


@pytest.mark.parametrize("name", FACTORY_NAMES)
def test_factories_reject_unknown_options(name):
    with pytest.raises(TypeError, match="not_an_option"):
        getattr(pymoo_algorithms, name)(pop_size=20, not_an_option=3)


def test_n_obj_only_for_reference_direction_algorithms():
    with pytest.raises(TypeError, match="n_obj"):
        pymoo_algorithms.nsga2(n_obj=2)


@pytest.mark.parametrize("name", ["nsga3", "moead"])
def test_reference_directions_sized_from_pop_size(name):
    factory = getattr(pymoo_algorithms, name)
    assert len(factory(pop_size=75).ref_dirs) == 75  # two objectives: p = 74 partitions
    three = factory(pop_size=100, n_obj=3).ref_dirs
    assert three.shape == (91, 3)  # p = 12 gives 91; p = 13 would give 105 > 100
    given_dirs = pymoo_algorithms.reference_directions(2, 10)
    assert factory(ref_dirs=given_dirs).ref_dirs is given_dirs
    assert factory(pop_size=30).pop_size in (30, None)


def test_moead_population_is_one_per_direction():
    assert pymoo_algorithms.moead(pop_size=40).pop_size == 40
    with pytest.raises(ValueError):
        pymoo_algorithms.moead(pop_size=40, ref_dirs=pymoo_algorithms.reference_directions(2, 10))


def test_operator_shorthands():
    algorithm = pymoo_algorithms.nsga2(eta_c=10, crossover_prob=0.8, eta_m=25, mutation_prob_var=0.1)
    assert algorithm.mating.crossover.eta.value == 10
    assert algorithm.mating.crossover.prob.value == 0.8
    assert algorithm.mating.mutation.eta.value == 25
    assert algorithm.mating.mutation.prob_var.value == 0.1


def test_entry_points_resolve_and_build():
    try:
        import tomllib
    except ModuleNotFoundError:  # Python 3.10
        tomllib = pytest.importorskip("tomli")
    entry_points = tomllib.loads(PYPROJECT.read_text())["project"]["entry-points"]["crashlab.optimizers"]
    assert set(entry_points) == {"nsga-sharing", "nsga2", "nsga3", "moead", "sms-emoa", "age-moea"}
    for target in entry_points.values():
        module, attr = target.split(":")
        factory = getattr(importlib.import_module(module), attr)
        assert isinstance(factory(pop_size=20, repair=None), Algorithm)


def test_package_import_does_not_import_pymoo():
    # crashlab itself is imported first so that only what the optimizers package adds is checked
    code = (
        "import sys, crashlab\n"
        "before = {m for m in sys.modules if m.split('.')[0] == 'pymoo'}\n"
        "import crashlab.optimizers, crashlab.optimizers.pymoo_algorithms\n"
        "added = {m for m in sys.modules if m.split('.')[0] == 'pymoo'} - before\n"
        "sys.exit(f'pymoo imported: {sorted(added)}' if added else 0)"
    )
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in sys.path if p))
    proc = subprocess.run([sys.executable, "-c", code], check=False, env=env, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr


# --------------------------------------------------------------------------- ZDT1 acceptance benchmark


def final_front_hypervolume(res) -> float:
    F = res.pop.get("F")
    front = NonDominatedSorting().do(F, only_non_dominated_front=True)
    return float(HV(ref_point=np.array([1.1, 1.1]))(F[front]))


@pytest.fixture(scope="module")
def zdt1():
    return get_problem("zdt1", n_var=30)


@pytest.fixture(scope="module")
def nsga_sharing_zdt1_hv(zdt1):
    return final_front_hypervolume(minimize(zdt1, NSGASharing(pop_size=100), ("n_gen", 200), seed=1))


def test_zdt1_nsga2_hypervolume(zdt1):
    res = minimize(zdt1, pymoo_algorithms.nsga2(pop_size=100), ("n_gen", 200), seed=1)
    assert final_front_hypervolume(res) >= 0.865  # measured 0.8679


def test_zdt1_nsga_sharing_hypervolume_target(nsga_sharing_zdt1_hv):
    # default settings (stochastic remainder, epsilon 0.8, SBX eta_c 5 on every variable,
    # crossover probability 1.0), non-dominated set of the final population: measured 0.8412 for
    # seed 1. The margin is thin: seeds 1-10 give mean 0.8407, min 0.8394, 8 of 10 >= 0.84.
    assert nsga_sharing_zdt1_hv >= 0.84


def test_zdt1_nsga_sharing_makes_progress(nsga_sharing_zdt1_hv):
    # the random initial population has HV 0 (all f2 > 1.1); the run must get onto the box
    assert nsga_sharing_zdt1_hv > 0.1
