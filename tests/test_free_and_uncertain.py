"""A field both free ([[free]]) and uncertain ([[uncertain]] of the study or of its base scene's file), issue 27.

Chosen: kept, with its meaning said (crashlab.reconstruction.study.free_and_uncertain): the free bounds are
the field's range in both commands, the search ignores the distribution, crashlab infer takes it as the prior
within the bounds (posterior.py). Refusing it would break the natural use of a Monte Carlo scene's
[[uncertain]] speeds as the prior of the study that frees them. `reconstruct` says which bounds apply (one
note line); a distribution with no probability within the bounds (a prior 0 everywhere) is refused with one
line naming the file, free.K and the uncertain entry, exit 2."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from conftest import assert_one_error_line
from test_reconstruction_truth import study_file

from crashlab.errors import InputError
from crashlab.reconstruction import load_study

REPO = Path(__file__).resolve().parent.parent
MONTECARLO_SIDE = REPO / "studies" / "montecarlo" / "side.toml"


def uncertain_x(lower, upper, vehicle="V1"):
    return (f'\n[[uncertain]]\nfield = "vehicles.{vehicle}.x"\ndistribution = "uniform"\n'
            f"lower = {lower}\nupper = {upper}\n")


def with_uncertain(tmp_path, text, name="s.toml", base="case3"):
    """case3 (V1.x free on [-3, 3] m, ...) with `text` appended (a non-twin study: nothing simulated at load)."""
    path = study_file(tmp_path, base=base, name=name, pop_size=8, generations=2, polish="evaluations = 0")
    path.write_text(path.read_text() + text)
    return path


def test_overlapping_distribution_is_kept_and_its_meaning_said(tmp_path):
    study = load_study(with_uncertain(tmp_path, uncertain_x(-1.0, 5.0)))
    assert [v.label for v in study.variables] == ["V1.x", "V1.y", "V2.x", "V2.y"]  # no second V1.x
    problem = study.make_problem()
    assert (problem.xl[0], problem.xu[0]) == (-3.0, 3.0)  # the free bounds stand in the search
    assert study.notes == ["V1.x is free (free.0, [-3, 3] m) and uncertain (uncertain.0): the search keeps the free "
                           "bounds; crashlab infer takes uniform on [-1, 5] m as its prior within them"]


@pytest.mark.parametrize("lower, upper", [(4.0, 9.0), (-9.0, -3.0), (3.0, 5.0)])
def test_a_distribution_without_probability_within_the_bounds_is_refused(tmp_path, lower, upper):
    path = with_uncertain(tmp_path, uncertain_x(lower, upper))
    with pytest.raises(InputError) as err:
        load_study(path)
    line = str(err.value)
    print("\n" + line)
    assert line.startswith(f"{path}: free.0: V1.x is also uncertain (uncertain.0: uniform on [{lower:g}, {upper:g}]")
    assert "no probability within its bounds [-3, 3] m" in line and "\n" not in line


def test_a_scene_files_uncertain_entry_is_named_with_the_scene(tmp_path):
    """The Monte Carlo scene's [[uncertain]] V1.speed (normal 50, sd 3) under a study that frees V1.speed."""
    text = study_file(tmp_path, base="case1", pop_size=8, generations=2, polish="evaluations = 0").read_text()
    path = tmp_path / "mc.toml"
    path.write_text(text.replace(f'scene = "{(REPO / "studies" / "pc_crash" / "side.toml").as_posix()}"',
                                 f'scene = "{MONTECARLO_SIDE.as_posix()}"'))
    notes = load_study(path).notes
    print("\n" + "\n".join(notes))
    assert any(n.startswith("V1.speed is free (free.0, ") and "(uncertain.3 of side.toml)" in n
               and "normal, mean 50, sd 3 km/h" in n for n in notes), notes


def test_reconstruct_says_it_and_refuses_the_empty_prior(tmp_path):
    cmd = [sys.executable, "-m", "crashlab.cli", "reconstruct"]
    ok = subprocess.run([*cmd, str(with_uncertain(tmp_path, uncertain_x(-1.0, 5.0))), "--no-progress"],
                        capture_output=True, text=True, timeout=300)
    assert ok.returncode in (0, 4), ok.stderr
    assert "crashlab: note: " in ok.stderr and "the search keeps the free bounds" in ok.stderr
    bad = with_uncertain(tmp_path, uncertain_x(4.0, 9.0), name="bad.toml")
    res = subprocess.run([*cmd, str(bad)], capture_output=True, text=True, timeout=300)
    assert_one_error_line(res, bad, "free.0", ["uncertain.0", "no probability within its bounds"])
