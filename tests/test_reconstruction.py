"""The reconstruction layer (README.md, study file and `crashlab reconstruct`): collision repair, the
objectives and failed evaluations, identical answers on every execution backend, resume after a kill,
bad study files, the output files, the least-squares polish, and (slow) the twin experiments. The
optimizers themselves are tested in test_optimizers.py."""
from __future__ import annotations

import json
import os
import pickle
import signal
import subprocess
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from conftest import assert_one_error_line

import crashlab
from crashlab.execution import evaluate as evaluation
from crashlab.reconstruction import FAILED_OBJECTIVE, ReconstructionProblem, load_study
from crashlab.reconstruction.polish import polish
from crashlab.reconstruction.repair import CollisionRepair, _least_separation, repair_poses

REPO = Path(__file__).resolve().parent.parent
STUDIES = REPO / "studies" / "reconstruction"
SIDE = REPO / "studies" / "pc_crash" / "side.toml"
POSITION_FIELDS = ("x", "y")


def cli(*args, timeout=300):
    return subprocess.run([sys.executable, "-m", "crashlab.cli", *map(str, args)], capture_output=True,
                          text=True, timeout=timeout)


def small_study(tmp_path, name="small.toml", pop_size=12, generations=3, **replace) -> Path:
    """twin1 (V1.speed, V2.speed free; evidence = the model's own simulation of side.toml) with a small
    budget and the scene path made absolute; `replace` swaps whole lines 'old' -> 'new'."""
    text = (STUDIES / "twin1.toml").read_text()
    text = text.replace('scene = "../pc_crash/side.toml"', f'scene = "{SIDE.as_posix()}"')
    text = text.replace("pop_size = 75", f"pop_size = {pop_size}")
    text = text.replace("generations = 20", f"generations = {generations}")
    for old, new in replace.values():
        assert old in text, old
        text = text.replace(old, new, 1)
    path = tmp_path / name
    path.write_text(text)
    return path


def truth_of(study) -> dict:
    """The base scene's start state in file units, per free variable label (twin truth)."""
    out = {}
    for f in study.spec.free:
        v = next(v for v in study.scene.vehicles if v.name == f.vehicle)
        out[f.label] = {"x": v.x, "y": v.y, "heading": np.degrees(v.heading), "speed": v.speed * 3.6}[f.field]
    return out


def wrap180(d):
    return (np.asarray(d) + 180.0) % 360.0 - 180.0


# ------------------------------------------------------------------ 1. repair
def _repair(problem, X, **kw):
    from pymoo.core.population import Population
    rep = CollisionRepair(**kw)
    return rep.do(problem, Population.new(X=X)).get("X"), rep


@pytest.mark.parametrize("twin", ["twin3", "twin5"])
def test_repair_separates_random_candidates_within_bounds(twin):
    problem = load_study(STUDIES / f"{twin}.toml").make_problem()
    assert problem.movable.all(), "both vehicles have free x and y"
    X = np.random.default_rng(7).uniform(problem.xl, problem.xu, (200, problem.n_var))
    Xr, rep = _repair(problem, X)

    # where the repair wanted the free positions (before clipping to the bounds)
    poses = problem.start_poses(X)
    changed = repair_poses(poses, problem.outline_dims, problem.movable, 1.0, 4.0).astype(bool)
    wanted = X.copy()
    for (i, field), c in problem.columns.items():
        if field in POSITION_FIELDS:
            wanted[:, c] = poses[:, i, POSITION_FIELDS.index(field)]
    within = np.all((wanted >= problem.xl) & (wanted <= problem.xu), axis=1)

    before, after = problem.start_overlap(X), problem.start_overlap(Xr)
    print(f"\n{twin}: overlapping at the start {np.sum(before > 0)}/200 before, {np.sum(after > 0)} after; "
          f"repaired {rep.repaired}; repaired position within bounds {within.sum()}/200")
    assert np.sum(before > 0) >= 30, "the draw exercises the back-off"
    assert rep.repaired == changed.sum() >= np.sum(before > 0)
    assert np.all(after[within] <= 0.0), "no overlap at the start wherever the bounds did not clip"
    assert within.mean() >= 0.9
    assert np.all((Xr >= problem.xl) & (Xr <= problem.xu))
    other = [c for c, f in enumerate(problem.free) if f.field not in POSITION_FIELDS]
    np.testing.assert_array_equal(Xr[:, other], X[:, other])  # only positions are moved
    np.testing.assert_array_equal(Xr[~changed], X[~changed])  # untouched candidates are not altered


