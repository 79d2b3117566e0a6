"""reconstruct and infer findings of the CLI fuzzer (fuzz15): a large but valid misfit is a result, not "could not be
scored"; bad input is one line on stderr (no notes, progress bar or blank line before it), exit 2; a bad
[optimizer.options] key is refused by every command. Run in-process (crashlab.cli.main) on the tutorial study with
a tiny budget."""
from __future__ import annotations

import pickle
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from crashlab.cli import main
from crashlab.errors import InputError
from crashlab.reconstruction import FAILED_OBJECTIVE, load_study
from crashlab.reconstruction.command import _no_feasible
from crashlab.reconstruction.problem import scored_feasible
from crashlab.reconstruction.run import CHECKPOINT_FORMAT, _result

REPO = Path(__file__).resolve().parent.parent
TUTORIAL = REPO / "studies" / "tutorial"
TINY = {"pop_size = 24": "pop_size = 4", "generations = 10": "generations = 1",
        "evaluations = 60 ": "evaluations = 0 ", "walkers = 16": "walkers = 8", "samples = 3000": "samples = 16",
        "burn = 300": "burn = 0"}
COUNTERFACTUAL = '\n[[counterfactuals]]\nname = "V1 at 50"\nset = { "vehicles.V1.speed" = 50.0 }\n'


def tutorial(tmp_path: Path, replace: dict | None = None, extra: str = "", name: str = "study.toml") -> Path:
    """The tutorial study (its [[questions]] and a [[counterfactuals]]: reconstruct notes both) with a tiny budget."""
    text = (TUTORIAL / "study.toml").read_text()
    for old, new in (TINY | {'scene = "scene.toml"': f'scene = "{(TUTORIAL / "scene.toml").as_posix()}"'}
                     | (replace or {})).items():
        assert old in text, old
        text = text.replace(old, new, 1)
    path = tmp_path / name
    path.write_text(text + COUNTERFACTUAL + extra)
    return path


def run(capsys, *args):
    """(exit status, stdout, stderr) of crashlab.cli.main in this process; stderr as written (not stripped)."""
    code = main([str(a) for a in args])
    out, err = capsys.readouterr()
    return code, out, err


def one_line(capsys, path, key, *args):
    """The command refused in exactly one stderr line naming `path` and `key`, exit 2."""
    code, out, err = run(capsys, *args)
    assert code == 2 and len(err.splitlines()) == 1, (code, out, err)
    assert err.startswith(f"crashlab: error: {path}: {key}: "), err


# 1 -- a misfit of 1000 sigma or more is a result; "could not be scored" is decided by what was not scored
def test_a_huge_but_valid_misfit_is_reported_exit_0(tmp_path, capsys):
    path = tutorial(tmp_path, {"x = 1.8": "x = 1000.0"})  # the point of impact about 1000 m off: ~2000 sigma
    code, out, err = run(capsys, "reconstruct", path, "--no-progress")
    assert code == 0, (out, err)
    assert "no feasible solution" not in err and "could be scored" not in err
    f = [float(v) for v in out.splitlines()[1].split()[4:6]]  # f_V1, f_V2 of Pareto row 0
    assert all(v > FAILED_OBJECTIVE for v in f), out


def evaluated(tmp_path, unscored: list[int]):
    """The tutorial's problem (impact 1000 m off) with two feasible evaluations near the truth, those in `unscored`
    made unscored as damage evidence on a side not struck makes them (a residual NaN, objectives FAILED_OBJECTIVE)."""
    study = load_study(tutorial(tmp_path, {"x = 1.8": "x = 1000.0"}))
    problem = study.make_problem()
    problem.evaluate(np.array([[62.0, 32.0, -12.9, 0.8], [61.0, 32.0, -12.9, 0.8]]))
    R, F = problem.archive["R"][0], problem.archive["F"][0]
    assert scored_feasible(problem.archive_arrays()).all() and (F > FAILED_OBJECTIVE).all()
    for k in unscored:
        R[k, 0], F[k] = np.nan, FAILED_OBJECTIVE
    algorithm = SimpleNamespace(n_gen=2, pop_size=4)
    return study, _result(study, problem, algorithm, "nsga2", 2, 0, time.perf_counter())


def test_unscored_rows_do_not_hide_a_larger_real_misfit(tmp_path, capsys):
    """Before, an unscored row (1000) dominated the scored one (~2000 sigma): the Pareto set showed it as a result."""
    study, res = evaluated(tmp_path, [1])
    assert len(res.pareto) == 1 and (res.pareto[["f_V1", "f_V2"]].to_numpy() > FAILED_OBJECTIVE).all()
    assert res.pareto["V1.speed"].iloc[0] == 62.0
    assert _no_feasible(SimpleNamespace(study=study.path), res) == 0
    assert capsys.readouterr().err == ""


