"""A reconstruction tells the truth (issue 10): a moving vehicle's end pose is not scored as a rest pose,
guard-failed and crashed evaluations are failures with reasons (failures.csv, --json `failed`), the
rest-heading error is in pareto.csv and summary.md whatever the heading weight, the Pareto set has no
duplicates, the polish runs by default, every optimizer resumes to the uninterrupted result, a
checkpoint of another study or a corrupt one is refused with one line, and bad study values are one
line before any computation."""
from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from conftest import assert_one_error_line

import crashlab
from crashlab.errors import InputError
from crashlab.execution import evaluate as evaluation
from crashlab.reconstruction import FAILED_OBJECTIVE, POLISH_MIN, load_study, pareto_table

REPO = Path(__file__).resolve().parent.parent
STUDIES = REPO / "studies" / "reconstruction"
SIDE = REPO / "studies" / "pc_crash" / "side.toml"
OPTIMIZERS = ["nsga-sharing", "nsga2", "nsga3", "moead", "sms-emoa", "age-moea"]


def study_file(tmp_path, base="twin1", name="s.toml", pop_size=12, generations=3, polish="evaluations = 30",
               scene_text=None, replace=None) -> Path:
    """A copy of studies/reconstruction/<base>.toml with a small budget, the scene path absolute (or a
    copy of side.toml with `scene_text` changes {old: new}), the [polish] body replaced, serial in this
    process (timeout_s = 0: fast, and monkeypatched models are seen); `replace`: {id: (old, new)}."""
    text = (STUDIES / f"{base}.toml").read_text()
    scene = SIDE
    if scene_text:
        s = SIDE.read_text()
        for old, new in scene_text.items():
            assert old in s, old
            s = s.replace(old, new)
        scene = tmp_path / f"scene_{name}"
        scene.write_text(s)
    text = text.replace('scene = "../pc_crash/side.toml"', f'scene = "{scene.as_posix()}"')
    text = text.replace("pop_size = 75", f"pop_size = {pop_size}").replace("generations = 20",
                                                                           f"generations = {generations}")
    head, _, tail = text.partition("[polish]")
    rest = tail.split("[execution]", 1)[1]
    text = head + ("[polish]\n" + polish + "\n\n" if polish is not None else "") + "[execution]" + rest
    text = text.replace('backend = "serial"', 'backend = "serial"\ntimeout_s = 0')
    for old, new in (replace or {}).values():
        assert old in text, old
        text = text.replace(old, new, 1)
    path = tmp_path / name
    path.write_text(text)
    return path


def cli(*args, timeout=300):
    return subprocess.run([sys.executable, "-m", "crashlab.cli", *map(str, args)], capture_output=True,
                          text=True, timeout=timeout)


# ------------------------------------------------------------------ 1. rest means rest
SHORT = {"duration = 10.0": "duration = 0.6"}  # the cars are still sliding after 0.6 s


def test_a_candidate_still_moving_at_the_end_fails_with_the_reason(tmp_path):
    """Before: the end pose of a car still sliding at 20-40 km/h was scored as its rest pose."""
    path = study_file(tmp_path, base="case1", scene_text=SHORT)
    study = load_study(path)
    problem = study.make_problem()
    X = np.array([[50.0, 30.0], [40.0, 20.0]])
    F = problem.evaluate(X, return_values_of=["F"])
    arch = problem.archive_arrays()
    print("\n" + "\n".join(arch["reason"]))
    np.testing.assert_array_equal(F, FAILED_OBJECTIVE)
    assert problem.n_failed == 2 and not arch["ok"].any()
    for r in arch["reason"]:
        assert "V1 still moving at" in r and "km/h at the end" in r and "V2 still moving" in r
    out = crashlab.simulate(problem.scene_for(X[0]))
    assert f"V1 still moving at {out.rest.loc['V1', 'speed']:.0f} km/h" in arch["reason"][0]


def test_a_twin_whose_base_scene_ends_moving_is_refused_at_load(tmp_path):
    path = study_file(tmp_path, scene_text=SHORT)
    with pytest.raises(InputError) as err:
        load_study(path)
    assert err.value.key == "evidence.twin" and "still moving" in err.value.problem