def test_repair_brings_near_misses_onto_a_collision_course():
    """Start from grazing configurations (V2, heading north, passes just ahead of V1, heading east: V2's
    rear corner meets V1's left front corner), then shift V2 sideways (+x) by 0.5 m: the straight paths
    now miss by a little and the impulse model sees no contact. After the repair they collide."""
    study = load_study(STUDIES / "twin3.toml")
    problem = study.make_problem()
    assert [f.label for f in problem.free] == ["V1.x", "V1.y", "V2.x", "V2.y"]
    front, rear, half_w = problem.outline_dims[0]
    v1, v2 = study.scene.vehicles[0].speed, study.scene.vehicles[1].speed
    rows = []
    for x1 in (-2.0, -1.0, 0.0):
        for x2 in (3.0, 4.0, 5.0, 6.0):
            t = (x2 - half_w - (x1 + front)) / v1  # V1's front reaches V2's left side
            y1 = -rear + v2 * t - half_w           # ... just as V2's rear clears V1's left side
            rows.append([x1, y1, x2 + 0.5, 0.0])
    X = np.array(rows)
    assert np.all((X >= problem.xl) & (X <= problem.xu))
    gaps = np.array([_least_separation(problem.start_poses(x)[0], problem.outline_dims, 0, 1, 4.0, 0.01)[0]
                     for x in X])
    assert np.all((gaps < -0.1) & (gaps > -0.5)), "straight paths miss by 0.1-0.5 m"

    def impacts(X):
        return evaluation.evaluate_in_process("impulse", (), [problem.scene_for(x) for x in X]).n_impacts

    assert np.all(impacts(X) == 0), "no contact before the repair"
    Xr, rep = _repair(problem, X, max_shift=1.0)
    n_imp = impacts(Xr)
    shift = np.linalg.norm(Xr - X, axis=1)
    print(f"\nnear misses: {len(X)}, repaired {rep.repaired}, colliding after {np.sum(n_imp > 0)}; "
          f"position change {shift.min():.3f}-{shift.max():.3f} m")
    assert np.all(n_imp > 0), "every near miss collides after the repair"
    assert np.all(problem.start_overlap(Xr) <= 0.0)
    assert np.all((Xr >= problem.xl) & (Xr <= problem.xu))
    assert np.all(shift <= 1.0 + 0.5), "a small move, not a re-draw"
    G = problem.evaluate(Xr, return_values_of=["G"])
    assert np.all(G <= 0), "feasible for the optimizer"


# ------------------------------------------------------------------ 2. objectives and failures
@pytest.mark.parametrize("name", ["case1", "twin3"])
def test_objective_is_the_rest_position_distance(name):
    study = load_study(STUDIES / f"{name}.toml")
    problem = study.make_problem()
    X = np.random.default_rng(3).uniform(problem.xl, problem.xu, (8, problem.n_var))
    F = problem.evaluate(X, return_values_of=["F"])
    for x, f in zip(X, F):
        scene = problem.scene_for(x)
        for field, val in zip(problem.free, x):  # the scene carries the candidate (file units -> SI)
            v = next(v for v in scene.vehicles if v.name == field.vehicle)
            got = {"x": v.x, "y": v.y, "heading": np.degrees(v.heading), "speed": v.speed * 3.6}[field.field]
            assert got == pytest.approx(val, abs=1e-9)
        rest = crashlab.simulate(scene, model="impulse").rest
        expected = [np.hypot(rest.loc[n, "x"] - ex, rest.loc[n, "y"] - ey)
                    for n, (ex, ey, _) in study.evidence.items()]
        if not rest.loc[list(study.evidence), "at_rest"].all():  # an end pose is no rest pose: failed
            expected = [FAILED_OBJECTIVE] * len(expected)
        np.testing.assert_allclose(f, expected, rtol=0, atol=1e-9)


