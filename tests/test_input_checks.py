"""Input checks and the given point of impact: each bad input is one line naming file and key (exit 2),
and a given point joins the pair whose outlines meet there."""
from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import crashlab
from crashlab.scene import scene_from_dict

REPO = Path(__file__).resolve().parent.parent
SIDE = REPO / "studies" / "pc_crash" / "side.toml"


def cli(*args):
    return subprocess.run([sys.executable, "-m", "crashlab.cli", *map(str, args)], capture_output=True,
                          text=True, timeout=300)


def one_line_error(res, file, key):
    lines = res.stderr.strip().splitlines()
    assert res.returncode == 2, res.stderr
    assert len(lines) == 1 and "Traceback" not in res.stderr, res.stderr
    assert str(file) in lines[0] and key in lines[0], lines[0]


SCENE = """name = "t"
[[vehicles]]
name = "V1"
vehicle = "clio"
speed = 40.0
{extra}
"""


@pytest.mark.parametrize("extra, key", [
    ("[vehicles.overrides]\nmas = 1200.0", "vehicles.0.overrides.mas"),        # unknown vehicle key
    ("[vehicles.overrides]\nmultibody = 3", "vehicles.0.overrides.multibody"),  # a table replaced by a value
    ("x = nan", "vehicles.0.x"),                                               # NaN
])
def test_bad_scene_values(tmp_path, extra, key):
    f = tmp_path / "s.toml"
    f.write_text(SCENE.format(extra=extra))
    one_line_error(cli("simulate", f), f, key)


def test_errors_in_a_vehicle_file_are_blamed_on_it(tmp_path):
    veh = tmp_path / "car.toml"
    text = (REPO / "framework" / "vehicles" / "clio.toml").read_text().replace("track = 1.405", "")
    veh.write_text(text)
    f = tmp_path / "s.toml"
    f.write_text(SCENE.format(extra="").replace('"clio"', '"car.toml"') + "[vehicles.overrides]\nmass = 900.0\n")
    one_line_error(cli("simulate", f), veh, "track")


def test_given_point_joins_the_pair_that_meets_there():
    """V1 against a barrier at its collision position, V2 parked far away: the impulse at t = 0 is
    between V1 and the barrier, and V1 rebounds at -e v."""
    sc = scene_from_dict({
        "name": "wall", "duration": 3.0,
        "impact": {"restitution": 0.1, "friction": 0.0, "point": [1.8875, 0.0], "plane_angle": 90.0},
        "vehicles": [{"name": "V1", "vehicle": "clio", "speed": 50.0},
                     {"name": "V2", "vehicle": "clio", "y": 20.0}],
        "barriers": [{"x": 2.3875, "y": 0.0, "length": 3.0, "width": 1.0, "heading": 90.0}]})
    out = crashlab.simulate(sc)
    assert out.outcome_ok, out.warnings
    first = out.impacts.iloc[0]
    assert first.t == 0.0 and first.vehicle == "V1" and first.other == "barrier0"
    assert first.dvx == pytest.approx(-50.0 * 1.1, rel=1e-9)
    assert np.allclose(out.rest_si[1], [0.0, 20.0, 0.0])  # V2 untouched


def test_a_given_point_far_from_every_pair_is_refused(tmp_path):
    f = tmp_path / "s.toml"
    f.write_text(SCENE.format(extra="") + '[impact]\npoint = [30.0, 0.0]\nplane_angle = 90.0\n')
    one_line_error(cli("simulate", f), f, "impact.point")


STUDY = f"""scene = "{SIDE.as_posix()}"
model = "impulse"
[optimizer]
name = "nsga2"
pop_size = 8
generations = 2
{{free}}
[evidence.rest.V1]
x = 7.11
y = 3.51
{{extra}}
"""
FREE_SPEED = '[[free]]\nvehicle = "V1"\nfield = "speed"\nlower = 40.0\nupper = 60.0\n'


@pytest.mark.parametrize("free, extra, key", [
    ('[[free]]\nvehicle = "V1"\nfield = "restitution"\nlower = 0.0\nupper = 0.5\n', "", "free.0"),
    ('[[free]]\nfield = "restitution"\nlower = 0.0\nupper = 1.5\n', "", "free.0"),
    (FREE_SPEED, "[model_options]\ndt = -1.0", "model_options"),
])
def test_bad_study_values(tmp_path, free, extra, key):
    f = tmp_path / "study.toml"
    f.write_text(STUDY.format(free=free, extra=extra))
    one_line_error(cli("reconstruct", f, "--no-progress"), f, key)


def test_nsga3_takes_the_objective_count_and_moead_needs_two(tmp_path):
    """One evidence vehicle: one objective. NSGA-III runs (one reference direction, the study's population);
    MOEA/D, whose population is one per direction, would silently shrink to one: refused in one line."""
    f = tmp_path / "study.toml"
    f.write_text(STUDY.format(free=FREE_SPEED, extra=""))
    res = crashlab.load_study(f).run(optimizer="nsga3")
    assert res.evaluations == 16 and list(res.pareto.columns).count("f_V1") == 1
    assert res.algorithm_info["pop_size"] == 8
    one_line_error(cli("reconstruct", f, "--optimizer", "moead", "--no-progress"), f, "optimizer.options")


def test_evidence_without_heading_has_no_heading_term(tmp_path):
    """heading_weight > 0 but no measured heading: the objective is the position distance alone."""
    f = tmp_path / "study.toml"
    f.write_text(STUDY.format(free=FREE_SPEED, extra="[objective]\nheading_weight = 0.5"))
    study = crashlab.load_study(f)
    problem = study.make_problem()
    x = np.array([50.0])
    out = crashlab.simulate(problem.scene_for(x))
    expected = math.hypot(out.rest_si[0, 0] - 7.11, out.rest_si[0, 1] - 3.51)
    assert problem.objectives(out.rest_si[None])[0, 0] == pytest.approx(expected, rel=1e-12)
