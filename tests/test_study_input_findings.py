"""Study inputs a CLI fuzz found accepted: a field free twice, [[questions]] and [[counterfactuals]] that only
`infer` checked, an empty or unnamed Dask scheduler (and one with backend = "serial"), infinity in a question,
and NaN with library warnings from a chain too short for an autocorrelation estimate. Each is refused with one
line naming the file and the key (exit 2), or said once in the project's own words."""
from __future__ import annotations

import logging
import warnings
from pathlib import Path
from types import SimpleNamespace

import pandas as pd
import pytest
from conftest import FREE_SPEEDS, assert_one_error_line, assert_refused_with_one_line

from crashlab.errors import InputError
from crashlab.reconstruction.questions import parse_question
from crashlab.reconstruction.study import load_study

REPO = Path(__file__).resolve().parent.parent
SIDE = REPO / "studies" / "pc_crash" / "side.toml"

# side.toml's collision, two free speeds, measured rest poses with sigmas; 4 x 1 evaluations, no polish
STUDY = f"""name = "findings"
scene = "{SIDE.as_posix()}"
model = "impulse"

[optimizer]
name = "nsga2"
pop_size = 4
generations = 1
seed = 1

{FREE_SPEEDS}
[evidence.rest.V1]
x = 7.11
y = 3.51
heading = 147.68
sigma_xy = 1.0
sigma_heading = 10.0

[evidence.rest.V2]
x = 10.64
y = 5.31
heading = 344.77
sigma_xy = 1.0
sigma_heading = 10.0

[polish]
evaluations = 0

[execution]
backend = "serial"
timeout_s = 0
"""
SERIAL = '[execution]\nbackend = "serial"\n'


def _study(tmp_path, text=STUDY, name="study.toml") -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


def _cli(capsys, *args):
    from crashlab.cli import main
    code = main([str(a) for a in args])
    captured = capsys.readouterr()
    return SimpleNamespace(returncode=code, stdout=captured.out, stderr=captured.err)


# ------------------------------------------------------------------ a field free twice
def test_a_field_free_twice_is_refused(tmp_path):
    """Two [[free]] V1 speeds made two columns of one field (the second set last): refused as a field uncertain
    twice is (crashlab.uncertainty.parse)."""
    text = STUDY.replace('vehicle = "V2"\nfield = "speed"', 'vehicle = "V1"\nfield = "speed"', 1)
    assert_refused_with_one_line(load_study, _study(tmp_path, text), "free.1", ["V1.speed is already free (free.0)"])


# ------------------------------------------------------------------ [execution]
@pytest.mark.parametrize("value, ok", [(0.0, True), (1e-9, False), (0.099, False), (0.1, True)])
def test_a_timeout_shorter_than_a_round_trip_is_refused(tmp_path, value, ok):
    """timeout_s = 1e-9 ran and failed 2 of 12 evaluations for it, letting 10 through (a probe, 2026-11-28): a
    batch gets n x the limit and a worker's first call a grace. 0 (no limit) or at least 0.1 s."""
    path = _study(tmp_path, STUDY.replace("timeout_s = 0\n", f"timeout_s = {value!r}\n"))
    if ok:
        assert load_study(path).spec.execution.timeout_s == value
    else:
        assert_refused_with_one_line(load_study, path, "execution.timeout_s", ["0 (no limit) or at least 0.1 s"])