class GuardFailingModel:
    """The impulse model, but the physics guard fails every candidate with V2 slower than 25 km/h."""

    def __init__(self):
        self.model = crashlab.get_model("impulse")

    def simulate(self, scene):
        return self.simulate_batch([scene])[0]

    def simulate_batch(self, scenes):
        outs = self.model.simulate_batch(scenes)
        for s, o in zip(scenes, outs):
            if s.vehicles[1].speed * 3.6 < 25.0:
                o.fail("energy_outside_contact", "V2 gains 12.3 kJ at t = 1.20 s outside contact")
        return outs


def test_guard_failed_candidates_are_failed_and_listed_in_failures_csv(tmp_path, monkeypatch):
    monkeypatch.setattr(evaluation, "model_instance", lambda name, items: GuardFailingModel())
    path = study_file(tmp_path)
    study = load_study(path)
    res = study.run(out_dir=tmp_path / "out")
    arch = res.problem.archive_arrays()
    bad = arch["X"][:, 1] < 25.0
    table = pd.read_csv(tmp_path / "out" / "failures.csv")
    print(f"\n{bad.sum()} of {res.evaluations} failed by the guard; failures.csv has {len(table)} rows")
    assert bad.sum() > 0 and res.failed == bad.sum() == len(table)
    assert list(table.columns) == ["evaluation", "phase", "V1.speed", "V2.speed", "reason"]
    assert (table["reason"] == "physics guard: energy_outside_contact: V2 gains 12.3 kJ at t = 1.20 s "
            "outside contact").all()
    np.testing.assert_allclose(table[["V1.speed", "V2.speed"]].to_numpy(), arch["X"][bad])
    assert np.all(res.pareto["V2.speed"] >= 25.0)
    data = res.to_json_dict()
    assert data["failed"] == len(table)
    assert data["failure_reasons"] == {"physics guard: energy_outside_contact: V2 gains N kJ at t = N s "
                                       "outside contact": len(table)}
    assert "failed evaluations by reason" in (tmp_path / "out" / "summary.md").read_text()


def test_failures_csv_is_written_when_nothing_failed(tmp_path):
    res = load_study(study_file(tmp_path)).run(out_dir=tmp_path / "out")
    assert res.failed == 0
    assert (tmp_path / "out" / "failures.csv").read_text().splitlines() == ["evaluation,phase,V1.speed,V2.speed,reason"]


# ------------------------------------------------------------------ 2. headings
def test_pareto_has_the_wrapped_heading_error_also_with_heading_weight_zero(tmp_path):
    """case1's evidence has headings, heading_weight = 0: dheading_<vehicle> is in pareto.csv, the JSON
    and summary.md; a vehicle without measured heading gets an empty column."""
    path = study_file(tmp_path, base="case1", replace={"h": ("heading = 344.77", "")})
    study = load_study(path)
    assert study.spec.objective.heading_weight == 0.0
    res = study.run(out_dir=tmp_path / "out")
    table = pd.read_csv(tmp_path / "out" / "pareto.csv")
    expected = ((table["rest_V1_heading"] - 147.68 + 180.0) % 360.0) - 180.0
    np.testing.assert_allclose(table["dheading_V1"], expected, atol=1e-9)
    assert table["dheading_V1"].between(-180.0, 180.0).all()
    assert table["dheading_V2"].isna().all()
    item = res.to_json_dict()["pareto"][0]
    assert item["rest"]["V1"]["dheading"] == pytest.approx(table["dheading_V1"][0], abs=1e-9)
    assert item["rest"]["V2"]["dheading"] is None
    summary = (tmp_path / "out" / "summary.md").read_text()
    print("\n" + summary)
    assert "dheading_V1" in summary and "not part of the objectives" in summary
    if abs(table["dheading_V1"][0]) > 15.0:
        assert "rest headings are off the measured ones: V1" in summary