def test_nothing_scored_still_exits_4_with_its_line(tmp_path, capsys):
    study, res = evaluated(tmp_path, [0, 1])
    assert len(res.pareto) and _no_feasible(SimpleNamespace(study=study.path), res) == 4
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and "none of 2 evaluations could be scored on every evidence item" in err[0], err


# 2 -- bad input to reconstruct: one line, no [[questions]] / [[counterfactuals]] notes before it
@pytest.mark.parametrize("args, key", [
    (["--optimizer", "nsga4"], "--optimizer"),
    (["--workers", "-1"], "--workers"),
    (["--resume"], "--resume"),
], ids=["optimizer", "workers", "resume-without-out"])
def test_reconstruct_bad_option_is_one_line(tmp_path, capsys, args, key):
    path = tutorial(tmp_path)
    one_line(capsys, path, key, "reconstruct", path, "--no-progress", *args)


@pytest.mark.parametrize("progress", [[], ["--no-progress"]], ids=["progress", "no-progress"])
def test_reconstruct_dead_scheduler_is_one_line(tmp_path, capsys, progress):
    """Also no progress bar before the line: the bar starts with the run."""
    path = tutorial(tmp_path)
    one_line(capsys, path, "--scheduler", "reconstruct", path, "--scheduler", "tcp://127.0.0.1:1", *progress)


@pytest.mark.parametrize("content", [None, b"", b"garbage", "foreign"], ids=["missing", "empty", "garbage", "foreign"])
def test_reconstruct_bad_checkpoint_is_one_line(tmp_path, capsys, content):
    path, out = tutorial(tmp_path), tmp_path / "out"
    out.mkdir()
    if content == "foreign":  # a checkpoint of this crashlab from another study
        content = pickle.dumps({"format": CHECKPOINT_FORMAT, "fingerprint": {"study file": "another"}})
    if content is not None:
        (out / "checkpoint.pkl").write_bytes(content)
    one_line(capsys, out / "checkpoint.pkl", "--resume", "reconstruct", path, "--out", out, "--resume")


# 3 -- infer with its progress line: no blank line before the error
def test_infer_resume_without_checkpoint_is_one_line_with_progress(tmp_path, capsys):
    path, out = tutorial(tmp_path), tmp_path / "new"
    one_line(capsys, out / "infer_checkpoint.pkl", "--resume", "infer", path, "--out", out, "--resume")


def test_infer_bad_input_after_an_evidence_warning_is_one_line(tmp_path, capsys):
    """A study whose evidence warns (a damage profile without residual crush) and an infer setting refused inside
    the run (--workers): the warning came first, two lines; now the warnings wait for the run to start."""
    damage = ('\n[evidence.damage.V1]\nside = "front"\nprofile = [0.0, 0.0]\nwidth = 1.0\nsigma_crush = 0.02\n'
              'sigma_stiffness = 0.15\n')
    path = tutorial(tmp_path, extra=damage)
    one_line(capsys, path, "--workers", "infer", path, "--out", tmp_path / "o", "--workers", 100000)
    assert "without residual crush" in run(capsys, "infer", path, "--out", tmp_path / "o", "--no-progress")[2]


# 2 and 4 -- a bad [optimizer.options] key is bad input for every command
@pytest.mark.parametrize("command", ["reconstruct", "infer"])
def test_a_bad_optimizer_option_is_refused_by_every_command(tmp_path, capsys, command):
    path = tutorial(tmp_path, {"seed = 1\n": "seed = 1\n[optimizer.options]\nbogus = 3\n"})
    one_line(capsys, path, "optimizer.options", command, path, "--out", tmp_path / "out", "--no-progress")
    with pytest.raises(InputError) as err:
        load_study(path)
    assert err.value.key == "optimizer.options" and "bogus" in err.value.problem


def test_an_empty_pareto_tables_header_is_a_full_ones(tmp_path):
    """The header written for a run without a feasible solution (report._pareto_columns) names the columns a
    table with rows has, in their order."""
    from crashlab.reconstruction.report import _pareto_columns, pareto_table
    study, res = evaluated(tmp_path, [])
    table = pareto_table(res.problem, res.problem.archive_arrays())
    assert len(table) and list(table.columns) == _pareto_columns(res.problem)