# ------------------------------------------------------------------ [[questions]], [[counterfactuals]]
@pytest.mark.parametrize("table, key, words", [
    ('[[questions]]\nexpr = ""', "questions.0.expr", ["at least 1 character"]),
    ('[[questions]]\nexpr = "V1.speed >"', "questions.0.expr", ["does not parse"]),
    ('[[questions]]\nexpr = "V3.speed > 50"', "questions.0.expr", ["unknown name 'V3.speed'"]),
    ('[[questions]]\nexpr = "V1.speed / 0 > 1"', "questions.0.expr", ["divides by zero"]),
    # a chain's part without a variable: summary.md answered 0.000 quietly (a probe, 2026-11-28)
    ('[[questions]]\nexpr = "V1.speed > 50 > 40 == 1"', "questions.0.expr",
     ["has 50 > 40, a comparison without a variable: always true"]),
    ('[[questions]]\nexpr = "V1.speed > 5 and 2 * 3 > 7"', "questions.0.expr", ["has 2 * 3 > 7,", "always false"]),
    ("[[questions]]\nexpr = \"__import__('os').system('echo PWNED')\"", "questions.0.expr", ["Call is not allowed"]),
    ('[[counterfactuals]]\nname = "x"\nset = {nope = 1}', "counterfactuals.0.set.nope", ["unknown field 'nope'"]),
    ('[[counterfactuals]]\nname = "x"', "counterfactuals.0", ["give set, shift or scale"]),
])
def test_reconstruct_refuses_what_infer_refuses(tmp_path, capsys, table, key, words):
    """Checked when the study is loaded, for both commands: the same one line."""
    p = _study(tmp_path, STUDY + "\n" + table + "\n")
    res = _cli(capsys, "reconstruct", p, "--no-progress")
    assert_one_error_line(res, p, key, words)
    inferred = _cli(capsys, "infer", p, "--out", tmp_path / "o", "--no-progress")
    assert_one_error_line(inferred, p, key, words)
    assert inferred.stderr == res.stderr


def test_reconstruct_runs_with_valid_questions_and_counterfactuals_and_says_it_answers_neither(tmp_path, capsys):
    p = _study(tmp_path, STUDY + '\n[[questions]]\nexpr = "V1.speed > 50"\n\n[[counterfactuals]]\nname = "x"\n'
               'set = { "vehicles.V1.speed" = 40.0 }\n')
    res = _cli(capsys, "reconstruct", p, "--no-progress")
    assert res.returncode == 0, res.stderr
    assert "evaluations 4" in res.stdout
    notes = res.stderr.strip().splitlines()
    assert len(notes) == 2, res.stderr
    for line, key in zip(notes, ("questions", "counterfactuals")):
        assert line.startswith(f"crashlab: note: {p}: {key}: 1 [[{key}]] checked, not answered by reconstruct"), line


def test_a_number_beyond_the_largest_float_is_refused():
    """1e999 is read as infinity: refused (as a division by a constant zero is), not a question always False."""
    with pytest.raises(InputError, match=r"^s\.toml: questions\.1\.expr: 'V1\.speed > 1e999' .*infinite"):
        parse_question("V1.speed > 1e999", ["V1.speed"], "s.toml", "questions.1.expr")
    with pytest.raises(InputError, match="infinite"):
        parse_question("-1e400 < V1.speed", ["V1.speed"])
    assert parse_question("V1.speed > 1e300", ["V1.speed"]).probability({"V1.speed": [50.0]}) == 0.0
    # an integer of 401 digits: float() raised OverflowError, a traceback of every study command
    with pytest.raises(InputError, match="infinite"):
        parse_question("V1.speed > 1" + "0" * 400, ["V1.speed"])


# ------------------------------------------------------------------ the Dask scheduler
def test_an_empty_scheduler_option_is_refused(tmp_path, capsys):
    p = _study(tmp_path)
    assert_one_error_line(_cli(capsys, "reconstruct", p, "--scheduler", "", "--no-progress"), p, "--scheduler",
                          ["empty address"])


def test_an_unreachable_scheduler_names_where_it_came_from(tmp_path, capsys):
    """The executor's line named neither the file nor the key: --scheduler or execution.scheduler."""
    p = _study(tmp_path)
    assert_one_error_line(_cli(capsys, "reconstruct", p, "--scheduler", "notanaddress", "--no-progress"), p,
                          "--scheduler", ["no Dask scheduler answers at 'notanaddress'"])
    dask = _study(tmp_path, STUDY.replace(SERIAL, SERIAL.replace("serial", "dask") + 'scheduler = "notanaddress"\n'),
                  "dask.toml")
    assert_one_error_line(_cli(capsys, "reconstruct", dask, "--no-progress"), dask, "execution.scheduler",
                          ["no Dask scheduler answers at 'notanaddress'"])
    infer = _cli(capsys, "infer", dask, "--out", tmp_path / "o", "--no-progress")
    assert_one_error_line(infer, dask, "execution.scheduler", ["no Dask scheduler answers at 'notanaddress'"])