def test_top_view_shows_measured_headings_and_a_moving_end_pose(tmp_path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from crashlab.tools import plotting
    scene = crashlab.load_scene(SIDE).replace(duration=0.6)
    out = crashlab.simulate(scene)
    assert not out.at_rest_mask.any()
    labels = []
    orig = plt.Axes.legend

    def spy(ax, *a, **k):
        labels.extend(ax.get_legend_handles_labels()[1])
        return orig(ax, *a, **k)
    plt.Axes.legend = spy
    try:
        plotting.top_view(scene, out, tmp_path / "t.png", measured={"V1": (7.11, 3.51, 147.68),
                                                                   "V2": (10.64, 5.31, None)})
    finally:
        plt.Axes.legend = orig
    print("\n" + "\n".join(labels))
    speed = out.rest.loc["V1", "speed"]
    assert any(lab.startswith(f"V1 end pose (moving {speed:.1f} km/h), heading") for lab in labels)
    assert not any(" rest" in lab for lab in labels)
    assert "V1 measured, heading 147.7 deg" in labels and "V2 measured (no heading)" in labels


# ------------------------------------------------------------------ 3. duplicates
def test_pareto_rows_within_1e_6_of_the_bound_width_are_one(tmp_path):
    """Before: rows were merged only when their objectives agreed to 1e-9, so the polish's near-repeats
    (same start to 1e-7 of the bounds, objectives apart by 1e-8) were listed twice."""
    problem = load_study(study_file(tmp_path)).make_problem()
    width = problem.xu - problem.xl
    X = np.array([[50.0, 30.0], [50.0, 30.0], [50.0, 30.0] + 1e-7 * width, [45.0, 35.0],
                  [45.0, 35.0] + 5e-6 * width])
    F = np.array([[0.1, 0.2], [0.1, 0.2], [0.1 + 1e-8, 0.2 - 1e-8], [0.2, 0.1], [0.19, 0.11]])
    arch = {"X": X, "F": F, "G": np.zeros((5, 2)), "ok": np.ones(5, bool), "rest": np.zeros((5, 2, 3)),
            "contact": np.zeros((5, 2, 4)), "reason": np.array([""] * 5, dtype=object)}
    table = pareto_table(problem, arch)
    print("\n" + table[["V1.speed", "V2.speed", "f_V1", "f_V2"]].to_string())
    assert len(table) == 3  # (50, 30) once; (45, 35) and the point 5e-6 away are different solutions
    Z = (table[["V1.speed", "V2.speed"]].to_numpy() - problem.xl) / width
    d = np.abs(Z[:, None] - Z[None]).max(axis=2) + np.eye(len(Z))
    assert d.min() > 1e-6


# ------------------------------------------------------------------ 4. polish by default
def test_polish_runs_by_default_and_zero_turns_it_off(tmp_path):
    res = load_study(study_file(tmp_path, polish=None)).run()
    info = res.algorithm_info
    assert info["polish_budget"] == max(POLISH_MIN, math.ceil(0.1 * 12 * 3)) == 100
    assert 0 < info["polish_evaluations"] <= 100
    off = load_study(study_file(tmp_path, name="off.toml", polish="evaluations = 0")).run()
    assert off.algorithm_info["polish_evaluations"] == 0 and off.evaluations == 36


# ------------------------------------------------------------------ 5. resume, every optimizer
@pytest.mark.parametrize("optimizer", OPTIMIZERS)
def test_every_optimizer_resumes_to_the_uninterrupted_result(tmp_path, optimizer):
    """--out, a stop after generation 2 of 4 (as a kill leaves it: the checkpoint of generation 2), then
    --resume: the same pareto.csv as the run without a stop. Before: nsga3, sms-emoa and moead crashed
    at the first checkpoint (their state did not pickle)."""
    path = study_file(tmp_path, pop_size=12, generations=4)
    full = load_study(path).run(optimizer=optimizer, out_dir=tmp_path / "full")
    assert load_study(path).run(optimizer=optimizer, out_dir=tmp_path / "cut", stop_after=2) is None
    assert not (tmp_path / "cut" / "pareto.csv").exists()
    resumed = load_study(path).run(out_dir=tmp_path / "cut", resume=True)  # the optimizer from the checkpoint
    a, b = (tmp_path / "full" / "pareto.csv").read_text(), (tmp_path / "cut" / "pareto.csv").read_text()
    print(f"\n{optimizer}: {full.evaluations} evaluations, {len(full.pareto)} Pareto rows, resumed equal: {a == b}")
    assert resumed.algorithm_info["optimizer"] == optimizer
    assert resumed.evaluations == full.evaluations and a == b


def test_resume_refuses_a_checkpoint_of_another_study_naming_what_changed(tmp_path):
    path = study_file(tmp_path, generations=2)
    load_study(path).run(out_dir=tmp_path / "out", stop_after=1)
    cases = {  # file text change -> the part the message names
        "generations": (("generations = 2", "generations = 3"), "study file"),
        "model option": (('model = "impulse"', 'model = "impulse"\nmodel_options = {crush_time = 0.02}'),
                         "study file"),
    }
    for what, ((old, new), part) in cases.items():
        changed = study_file(tmp_path, name=f"{what}.toml", generations=2, replace={"x": (old, new)})
        with pytest.raises(InputError) as err:
            load_study(changed).run(out_dir=tmp_path / "out", resume=True)
        print(f"\n{what}: {err.value}")
        assert err.value.key == "--resume" and "different study" in err.value.problem and part in err.value.problem
    scene_changed = study_file(tmp_path, name="sc.toml", generations=2, scene_text={"friction = 0.8": "friction = 0.7"})
    with pytest.raises(InputError, match="scene file"):
        load_study(scene_changed).run(out_dir=tmp_path / "out", resume=True)
    vehicle_changed = study_file(tmp_path, name="vc.toml", generations=2,
                                 scene_text={"rolling_resistance = 0.0": "mass = 1200.0"})
    with pytest.raises(InputError, match="vehicle data of V1"):
        load_study(vehicle_changed).run(out_dir=tmp_path / "out", resume=True)
    with pytest.raises(InputError, match="optimizer 'nsga-sharing', not 'nsga2'"):
        load_study(path).run(optimizer="nsga2", out_dir=tmp_path / "out", resume=True)
    # the same study resumes (the execution backend may differ: results do not depend on it)
    same = study_file(tmp_path, name="same.toml", generations=2,
                      replace={"b": ('backend = "serial"', 'backend = "processes"\nworkers = 3')})
    study = load_study(same)
    study.spec.execution.backend = "serial"
    assert study.run(out_dir=tmp_path / "out", resume=True) is not None


def test_resume_cli_one_line_exit_2_for_another_study_and_a_corrupt_checkpoint(tmp_path):
    path = study_file(tmp_path, generations=2)
    load_study(path).run(out_dir=tmp_path / "out", stop_after=1)
    changed = study_file(tmp_path, name="changed.toml", generations=2,
                         replace={"e": ("[evidence]\ntwin = true", "[evidence.rest.V1]\nx = 4.0\ny = 0.4")})
    ckpt = tmp_path / "out" / "checkpoint.pkl"
    assert_one_error_line(cli("reconstruct", changed, "--resume", "--out", tmp_path / "out", "--no-progress"),
                          ckpt, "--resume", ["different study", "evidence"])
    ckpt.write_bytes(ckpt.read_bytes()[:200])  # a truncated file
    assert_one_error_line(cli("reconstruct", path, "--resume", "--out", tmp_path / "out", "--no-progress"),
                          ckpt, "--resume", ["cannot read the checkpoint", "corrupt"])


@pytest.mark.parametrize("content", [b"", b"not a pickle at all", b"\x80\x04K\x05."])
def test_corrupt_or_foreign_checkpoints_are_assert_one_error_line(tmp_path, content):
    path = study_file(tmp_path)
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "checkpoint.pkl").write_bytes(content)
    with pytest.raises(InputError) as err:
        load_study(path).run(out_dir=tmp_path / "out", resume=True)
    assert err.value.key == "--resume" and "\n" not in str(err.value)