def test_twin_truth_has_zero_objectives():
    study = load_study(STUDIES / "twin5.toml")
    problem = study.make_problem()
    truth = truth_of(study)
    x = np.array([[truth[f.label] for f in problem.free]])
    F, G = problem.evaluate(x, return_values_of=["F", "G"])
    np.testing.assert_allclose(F, 0.0, atol=1e-9)
    assert np.all(G <= 0)


def test_heading_weight_adds_weighted_wrapped_heading_difference():
    study = load_study(STUDIES / "case1.toml")
    w = 0.05
    base = ReconstructionProblem(study.scene, study.spec.free, study.evidence, 0.0, "impulse", {})
    weighted = ReconstructionProblem(study.scene, study.spec.free, study.evidence, w, "impulse", {})
    turned = {n: (x, y, h + 360.0 * k) for k, (n, (x, y, h)) in zip((1, -2), study.evidence.items())}
    weighted_turned = ReconstructionProblem(study.scene, study.spec.free, turned, w, "impulse", {})
    X = np.random.default_rng(5).uniform(base.xl, base.xu, (10, base.n_var))
    F0 = base.evaluate(X, return_values_of=["F"])
    Fw = weighted.evaluate(X, return_values_of=["F"])
    for x, f0, fw in zip(X, F0, Fw):
        rest = crashlab.simulate(base.scene_for(x), model="impulse").rest
        dh = np.array([rest.loc[n, "heading"] - eh for n, (_, _, eh) in study.evidence.items()])
        np.testing.assert_allclose(fw - f0, w * np.abs(wrap180(dh)), rtol=0, atol=1e-9)
        assert np.all(fw - f0 <= w * 180.0 + 1e-12)
    # the evidence heading given one or two turns apart changes nothing (the wrapped difference)
    np.testing.assert_allclose(weighted_turned.evaluate(X, return_values_of=["F"]), Fw, rtol=0, atol=1e-9)


class FlakyModel:
    """The impulse model, except: V1 faster than 60 km/h raises; V2 slower than 15 km/h returns a failed
    outcome (outcome_ok False, no rest pose). simulate_batch raises whenever a raising scene is in it."""

    def __init__(self):
        self.model = crashlab.get_model("impulse")

    @staticmethod
    def _raises(scene):
        return scene.vehicles[0].speed * 3.6 > 60.0

    @staticmethod
    def _fails(scene):
        return scene.vehicles[1].speed * 3.6 < 15.0

    def simulate(self, scene):
        if self._raises(scene):
            raise RuntimeError("solver blew up")
        if self._fails(scene):
            return SimpleNamespace(outcome_ok=False, rest_si=np.full((2, 3), np.nan), warnings=["failed"])
        return self.model.simulate(scene)

    def simulate_batch(self, scenes):
        if any(self._raises(s) for s in scenes):
            raise RuntimeError("batch blew up")
        return [self.simulate(s) for s in scenes]


def test_failed_evaluations_are_counted_infeasible_and_do_not_stop_the_run(monkeypatch, tmp_path):
    monkeypatch.setattr(evaluation, "model_instance", lambda name, items: FlakyModel())
    study = load_study(small_study(tmp_path, pop_size=12, generations=3))
    problem = study.make_problem()
    X = np.array([[50.0, 30.0], [65.0, 30.0], [50.0, 12.0], [40.0, 20.0]])
    F, G = problem.evaluate(X, return_values_of=["F", "G"])
    assert problem.n_failed == 2
    np.testing.assert_array_equal(F[1:3], FAILED_OBJECTIVE)
    assert np.all(G[1:3] > 0) and np.all(G[[0, 3]] <= 0)
    assert np.all(F[[0, 3]] < 10.0)

    study.spec.execution.timeout_s = 0  # in this process, where the monkeypatched model is (test_execution.py
    res = study.run()                   # has the same through worker processes)
    arch = res.problem.archive_arrays()
    bad = (arch["X"][:, 0] > 60.0) | (arch["X"][:, 1] < 15.0)
    print(f"\nflaky model: {bad.sum()} of {res.evaluations} evaluations failed")
    assert res.algorithm_info["search_evaluations"] == 12 * 3  # then the polish (failures included)
    assert res.evaluations == 12 * 3 + res.algorithm_info["polish_evaluations"]
    assert bad.sum() > 0 and res.failed == bad.sum()
    assert np.all(arch["F"][bad] == FAILED_OBJECTIVE) and np.all(np.any(arch["G"][bad] > 0, axis=1))
    assert not np.any(arch["ok"][bad]) and np.all(arch["ok"][~bad])
    assert len(res.pareto) > 0
    assert np.all(res.pareto["V1.speed"] <= 60.0) and np.all(res.pareto["V2.speed"] >= 15.0)
    assert res.feasible_fraction <= 1.0 - bad.mean() + 1e-12


