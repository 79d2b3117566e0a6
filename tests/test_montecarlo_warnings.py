"""The model's warnings of a Monte Carlo's draws (crashlab.reconstruction.montecarlo, issue 24's user pass): a law
used outside its assumptions is said, once per kind with the number of draws that gave it, never dropped by the
population route and never one line per draw.

Physics of the check: a collinear rear impact of a car at speed v into a standing one (no rolling resistance, 0.1 m
gap, wheels locked only after the impact) closes at v, so restitution = "speed" (Cipriani et al. 2002, data 1-8 m/s
= 3.6-28.8 km/h, docs/physics.md §13b) is held at its end value in exactly the draws with v above 28.8 km/h:
counted here from the drawn speeds, not from the model. crashlab.warning_groups, which tells a kind of warning once:
checked on hand-written warnings.

Needs the patches population_warnings.diff (crashlab.population keeps each draw's warnings; without
it they were dropped, the failure the user pass found) and cli_montecarlo_stderr.diff (stderr from the CLI).
"""
from __future__ import annotations

import io
import json

import numpy as np
import pandas as pd
import pytest

import crashlab
from crashlab.cli import main
from crashlab.reconstruction import montecarlo
from crashlab.scene_file import load_scene
from crashlab.warning_groups import group

V_MAX_KMH = 8.0 * 3.6  # the top of the law's data (Cipriani et al. 2002), km/h
MARGIN_KMH = 0.3  # a draw this close to the end: either side (the 0.1 m roll to contact, the onset bisection)

REAR = """name = "rear impact, uncertain bullet speed"
duration = 3.0
stop_at_rest = true
[road]
friction = 0.8
[impact]
restitution = "speed"
friction = 0.3
force_law = "exact-restitution"
[[vehicles]]
name = "V1"
vehicle = "clio"
x = 0.0
y = 0.0
heading = 0.0
speed = 25.0
wheels = "locked_after_impact"
[vehicles.overrides]
rolling_resistance = 0.0
[[vehicles]]
name = "V2"
vehicle = "clio"
x = 3.875
y = 0.0
heading = 0.0
speed = 0.0
wheels = "locked_after_impact"
[vehicles.overrides]
rolling_resistance = 0.0
[[uncertain]]
field = "vehicles.V1.speed"
distribution = "uniform"
lower = 15.0
upper = 45.0
"""


# ---------------------------------------------------------------- crashlab.warning_groups
def test_a_kind_of_warning_once_with_its_runs_and_ranges():
    runs = [["closing speed 48.3 km/h is outside (3.6-28.8 km/h)", "impact 1 (V1-V2): slip reverses"],
            [],
            ["closing speed 52.1 km/h is outside (3.6-28.8 km/h)"],
            ["closing speed 50.0 km/h is outside (3.6-28.8 km/h)", "closing speed 61.0 km/h is outside (3.6-28.8 "
             "km/h)"]]
    assert group(runs) == [("closing speed 48.3 to 61.0 km/h is outside (3.6-28.8 km/h)", [0, 2, 3]),
                           ("impact 1 (V1-V2): slip reverses", [0])]
    assert group([[], []]) == []
    # words that differ are different kinds, even with the same numbers
    assert [n for _, n in group([["a 1 below"], ["a 1 above"]])] == [[0], [1]]
    # a name's digits are the name (the review: V1-V2 and V2-V3 read "V1 to 2-V2 to 3")
    assert group([["impact 1 (V1-V2 at t = 0.1 s)"], ["impact 1 (V2-V3 at t = 0.3 s)"]]) == [
        ("impact 1 (V1-V2 at t = 0.1 s)", [0]), ("impact 1 (V2-V3 at t = 0.3 s)", [1])]


# ---------------------------------------------------------------- the Monte Carlo
@pytest.fixture(scope="module")
def rear(tmp_path_factory):
    path = tmp_path_factory.mktemp("mc") / "rear.toml"
    path.write_text(REAR)
    result = montecarlo.run(load_scene(path), crashlab.get_model("impulse"), 200, seed=4)
    return path, result


def test_counts_the_draws_where_the_law_is_held(rear):
    _, result = rear
    assert result.table["ok"].all(), result.failure_reasons()
    v = result.table["vehicles.V1.speed"].to_numpy()
    counts = [(w, k) for w, k in result.warning_counts() if w.startswith('restitution = "speed"')]
    assert len(counts) == 1, result.warning_counts()  # one kind, told once, not a line per draw
    text, k = counts[0]
    assert int((v > V_MAX_KMH + MARGIN_KMH).sum()) <= k <= int((v > V_MAX_KMH - MARGIN_KMH).sum())
    assert 50 < k < 150  # the premise: uniform 15-45 km/h, about 200 x 16.2 / 30 above the end
    # its closing speeds span the drawn speeds above the end: from about 28.8 to about the largest draw
    low, high = (float(x) for x in text.split("closing speed ")[1].split(" km/h")[0].split(" to "))
    assert V_MAX_KMH - MARGIN_KMH <= low < V_MAX_KMH + 1.0 and high == pytest.approx(v.max(), abs=MARGIN_KMH)
    # per draw: exactly the draws above the end carry it (the population keeps each draw's warnings)
    held = result.table["warnings"].str.contains("closing speed", regex=False).to_numpy()
    sure = np.abs(v - V_MAX_KMH) > MARGIN_KMH
    assert np.array_equal(held[sure], (v > V_MAX_KMH)[sure])