# ------------------------------------------------------------------ 6. bad values: one line, before the search
BAD_VALUES = {  # id: ((old, new), key, words)
    "seed-negative": (("seed = 1", "seed = -1"), "optimizer.seed", ["0"]),
    "seed-huge": (("seed = 1", "seed = 4294967296"), "optimizer.seed", ["4294967295"]),
    "pop-float": (("pop_size = 12", "pop_size = 1e9"), "optimizer.pop_size", ["integer"]),
    "pop-huge": (("pop_size = 12", "pop_size = 1000000000"), "optimizer.pop_size", ["100000"]),
    "pop-bool": (("pop_size = 12", "pop_size = true"), "optimizer.pop_size", ["integer"]),
    "generations-zero": (("generations = 3", "generations = 0"), "optimizer.generations", ["1"]),
    "bound-inf": (("upper = 70.0", "upper = inf"), "free.0.upper", ["finite"]),
    "bound-speed": (("upper = 70.0", "upper = 1000.0"), "free.0", ["400"]),
    "bound-bool": (("lower = 30.0", "lower = true"), "free.0.lower", []),
    "evidence-huge": (("x = 7.11", "x = 1e18"), "evidence.rest.V1.x", ["100000"]),
    "evidence-nan": (("y = 3.51", "y = nan"), "evidence.rest.V1.y", ["finite"]),
    "heading-weight-nan": (("heading_weight = 0.0", "heading_weight = nan"), "objective.heading_weight", []),
    "timeout-negative": (("timeout_s = 0", "timeout_s = -1"), "execution.timeout_s", ["0"]),
    "polish-float": (("evaluations = 30", "evaluations = 1.5"), "polish.evaluations", ["integer"]),
    "workers-zero": (('backend = "serial"', 'backend = "serial"\nworkers = 0'), "execution.workers", ["1"]),
}