# ------------------------------------------------------------------ 3. the same answer on every backend
def _short_run(backend, workers=None):
    study = load_study(STUDIES / "twin1.toml")
    study.spec.optimizer.pop_size, study.spec.optimizer.generations = 12, 3
    study.spec.execution.backend = backend
    t0 = time.perf_counter()
    res = study.run(workers=workers)
    print(f"\n{backend}: {time.perf_counter() - t0:.2f} s, {len(res.pareto)} Pareto rows")
    return res


@pytest.fixture(scope="module")
def serial_run():
    return _short_run("serial")


def _assert_same(a, b):
    assert list(a.pareto.columns) == list(b.pareto.columns)
    assert len(a.pareto) > 0
    assert np.array_equal(a.pareto.to_numpy(float), b.pareto.to_numpy(float))
    assert a.algorithm_info["search_evaluations"] == 36 and a.failed == b.failed == 0
    assert a.evaluations == b.evaluations > 36  # and the polish gave the same evaluations on both
    fa, fb = a.problem.archive_arrays(), b.problem.archive_arrays()
    assert np.array_equal(fa["X"], fb["X"]) and np.array_equal(fa["F"], fb["F"])


def test_processes_backend_gives_the_serial_answer(serial_run):
    _assert_same(serial_run, _short_run("processes", workers=2))


def test_dask_local_cluster_gives_the_serial_answer(serial_run):
    pytest.importorskip("dask.distributed")
    _assert_same(serial_run, _short_run("dask", workers=2))


# ------------------------------------------------------------------ 4. resume after a kill
def test_resume_after_kill_equals_uninterrupted_run(tmp_path):
    pop, gens = 20, 8
    study = small_study(tmp_path, pop_size=pop, generations=gens)
    full, cut = tmp_path / "full", tmp_path / "cut"
    res = cli("reconstruct", study, "--out", full, "--no-progress", "--json")
    assert res.returncode == 0, res.stderr
    assert json.loads(res.stdout)["search_evaluations"] == pop * gens

    ckpt = cut / "checkpoint.pkl"
    proc = subprocess.Popen([sys.executable, "-m", "crashlab.cli", "reconstruct", str(study), "--out", str(cut),
                             "--no-progress"], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    deadline = time.monotonic() + 120
    while not ckpt.exists() and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.001)
    seen = ckpt.exists()
    if proc.poll() is None:
        os.kill(proc.pid, signal.SIGKILL)
    proc.wait(timeout=30)
    assert seen, f"a checkpoint is written after every generation: {proc.stderr.read()!r}"
    killed = proc.returncode == -signal.SIGKILL
    with open(ckpt, "rb") as fh:
        algorithm = pickle.load(fh)["algorithm"]
    done = len(algorithm.problem.archive["X"])
    print(f"\nkilled={killed}: checkpoint holds {done} of {gens} generations")
    if killed and done < gens:
        assert not (cut / "pareto.csv").exists(), "outputs come at the end"

    res = cli("reconstruct", study, "--resume", "--out", cut, "--no-progress", "--json")
    assert res.returncode == 0, res.stderr
    data = json.loads(res.stdout)
    assert data["search_evaluations"] == pop * gens and data["failed"] == 0
    assert (cut / "pareto.csv").read_text() == (full / "pareto.csv").read_text()