def test_summary_json_and_stderr_say_it(rear, tmp_path):
    _, result = rear
    k = dict(result.warning_counts())
    text = io.StringIO()
    montecarlo.print_summary(result, file=text)
    lines = [ln for ln in text.getvalue().splitlines() if "restitution" in ln]
    assert len(lines) == 1 and f"in {next(iter(k.values()))} of 200 draws: restitution" in lines[0]
    err = io.StringIO()
    montecarlo.print_warnings(result, file=err)
    assert len([ln for ln in err.getvalue().splitlines() if "restitution" in ln]) == 1
    d = result.to_json_dict()
    assert [(w["warning"], w["draws"]) for w in d["warnings"]] == result.warning_counts()
    json.dumps(d)
    written = montecarlo.write(result, tmp_path / "out")
    table = pd.read_csv(tmp_path / "out" / "warnings.csv")
    assert tmp_path / "out" / "warnings.csv" in written
    drawn, nominal = table[table["run"] == "draws"], table[table["run"] == montecarlo.NOMINAL]
    assert list(zip(drawn["warning"], drawn["draws"])) == result.warning_counts() and (drawn["of"] == 200).all()
    assert nominal.empty and len(drawn) == len(table)  # the scene as written (25 km/h) is within the law's data
    assert "warnings" not in pd.read_csv(tmp_path / "out" / "montecarlo.csv").columns  # not a column per draw


def test_the_scene_as_written_has_its_own_rows(tmp_path):
    """The nominal run's warnings (the scene as written, 40 km/h: above the law's data) are rows of warnings.csv of
    their own, run "the scene as written" (until 2026-11-28 on stderr and in the summary only)."""
    path = tmp_path / "fast.toml"
    path.write_text(REAR.replace("speed = 25.0", "speed = 40.0"))
    result = montecarlo.run(load_scene(path), crashlab.get_model("impulse"), 4, seed=1)
    montecarlo.write(result, tmp_path / "out")
    table = pd.read_csv(tmp_path / "out" / "warnings.csv")
    nominal = table[table["run"] == montecarlo.NOMINAL]
    assert list(nominal["warning"]) == [str(w) for w in result.nominal.warnings]
    assert len(nominal) == 1 and "40.0 km/h" in nominal["warning"].iloc[0] and (nominal["of"] == 1).all()


def test_no_warning_within_the_law_data(tmp_path, capsys):
    """Speeds of 10-25 km/h (2.8-6.9 m/s): within the law's data, the summary says none."""
    path = tmp_path / "slow.toml"
    path.write_text(REAR.replace("lower = 15.0", "lower = 10.0").replace("upper = 45.0", "upper = 25.0"))
    assert main(["simulate", str(path), "--monte-carlo", "40", "--seed", "2", "--out", str(tmp_path / "o")]) == 0
    cap = capsys.readouterr()
    out = cap.out
    assert "the model's warnings in the draws: none" in out and "restitution" not in out
    assert "wrote " in cap.err and "wrote " not in out  # (on stdout until 2026-11-28, unlike simulate --csv)
    assert pd.read_csv(tmp_path / "o" / "warnings.csv").empty


def test_cli_says_it_on_stderr(rear, capsys):
    """`crashlab simulate SCENE --monte-carlo N --json`: stdout is the JSON, stderr tells each kind once with its
    count (framework/cli/simulate.py calls montecarlo.print_warnings)."""
    path, _ = rear
    assert main(["simulate", str(path), "--monte-carlo", "60", "--seed", "4", "--json"]) == 0
    cap = capsys.readouterr()
    d = json.loads(cap.out)
    said = [ln for ln in cap.err.splitlines() if "restitution" in ln and "draws" in ln]
    k = [w["draws"] for w in d["warnings"] if w["warning"].startswith('restitution = "speed"')]
    assert len(said) == 1 and len(k) == 1 and f"in {k[0]} of 60 draws" in said[0]


def test_a_populations_warnings_are_each_variants_own():
    """simulate_population's warnings equal each variant's Outcome's, word for word, with the engagement depth
    varied (docs/physics.md §4): a variant's warning quotes its own depth (it quoted the base scene's before)."""
    import dataclasses
    from pathlib import Path

    from crashlab import fields
    from crashlab.registry import get_model
    repo = Path(__file__).resolve().parent.parent
    scene = load_scene(repo / "studies" / "validation" / "rose4363_accord_blazer.toml")
    scene = dataclasses.replace(scene, impact=dataclasses.replace(scene.impact, engagement=True))
    model = get_model("impulse")
    depths = np.linspace(0.1, 1.5, 12)
    pop = model.simulate_population(scene, ["impact.engagement_depth"], depths[:, None])
    own = ["\n".join(map(str, model.simulate(fields.set_field(scene, "impact.engagement_depth", d)).warnings))
           for d in depths]
    assert list(pop.warnings) == own
    assert sum("engagement_depth" in w for w in own) >= 3  # the fallback is met, at several depths