@pytest.mark.parametrize("lines, words", [('scheduler = "tcp://1.2.3.4:8786"\n', ["execution.backend = 'serial'"]),
                                          ('scheduler = " "\n', ["empty address"])])
def test_a_study_scheduler_needs_an_address_and_the_dask_backend(tmp_path, lines, words):
    """A scheduler made a serial study's run a Dask one, contacting that address (a reply that is no Dask's
    was read as a message 3 EiB long: MemoryError); now refused when the study is loaded."""
    p = _study(tmp_path, STUDY.replace(SERIAL, SERIAL + lines))
    assert_refused_with_one_line(load_study, p, "execution.scheduler", words)


# ------------------------------------------------------------------ a chain too short for tau
def test_a_chain_too_short_for_tau_shows_dashes_and_one_warning(tmp_path, capsys, caplog):
    """[infer] at its documented minimums (8 walkers, 2 kept iterations): a walker that did not move leaves
    tau and the ESS uncomputable; a dash and the project's one warning line, no NaN, no library warning."""
    p = _study(tmp_path, STUDY + '\n[[questions]]\nexpr = "V1.speed > 50"\n\n[infer]\nwalkers = 8\nsamples = 16\n'
               "burn = 0\ninit = 1\ndraws_plotted = 0\n")
    out = tmp_path / "o"
    with warnings.catch_warnings(record=True) as seen, caplog.at_level(logging.WARNING):
        warnings.simplefilter("always")
        res = _cli(capsys, "infer", p, "--out", out, "--no-progress")
    assert res.returncode == 0, res.stderr
    assert [str(w.message) for w in seen if not issubclass(w.category, DeprecationWarning)] == []
    assert [r.getMessage() for r in caplog.records] == []
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("warning: 2 kept iterations are too few samples for an "
                                                   "autocorrelation estimate"), res.stderr
    assert "ESS -" in res.stdout and "nan" not in res.stdout.lower()
    summary = (out / "summary.md").read_text()
    assert "nan" not in summary.lower() and "| - | - |" in summary and "smallest ESS -." in summary
    assert "| `V1.speed > 50` |" in summary


def test_a_scheduler_alone_is_a_dask_study(tmp_path):
    """[execution] scheduler without a backend written (the default "serial"): the study runs on that scheduler,
    as before the check of a scheduler with a serial backend (which refused it too in a first version)."""
    from crashlab.reconstruction.run import _backend
    p = _study(tmp_path, STUDY.replace(SERIAL, '[execution]\nscheduler = "tcp://127.0.0.1:8786"\n'))
    study = load_study(p)
    assert _backend(study, None, None) == "dask"


def test_summary_says_when_it_shows_part_of_the_pareto_set(tmp_path, capsys, monkeypatch):
    """summary.md showed the first 15 Pareto rows of 42 without a word (a probe, 2026-11-28); here with the limit
    at 1 row, so that the small search's set exceeds it."""
    from crashlab.reconstruction import report
    monkeypatch.setattr(report, "SUMMARY_ROWS", 1)
    p = _study(tmp_path, STUDY.replace("pop_size = 4\ngenerations = 1", "pop_size = 12\ngenerations = 4"))
    res = _cli(capsys, "reconstruct", p, "--no-progress", "--out", tmp_path / "out")
    assert res.returncode == 0, res.stderr
    n = len(pd.read_csv(tmp_path / "out" / "pareto.csv"))
    assert n > 1
    text = (tmp_path / "out" / "summary.md").read_text()
    assert f"(rows 0-0 of {n}; every row in pareto.csv and report.html)" in text