@pytest.mark.parametrize("case", list(BAD_VALUES), ids=list(BAD_VALUES))
def test_bad_study_values_are_one_line_naming_the_key(tmp_path, case):
    (old, new), key, words = BAD_VALUES[case]
    path = study_file(tmp_path, base="case1", replace={"r": (old, new)})
    with pytest.raises(InputError) as err:
        load_study(path)
    print(f"\n{err.value}")
    assert err.value.key == key and str(path) == err.value.file and "\n" not in str(err.value)
    for w in words:
        assert w in err.value.problem


def test_bad_study_value_cli_exits_2_before_the_search(tmp_path):
    """Before: evidence at 1e18 m ran the whole search, then crashed drawing the plots."""
    path = study_file(tmp_path, base="case1", replace={"r": ("x = 7.11", "x = 1e18")})
    res = cli("reconstruct", path, "--no-progress", "--out", tmp_path / "out")
    assert_one_error_line(res, path, "evidence.rest.V1.x", ["100000"])
    assert not (tmp_path / "out").exists()
    assert_one_error_line(cli("reconstruct", study_file(tmp_path, name="ok.toml"), "--workers", "-1", "--no-progress"),
             tmp_path / "ok.toml", "--workers")


def test_json_counts_failed_and_reasons(tmp_path):
    res = cli("reconstruct", study_file(tmp_path, base="case1", scene_text=SHORT), "--json", "--no-progress")
    # every evaluation failed: the run finished without a feasible solution, exit 4 with one line on stderr
    assert res.returncode == 4, res.stderr
    assert res.stderr.strip().splitlines()[-1].startswith("crashlab: no feasible solution: ")
    data = json.loads(res.stdout)
    print({k: v for k, v in data.items() if k != "pareto"})
    assert data["failed"] == sum(data["failure_reasons"].values()) == data["evaluations"] == 36
    assert all("still moving at N km/h" in r for r in data["failure_reasons"])


def test_no_feasible_run_writes_a_pareto_csv_with_its_header(tmp_path):
    """Every evaluation failed: pareto.csv was an empty file, which pandas cannot read (a probe, 2026-11-28);
    now its header with no rows."""
    res = cli("reconstruct", study_file(tmp_path, base="case1", scene_text=SHORT), "--no-progress", "--out",
              tmp_path / "out")
    assert res.returncode == 4, res.stderr
    table = pd.read_csv(tmp_path / "out" / "pareto.csv")
    assert table.empty and {"V1.speed", "f_V1", "rest_V1_x", "contact_V2_speed"} <= set(table.columns)
