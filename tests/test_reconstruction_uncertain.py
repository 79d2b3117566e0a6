"""Uncertain parameters in the search (issue 14, item 2; crashlab.reconstruction.problem, "Uncertain
parameters"): `crashlab reconstruct` takes `[[uncertain]]` entries as extra free variables within their support
(uniform, triangular: lower..upper; normal: mean +- 3 sd within its truncation), and the Pareto rows show them.

The twin: side.toml's collision (V1 50 km/h, V2 30 km/h, road friction 0.8) simulated by the impulse model is
the evidence (rest poses); the speeds are free and the road friction is uncertain, uniform on [0.6, 1.2] (the
truth 0.8 off its centre 0.9, so a search that kept the scene's value or the middle of the range would not pass
by chance). Two rest positions (four numbers) determine the three unknowns: the search recovers them.
"""
from __future__ import annotations

import numpy as np
import pytest
from conftest import PC_CRASH, side_twin_study

from crashlab import uncertainty
from crashlab.cli import main
from crashlab.errors import InputError
from crashlab.reconstruction import load_study, search_bounds

SIDE = PC_CRASH / "side.toml"

TWIN = side_twin_study("twin with uncertain road friction", pop_size=24, generations=12, polish=150)
FRICTION = """
[[uncertain]]
field = "road.friction"
distribution = "uniform"
lower = 0.6
upper = 1.2
"""


def _study(tmp_path, text, name="study.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_twin_recovers_uncertain_friction_and_speeds(tmp_path):
    """The best Pareto row lies at the truth: speeds within 0.2 km/h, friction within 0.01 (a search without the
    friction cannot show it: the column would be missing; pareto.csv has it)."""
    path = _study(tmp_path, TWIN + FRICTION)
    study = load_study(path)
    assert [v.label for v in study.variables] == ["V1.speed", "V2.speed", "road.friction"]
    res = study.run()
    best = res.pareto.iloc[0]
    assert "road.friction" in res.pareto.columns
    assert abs(best["V1.speed"] - 50.0) < 0.2 and abs(best["V2.speed"] - 30.0) < 0.2
    assert abs(best["road.friction"] - 0.8) < 0.01
    assert res.pareto["road.friction"].between(0.6, 1.2).all()  # within the support
    res.pareto.to_csv(tmp_path / "pareto.csv", index=False)  # what write_outputs writes (report.py)
    assert "road.friction" in (tmp_path / "pareto.csv").read_text().splitlines()[0].split(",")


def test_search_bounds_of_each_distribution():
    """uniform and triangular: their support; normal: mean +- 3 sd, cut to its truncation."""
    scene = load_study_scene()
    u, t, n, nt = uncertainty.parse([
        {"field": "road.friction", "distribution": "uniform", "lower": 0.6, "upper": 1.2},
        {"field": "impact.restitution", "distribution": "triangular", "lower": 0.05, "mode": 0.1, "upper": 0.3},
        {"field": "impact.friction", "distribution": "normal", "mean": 0.3, "sd": 0.05},
        {"field": "vehicles.V1.mass", "distribution": "normal", "mean": 1000.0, "sd": 100.0, "lower": 900.0},
    ], scene)
    assert search_bounds(u) == (0.6, 1.2)
    assert search_bounds(t) == (0.05, 0.3)
    assert search_bounds(n) == pytest.approx((0.15, 0.45), abs=1e-12)
    lo, hi = search_bounds(nt)
    assert lo == 900.0 and hi == pytest.approx(1300.0)


def load_study_scene():
    from crashlab.scene_file import load_scene
    return load_scene(SIDE)


def test_mass_and_free_field_entries(tmp_path):
    """An uncertain mass becomes a variable whose value reaches the simulated scene (total mass replaced); an
    entry on a free variable's own field adds nothing (the free bounds stand)."""
    extra = """
[[uncertain]]
field = "vehicles.V2.mass"
distribution = "uniform"
lower = 900.0
upper = 1100.0
[[uncertain]]
field = "vehicles.V1.speed"
distribution = "normal"
mean = 50.0
sd = 2.0
"""
    study = load_study(_study(tmp_path, TWIN + extra))
    assert [v.label for v in study.variables] == ["V1.speed", "V2.speed", "V2.mass"]
    problem = study.make_problem()
    assert problem.xl.tolist() == [30.0, 10.0, 900.0] and problem.xu.tolist() == [70.0, 50.0, 1100.0]
    scene = problem.scene_for(np.array([55.0, 25.0, 950.0]))
    assert scene.vehicle("V2").spec.mass == 950.0
    assert scene.vehicle("V1").speed == pytest.approx(55.0 / 3.6, rel=1e-15)
    assert problem.base_values()[2] == pytest.approx(study.scene.vehicle("V2").spec.mass)


@pytest.mark.parametrize("entry, key", [
    ('field = "road.fricton"\ndistribution = "uniform"\nlower = 0.6\nupper = 1.0', "uncertain.0.field"),
    ('field = "road.friction"\ndistribution = "normal"\nmean = 0.8\nsd = -0.1', "uncertain.0.sd"),
    ('field = "road.friction"\ndistribution = "uniform"\nlower = 0.6', "uncertain.0.upper"),
])
def test_bad_uncertain_is_one_line(tmp_path, capsys, entry, key):
    """Bad [[uncertain]] input for `crashlab reconstruct`: one line naming the file and the key, exit 2."""
    path = _study(tmp_path, TWIN + "[[uncertain]]\n" + entry + "\n")
    with pytest.raises(InputError):
        load_study(path)
    assert main(["reconstruct", str(path), "--no-progress"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and str(path) in err and key in err


def test_the_printed_pareto_table_carries_units(tmp_path, capsys):
    """`crashlab reconstruct` prints the Pareto rows with each column's unit: the speeds in km/h, the uncertain
    friction dimensionless, the thesis objective in m."""
    text = TWIN.replace("pop_size = 24", "pop_size = 6").replace("generations = 12", "generations = 1")
    path = _study(tmp_path, text.replace("evaluations = 150", "evaluations = 0") + FRICTION)
    assert main(["reconstruct", str(path), "--no-progress"]) == 0
    header = capsys.readouterr().out.splitlines()[0].split()
    assert header[:8] == ["V1.speed", "[km/h]", "V2.speed", "[km/h]", "road.friction", "[-]", "f_V1", "[m]"]