# ------------------------------------------------------------------ 5. bad study files
BAD = {  # id: (line replacements, key, words in the message)
    "optimizer-typo": ({"o": ('name = "nsga-sharing"', 'name = "nsga-sharng"')}, "optimizer.name",
                       ["did you mean 'nsga-sharing'"]),
    "optimizer-prefix": ({"o": ('name = "nsga-sharing"', 'name = "nsga"')}, "optimizer.name",
                         ["unknown optimizer 'nsga'", "did you mean"]),
    "reversed-bounds": ({"l": ("lower = 30.0", "lower = 80.0")}, "free.0", ["lower", "upper", "80"]),
    "unknown-vehicle": ({"v": ('vehicle = "V2"', 'vehicle = "V3"')}, "free.1.vehicle", ["'V3'"]),
    "unknown-field-value": ({"f": ('field = "speed"', 'field = "velocity"')}, "free.0.field", ["speed"]),
    "unknown-key": ({"k": ("upper = 70.0", 'upper = 70.0\ncolour = "red"')}, "free.0.colour", ["unknown key"]),
    "missing-scene": ({"s": ("side.toml", "no_such_scene.toml")}, "scene", ["not found"]),
    "unknown-model": ({"m": ('model = "impulse"', 'model = "impluse"')}, "model", ["did you mean 'impulse'"]),
    "negative-polish": ({"p": ("evaluations = 250", "evaluations = -5")}, "polish.evaluations", ["0"]),
    "polish-step": ({"p": ("evaluations = 250", "evaluations = 250\nstep = 0.9")}, "polish.step", ["0.5"]),
}


@pytest.mark.parametrize("case", list(BAD), ids=list(BAD))
def test_bad_study_file_exits_2_with_one_line(tmp_path, case):
    replace, key, words = BAD[case]
    path = small_study(tmp_path, name=f"{case}.toml", **replace)
    assert_one_error_line(cli("reconstruct", path, "--no-progress"), path, key, words)


def test_bad_command_line_options_exit_2(tmp_path):
    path = small_study(tmp_path)
    assert_one_error_line(cli("reconstruct", path, "--optimizer", "nsga-sharng"), path, "--optimizer",
                    ["did you mean 'nsga-sharing'"])
    assert_one_error_line(cli("reconstruct", path, "--resume", "--out", tmp_path / "empty"),
                    tmp_path / "empty" / "checkpoint.pkl", "--resume", ["no checkpoint"])


# ------------------------------------------------------------------ 6. outputs
def test_outputs_csv_figures_summary_and_json(tmp_path):
    pop, gens = 12, 3
    path = small_study(tmp_path, pop_size=pop, generations=gens)
    out = tmp_path / "out"
    res = cli("reconstruct", path, "--out", out, "--json")
    assert res.returncode == 0, res.stderr
    data = json.loads(res.stdout)

    import pandas as pd
    table = pd.read_csv(out / "pareto.csv")
    per_vehicle = [f"{kind}_{n}_{q}" for n in ("V1", "V2")
                   for kind, qs in (("rest", "x y heading"), ("contact", "x y heading speed")) for q in qs.split()]
    assert list(table.columns[:6]) == ["V1.speed", "V2.speed", "f_V1", "f_V2", "dheading_V1", "dheading_V2"]
    assert set(table.columns[6:]) == set(per_vehicle) and len(table.columns) == 6 + len(per_vehicle)
    assert len(table) >= 1
    assert np.all((table["V1.speed"] >= 30) & (table["V1.speed"] <= 70))
    assert np.all((table["V2.speed"] >= 10) & (table["V2.speed"] <= 50))
    # the objectives are the distances of the tabled rest positions from the twin evidence
    ref = crashlab.simulate(crashlab.load_scene(SIDE), model="impulse").rest
    for n in ("V1", "V2"):
        d = np.hypot(table[f"rest_{n}_x"] - ref.loc[n, "x"], table[f"rest_{n}_y"] - ref.loc[n, "y"])
        np.testing.assert_allclose(table[f"f_{n}"], d, rtol=0, atol=1e-9)
    # non-dominated among themselves
    F = table[["f_V1", "f_V2"]].to_numpy()
    for a in F:
        assert not np.any(np.all(F <= a, axis=1) & np.any(F < a, axis=1))

    assert (out / "objectives.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    summary = (out / "summary.md").read_text()
    assert summary.startswith("# Reconstruction") and "Pareto set" in summary
    assert "V1.speed = 50.000, V2.speed = 30.000" in summary  # the twin's truth: side.toml's start

    assert {"pareto", "evaluations", "failed", "wall_time_s"} <= set(data)
    assert data["search_evaluations"] == pop * gens and data["failed"] == 0 and data["wall_time_s"] > 0
    assert len(data["pareto"]) == len(table)
    for item, (_, row) in zip(data["pareto"], table.iterrows()):
        assert set(item) == {"start", "objectives", "rest"}
        assert item["start"] == pytest.approx({"V1.speed": row["V1.speed"], "V2.speed": row["V2.speed"]}, abs=1e-9)
        assert item["objectives"] == pytest.approx({"f_V1": row["f_V1"], "f_V2": row["f_V2"]}, abs=1e-9)
        assert set(item["rest"]) == {"V1", "V2"}
        assert item["rest"]["V2"]["heading"] == pytest.approx(row["rest_V2_heading"], abs=1e-9)


# ------------------------------------------------------------------ 7. twin experiments (slow)
@pytest.mark.slow
@pytest.mark.parametrize("k", [1, 2, 3, 4, 5])
def test_twin_experiment_finds_the_evidence(k):
    """The study as written (its optimizer, the thesis's budget, then the least-squares polish), seeds 1-5:
    every seed's Pareto set holds a solution within 10 cm for both vehicles. Printed per seed: the best
    after the search alone, after the polish, and how far the best solution's free variables are from
    the truth."""
    bests = []
    for seed in (1, 2, 3, 4, 5):
        study = load_study(STUDIES / f"twin{k}.toml")
        study.spec.optimizer.seed = seed
        t0 = time.perf_counter()
        res = study.run()
        wall = time.perf_counter() - t0
        P = res.pareto
        fcols = [f"f_{n}" for n in study.evidence]
        best = P.loc[P[fcols].max(axis=1).idxmin()]
        truth = truth_of(study)
        off = {c: round(float(best[c] - truth[c]), 3) for c in truth}
        n_search = res.algorithm_info["search_evaluations"]
        search_best = res.problem.archive_arrays()
        feasible = np.all(search_best["G"][:n_search] <= 0, axis=1) & search_best["ok"][:n_search]
        search_best = search_best["F"][:n_search][feasible].max(axis=1).min()
        print(f"\ntwin{k} seed {seed} ({study.spec.optimizer.name} {study.spec.optimizer.pop_size}x"
              f"{study.spec.optimizer.generations} + polish {res.algorithm_info['polish_evaluations']}, "
              f"{wall:.1f} s): best max objective {search_best:.4f} m after the search, "
              f"{best[fcols].max():.4f} m after the polish; its free variables minus the truth: {off}")
        assert n_search == study.spec.optimizer.pop_size * study.spec.optimizer.generations
        assert 0 < res.algorithm_info["polish_evaluations"] <= study.spec.polish.evaluations
        assert res.evaluations == n_search + res.algorithm_info["polish_evaluations"]
        bests.append(float(best[fcols].max()))
    assert max(bests) <= 0.10, f"a solution within 10 cm for both vehicles at every seed (per seed: {bests})"


# ------------------------------------------------------------------ 8. polish and constraint handling
def test_spaced_starts_keep_one_start_per_basin():
    from crashlab.reconstruction import spaced_starts
    X = np.array([[0.50, 0.50], [0.52, 0.50], [0.90, 0.10], [0.55, 0.55], [0.10, 0.90]])
    got, picked = spaced_starts(X, np.zeros(2), np.ones(2), spacing=0.1)
    np.testing.assert_array_equal(picked, [0, 2, 4])  # the best first, then the next one 0.1 away
    np.testing.assert_array_equal(got, X[[0, 2, 4]])


def test_polish_brings_twin4_within_10_cm_where_the_search_alone_does_not():
    """twin4 at seed 18: NSGA with the thesis's budget ends 0.111 m from the evidence; the polish
    (250 evaluations from spaced starts) ends within 10 cm for both vehicles (measured 0.019 m). (Seed 15 until
    the impulse kernel's solved load transfer and long slide steps of issue 25, smoother rest poses: its search
    alone now reaches 0.076 m; seed 7 until the impulse model's sustained contact of issue 10: 0.021 m.)"""
    study = load_study(STUDIES / "twin4.toml")
    study.spec.optimizer.seed = 18
    res = study.run()
    n_search = res.algorithm_info["search_evaluations"]
    arch = res.problem.archive_arrays()
    feasible = np.all(arch["G"] <= 0, axis=1) & arch["ok"]
    after_search = arch["F"][:n_search][feasible[:n_search]].max(axis=1).min()
    after_polish = res.pareto[["f_V1", "f_V2"]].max(axis=1).min()
    print(f"\ntwin4 seed 18: {after_search:.3f} m after the search, {after_polish:.4f} m after the polish")
    assert after_search > 0.10
    assert after_polish <= 0.10
    assert 0 < res.algorithm_info["polish_evaluations"] <= 250


def _himmelblau_residuals(calls):
    """Residuals of Himmelblau's function, zero at (3, 2), (-2.805118, 3.131312), ...; `calls` collects
    every batch size asked for."""
    def residuals(X):
        calls.append(len(X))
        x, y = X[:, 0], X[:, 1]
        return np.column_stack([x**2 + y - 11.0, x + y**2 - 7.0])
    return residuals


def test_polish_reaches_the_zero_of_an_analytic_residual_within_its_budget():
    calls = []
    res = polish(_himmelblau_residuals(calls), [[1.0, 1.0]], xl=[0.0, 0.0], xu=[5.0, 5.0], max_evaluations=100)
    assert res.x[0] == pytest.approx([3.0, 2.0], abs=1e-6)  # the zero inside the bounds
    assert res.cost[0] < 1e-12
    assert res.evaluations == sum(calls) <= 100
    assert set(calls) <= {1, 2}  # single points and one batch of n_var points per Jacobian


def test_polish_reuses_known_start_residuals():
    """With the starts' residuals given, no start is evaluated again; a budget below n_var (no Jacobian
    possible) then spends nothing."""
    calls = []
    r0 = _himmelblau_residuals([])(np.array([[1.0, 1.0]]))
    res = polish(_himmelblau_residuals(calls), [[1.0, 1.0]], xl=[0.0, 0.0], xu=[5.0, 5.0], max_evaluations=1,
                 start_residuals=r0)
    assert res.evaluations == sum(calls) == 0
    assert res.cost[0] == pytest.approx(0.5 * float(r0[0] @ r0[0]))


def test_polish_never_exceeds_its_budget_and_goes_through_the_starts_in_order():
    calls = []
    starts = [[1.0, 1.0], [4.5, 0.5], [0.5, 4.5]]
    res = polish(_himmelblau_residuals(calls), starts, xl=[0.0, 0.0], xu=[5.0, 5.0], max_evaluations=25)
    assert res.evaluations == sum(calls) <= 25
    assert np.isfinite(res.cost[0]) and res.cost[0] < 0.5 * (5.0**2 + 5.0**2)  # improved on the start
    calls.clear()
    res = polish(_himmelblau_residuals(calls), starts, xl=[0.0, 0.0], xu=[5.0, 5.0], max_evaluations=1000)
    assert np.all(res.cost < 1e-12)  # every start polished when the budget allows
    assert np.all(res.x >= 0.0) and np.all(res.x <= 5.0)


def test_polish_stays_inside_the_bounds_when_the_zero_lies_outside():
    """r = x - 2 on [0, 1]: the bounded least-squares optimum is the bound x = 1."""
    seen = []

    def residuals(X):
        seen.append(X.copy())
        return X - 2.0

    res = polish(residuals, [[0.2]], xl=[0.0], xu=[1.0], max_evaluations=60)
    assert res.x[0, 0] == pytest.approx(1.0, abs=1e-6)
    X = np.concatenate(seen)
    assert X.min() >= 0.0 and X.max() <= 1.0  # the forward differences turn back at the upper bound


def test_optimizer_without_constraint_handling_gets_the_violation_as_a_penalty():
    """pymoo's MOEA/D takes no constraints: the problem carries overlap and miss as a penalty on the
    objectives; the archive keeps the true objectives and constraints, and the Pareto set is feasible."""
    study = load_study(STUDIES / "twin3.toml")  # x, y of V1 and V2 free
    study.spec.optimizer.pop_size, study.spec.optimizer.generations = 20, 4
    name, algorithm = study.make_algorithm("moead")
    assert algorithm.handles_constraints is False
    problem = study.make_problem(constraints_as_penalty=True)
    assert problem.n_ieq_constr == 0
    truth = [truth_of(study)[f.label] for f in study.spec.free]
    X = np.array([truth, [3.0, 0.0, 3.5, 0.0]])  # the second puts V1 onto V2 at the start
    F = problem.evaluate(X, return_values_of=["F"])
    arch = problem.archive_arrays()
    violation = np.maximum(arch["G"], 0.0).sum(axis=1)
    assert violation[0] == 0.0 and violation[1] > 0.1
    np.testing.assert_allclose(F, arch["F"] + FAILED_OBJECTIVE * violation[:, None])
    res = study.run(optimizer="moead")
    assert len(res.pareto) > 0
    assert res.pareto[["f_V1", "f_V2"]].max(axis=1).min() < 1.0


@pytest.mark.slow
def test_heading_evidence_and_the_contact_zone_point_of_impact():
    """twin2 with heading evidence (heading_weight 0.05 m/deg), seeds 1-3: the first-touch point of impact
    puts the truth on a knife edge (V1 exactly perpendicular to V2) that the search cannot find (> 0.5 m);
    the impulse model's crush_time = 0.036 s makes the rest pose continuous and every seed recovers the
    evidence within 10 cm."""
    import math

    import crashlab
    found = {}
    for crush_time in (0.0, 0.036):
        found[crush_time] = []
        for seed in (1, 2, 3):
            study = load_study(STUDIES / "twin2.toml")
            study.spec.objective.heading_weight = 0.05
            study.spec.optimizer.seed = seed
            study.spec.model_options = {"crush_time": crush_time}
            out = crashlab.get_model("impulse", crush_time=crush_time).simulate(study.scene)
            study.evidence = {n: (out.rest_si[i, 0], out.rest_si[i, 1], math.degrees(out.rest_si[i, 2]))
                              for i, n in enumerate(study.scene.vehicle_names)}
            res = study.run()
            found[crush_time].append(float(res.pareto[["f_V1", "f_V2"]].max(axis=1).min()))
    print(f"\ntwin2 with heading evidence, best per seed: first touch {np.round(found[0.0], 3)}, "
          f"contact zone {np.round(found[0.036], 3)}")
    assert min(found[0.0]) > 0.5
    assert max(found[0.036]) <= 0.10


def test_a_free_engagement_depth_is_checked_against_its_scene_range():
    """The study's free fields are read by crashlab.fields (one vocabulary, one table of ranges): the
    engagement depth, a field a study may free, had no range in the study's own table (a KeyError)."""
    from pydantic import ValidationError

    from crashlab.reconstruction.schema import FreeVariable
    assert FreeVariable(field="engagement_depth", lower=0.2, upper=0.8).path == "impact.engagement_depth"
    with pytest.raises(ValidationError, match=r"lower = 0 is outside \[0.001, .*\] m for engagement_depth"):
        FreeVariable(field="engagement_depth", lower=0.0, upper=0.8)


def test_progress_and_summary_say_the_same_feasible_share(serial_run):
    """Issue 26 item 2: the progress line's feasible share is the summary's (every evaluation, ok and within
    the constraints), not the last generation's alone; counted here from the archive."""
    from crashlab.reconstruction.run import status
    problem = serial_run.problem
    arch = problem.archive_arrays()
    share = float((np.all(arch["G"] <= 0, axis=1) & arch["ok"]).mean())
    assert serial_run.feasible_fraction == pytest.approx(share)
    assert f"feasible {share:.1%} " in status(problem, 10.0)
