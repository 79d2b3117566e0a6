"""Input checks and the given point of impact: each bad input is one line naming file and key (exit 2),
and a given point joins the pair whose outlines meet there."""
from __future__ import annotations

import math
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import crashlab
from crashlab.reconstruction import load_study
from crashlab.scene_file import scene_from_dict

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
duration = 2.0
{top}
[[vehicles]]
name = "V1"
vehicle = "clio"
speed = 40.0
{extra}
"""


def scene_text(extra: str = "", top: str = "") -> str:
    return SCENE.format(top=top, extra=extra)


@pytest.mark.parametrize("extra, key", [
    ("[vehicles.overrides]\nmas = 1200.0", "vehicles.V1.overrides.mas"),        # unknown vehicle key
    ("[vehicles.overrides]\nmultibody = 3", "vehicles.V1.overrides.multibody"),  # a table replaced by a value
    ("x = nan", "vehicles.V1.x"),                                               # NaN
])
def test_bad_scene_values(tmp_path, extra, key):
    f = tmp_path / "s.toml"
    f.write_text(scene_text(extra))
    one_line_error(cli("simulate", f), f, key)


def test_errors_in_a_vehicle_file_are_blamed_on_it(tmp_path):
    veh = tmp_path / "car.toml"
    text = (REPO / "framework" / "vehicles" / "clio.toml").read_text().replace("track = 1.405", "")
    veh.write_text(text)
    f = tmp_path / "s.toml"
    f.write_text(scene_text().replace('"clio"', '"car.toml"') + "[vehicles.overrides]\nmass = 900.0\n")
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
    f.write_text(scene_text() + '[impact]\npoint = [30.0, 0.0]\nplane_angle = 90.0\n')
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
    res = load_study(f).run(optimizer="nsga3")
    assert res.algorithm_info["search_evaluations"] == 16 and list(res.pareto.columns).count("f_V1") == 1
    assert res.algorithm_info["pop_size"] == 8
    one_line_error(cli("reconstruct", f, "--optimizer", "moead", "--no-progress"), f, "optimizer.options")


def test_evidence_without_heading_has_no_heading_term(tmp_path):
    """heading_weight > 0 but no measured heading: the objective is the position distance alone."""
    f = tmp_path / "study.toml"
    f.write_text(STUDY.format(free=FREE_SPEED, extra="[objective]\nheading_weight = 0.5"))
    study = load_study(f)
    problem = study.make_problem()
    x = np.array([50.0])
    out = crashlab.simulate(problem.scene_for(x))
    expected = math.hypot(out.rest_si[0, 0] - 7.11, out.rest_si[0, 1] - 3.51)
    assert problem.objectives(out.rest_si[None])[0, 0] == pytest.approx(expected, rel=1e-12)


# ---------------------------------------------------------------- bounds of scene and vehicle numbers
def run_main(capsys, *argv):
    """`crashlab ...` in this process: (exit status, stdout, stderr)."""
    from crashlab.cli import main
    rc = main([str(a) for a in argv])
    out = capsys.readouterr()
    return rc, out.out, out.err


def refused(capsys, file, key, *argv):
    rc, _, err = run_main(capsys, *(argv or ("simulate", file)))
    lines = err.strip().splitlines()
    assert rc == 2 and len(lines) == 1, err
    assert lines[0].startswith(f"crashlab: error: {file}: {key}: "), lines[0]
    return lines[0]


@pytest.mark.parametrize("top, extra, key", [
    # a traceback before (ZeroDivisionError in the outline geometry; math domain error in sin/cos)
    ("", "x = 1e30", "vehicles.V1.x"),
    ("", "heading = 1e308", "vehicles.V1.heading"),
    ("", "[[barriers]]\nx = 1e30\ny = 0.0\nlength = 1.0\nwidth = 1.0", "barriers.0.x"),
    ("", "[[barriers]]\nx = 50.0\ny = 0.0\nheading = 1e308\nlength = 1.0\nwidth = 1.0", "barriers.0.heading"),
    ("[impact]\npoint = [0.0, 0.0]\nplane_angle = 1e308", "", "impact.plane_angle"),
    # accepted before: ran with a spinning, a blown-up or an infinite vehicle
    ("", "yaw_rate = 1e308", "vehicles.V1.yaw_rate"),
    ("", "[[barriers]]\nx = 50.0\ny = 0.0\nlength = 1e30\nwidth = 1.0", "barriers.0.length"),
    ("", "[vehicles.overrides]\nmass = inf", "vehicles.V1.overrides.mass"),
    ("", "[vehicles.overrides]\nyaw_inertia = -inf", "vehicles.V1.overrides.yaw_inertia"),
    ("", "[vehicles.overrides]\ncornering_stiffness = inf", "vehicles.V1.overrides.cornering_stiffness"),
    ("", "[vehicles.overrides]\nmass = 1e30", "vehicles.V1.overrides.mass"),
    ("", "[vehicles.overrides]\nyaw_inertia = 1e-9", "vehicles.V1.overrides.yaw_inertia"),
    ("", "[vehicles.overrides.multibody.chassis]\nmass = inf", "vehicles.V1.overrides.multibody.chassis.mass"),
    ("[reference.pc.V1]\nx = 1e308", "", "reference.pc.V1.x"),
    ("[reference.pc.V1]\nhedaing = 30.0", "", "reference.pc.V1.hedaing"),  # a typo, ignored before
    # booleans are not numbers (true was a friction of 1.0, 1 a stop_at_rest)
    ("[road]\nfriction = true", "", "road.friction"),
    ("[impact]\nfriction = true", "", "impact.friction"),
    ("stop_at_rest = 1", "", "stop_at_rest"),
    ("", "steer = true", "vehicles.V1.steer"),
    ("", "[vehicles.overrides]\nmass = true", "vehicles.V1.overrides.mass"),
])
def test_scene_numbers_finite_and_bounded(tmp_path, capsys, top, extra, key):
    f = tmp_path / "s.toml"
    f.write_text(scene_text(extra, top))
    refused(capsys, f, key)


@pytest.mark.parametrize("key, bad", [("mass", "inf"), ("mass", "true"), ("yaw_inertia", "1e-9"),
                                      ("track", "1.9"), ("cg_height", "2.0"), ("wheel_radius", "nan"),
                                      ("track", "0.01")])
def test_a_vehicle_file_and_an_override_pass_the_same_checks(tmp_path, capsys, key, bad):
    """The same bad value in a vehicle file (blamed on the vehicle file) and as an override of a good file
    (blamed on the scene, vehicles.V1.overrides.KEY) gives the same problem."""
    good = (REPO / "framework" / "vehicles" / "clio.toml").read_text()
    line = next(s for s in good.splitlines() if s.startswith(f"{key} ="))
    (tmp_path / "bad.toml").write_text(good.replace(line, f"{key} = {bad}"))
    (tmp_path / "good.toml").write_text(good)
    f1, f2 = tmp_path / "s1.toml", tmp_path / "s2.toml"
    f1.write_text(scene_text().replace('"clio"', '"bad.toml"'))
    override = scene_text(f"[vehicles.overrides]\n{key} = {bad}")
    f2.write_text(override.replace('"clio"', '"good.toml"'))
    in_file = refused(capsys, tmp_path / "bad.toml", key, "simulate", f1)
    in_override = refused(capsys, f2, f"vehicles.V1.overrides.{key}")
    assert in_file.split(f": {key}: ")[1] == in_override.split(f".{key}: ")[1]


@pytest.mark.parametrize("overrides, key, words", [
    ("track = 0.01", "track", ["0.5 x the width"]),          # the impulse model divided by zero (a traceback)
    ("track = 0.2", "track", ["0.5 x the width"]),           # ran quietly: rest 1 m short, 15 deg off
    ("track = 0.85\ncg_height = 1.5\nheight = 3.0", "track", ["tip over at 0.28 g"]),
    ("wheelbase = 0.05\ncg_to_front_axle = 0.02", "wheelbase", ["0.3 x the length"]),  # "the state became NaN"
])
def test_the_wheels_layout_against_the_body_is_checked(tmp_path, capsys, overrides, key, words):
    """A probe (2026-11-28): a track or wheelbase of centimetres passed every check (track > 0, <= width) and the
    impulse model raised ZeroDivisionError, failed with a NaN state or ran quietly. Refused in one line naming
    the key; the library's 20 vehicles pass (track 0.82-0.88 x width, track / 2 cg_height 0.91-1.44,
    wheelbase 0.49-0.65 x length)."""
    f = tmp_path / "s.toml"
    f.write_text(scene_text(f"[vehicles.overrides]\n{overrides}"))
    line = refused(capsys, f, f"vehicles.V1.overrides.{key}")
    for w in words:
        assert w in line, line


def test_a_source_of_no_key_is_refused(tmp_path, capsys):
    """[sources] wheelbse = "..." was accepted quietly (a probe, 2026-11-28): the wheelbase it meant had no
    source. In a vehicle file and in a scene's overrides alike; a model's own table (multibody) may have one."""
    good = (REPO / "framework" / "vehicles" / "clio.toml").read_text()
    assert "\nmultibody = " in good  # a table's entry, accepted
    (tmp_path / "bad.toml").write_text(good.replace("[sources]\n", "[sources]\nwheelbse = \"typo\"\n", 1))
    f1, f2 = tmp_path / "s1.toml", tmp_path / "s2.toml"
    f1.write_text(scene_text().replace('"clio"', '"bad.toml"'))
    f2.write_text(scene_text("[vehicles.overrides.sources]\nmas = \"typo\""))
    assert "did you mean 'wheelbase'" in refused(capsys, tmp_path / "bad.toml", "sources.wheelbse", "simulate", f1)
    assert "did you mean 'mass'" in refused(capsys, f2, "vehicles.V1.overrides.sources.mas")


def test_a_file_of_another_kind_is_named_as_such(tmp_path, capsys):
    """A vehicle file given to simulate (or infer), a study whose scene is a study, a scene's vehicle that is a
    scene: the schema said "class: unknown key", "scene: unknown key", "duration: unknown key" (a probe,
    2026-11-28). One line saying what the file is."""
    veh = tmp_path / "veh.toml"
    veh.write_text((REPO / "framework" / "vehicles" / "clio.toml").read_text())
    assert "this is a vehicle file" in refused(capsys, veh, "(top level)", "simulate", veh)
    assert "study file" in refused(capsys, veh, "(top level)", "infer", veh, "--out", tmp_path / "o")
    scene = tmp_path / "s.toml"
    scene.write_text(scene_text())
    study = tmp_path / "study.toml"
    text = (REPO / "studies" / "reconstruction" / "twin1.toml").read_text()
    study.write_text(re.sub(r'(?m)^scene = ".*"$', 'scene = "study.toml"', text))
    assert "this is a study file" in refused(capsys, study, "(top level)", "reconstruct", study)
    car = tmp_path / "car.toml"
    car.write_text(scene.read_text().replace('"clio"', '"s.toml"'))
    assert "this is a scene file" in refused(capsys, scene, "(top level)", "simulate", car)


def test_mass_override_refused_when_the_inertias_are_not_scaled(tmp_path, capsys):
    """3000 kg on the Clio's inertias is a plausible (dense) car; 60 t on them is a radius of gyration of
    14 cm about the yaw axis (0.03 x the diagonal): refused, naming the overridden key."""
    f = tmp_path / "s.toml"
    f.write_text(scene_text("[vehicles.overrides]\nmass = 3000.0"))
    assert crashlab.load_scene(f).vehicles[0].spec.mass == 3000.0
    f.write_text(scene_text("[vehicles.overrides]\nmass = 60000.0"))
    line = refused(capsys, f, "vehicles.V1.overrides.mass")
    assert "yaw_inertia" in line and "radius of gyration" in line


def test_bad_scene_of_a_study_is_refused_at_load(tmp_path):
    """The scene's checks run when the study loads, before any search."""
    scene = tmp_path / "scene.toml"
    scene.write_text(SIDE.read_text().replace("heading = 90.0", "heading = 1e308"))
    study = tmp_path / "study.toml"
    study.write_text(STUDY.format(free=FREE_SPEED, extra="").replace(SIDE.as_posix(), scene.as_posix()))
    with pytest.raises(crashlab.InputError) as err:
        load_study(study)
    assert err.value.file == str(scene) and err.value.key == "vehicles.V2.heading"


def test_an_input_error_is_one_line():
    """A key or value with a line break (quoted TOML keys may hold one) is shown escaped."""
    err = crashlab.InputError("s.toml", 'vehicles.0."a\nb"', "unknown key\n")
    assert "\n" not in str(err) and str(err) == 's.toml: vehicles.0."a\\nb": unknown key\\n'


# ---------------------------------------------------------------- zero friction (ice; an isolated impact)
def ice_scene(make_scene, wheels):
    """Two Clios head-on on a frictionless road, impact friction 0: after the impact nothing acts on them."""
    return make_scene([{"speed": 50.0, "wheels": wheels, "overrides": {"rolling_resistance": 0.0}},
                       {"x": 6.0, "heading": 180.0, "speed": 20.0, "wheels": wheels,
                        "overrides": {"rolling_resistance": 0.0, "mass": 1500.0, "yaw_inertia": 1700.0}}],
                      road={"friction": 0.0}, duration=2.0,
                      impact={"friction": 0.0, "restitution": 0.3, "force_law": "exact-restitution"})


def test_zero_friction_is_accepted(make_scene):
    sc = ice_scene(make_scene, "locked")
    assert sc.road.friction == 0.0 and sc.impact.friction == 0.0


ICE_CASES = [(m, w) for m in ("impulse", "pymunk") for w in ("rolling", "locked", "braked")]
ICE_CASES += [pytest.param(m, w, marks=pytest.mark.slow)
              for m in ("multibody", "exudyn") for w in ("rolling", "locked")]


@pytest.mark.parametrize("model, wheels", ICE_CASES)
def test_on_ice_the_vehicles_keep_moving(make_scene, model, wheels):
    """Road friction 0: no force but the impact's. Central head-on impact, e = 0.3, m1 = 980, m2 = 1500 kg:
    v1' = (m1 v1 + m2 v2 - m2 e (v1 - v2)) / (m1 + m2), v2' = v1' + e (v1 - v2) (v2 = -20 km/h), both still
    moving at the end of the run, total momentum conserved."""
    sc = ice_scene(make_scene, wheels)
    out = crashlab.get_model(model).simulate(sc)
    m1, m2, v1, v2, e = 980.0, 1500.0, 50 / 3.6, -20 / 3.6, 0.3
    v1p = (m1 * v1 + m2 * v2 - m2 * e * (v1 - v2)) / (m1 + m2)
    v2p = v1p + e * (v1 - v2)
    vx = out.final_si[:, 0]
    assert m1 * vx[0] + m2 * vx[1] == pytest.approx(m1 * v1 + m2 * v2, rel=1e-3)
    assert vx == pytest.approx([v1p, v2p], abs=0.02 * abs(v1 - v2))
    assert np.all(np.abs(out.final_si[:, 1]) < 1e-6 + 0.01 * abs(v1 - v2))
    assert not out.rest["at_rest"].any()


@pytest.mark.parametrize("extra, key, expected", [
    ("steer = 200.0", "vehicles.V1.steer", "less than or equal to 45 deg, got 200.0"),
    ("heading = 1e308", "vehicles.V1.heading", " deg, got 1e+308"),
    ("[vehicles.overrides]\nyaw_inertia = -5.0", "vehicles.V1.overrides.yaw_inertia",
     "greater than 0 kg m^2, got -5.0"),
    ("[vehicles.overrides]\nwheelbase = -1.0", "vehicles.V1.overrides.wheelbase", "greater than 0 m, got -1.0"),
])
def test_a_range_error_gives_the_bound_in_the_keys_unit(tmp_path, capsys, extra, key, expected):
    """Issue 26 item 5: a bound is read in the key's unit (its description's, as in docs/reference.md), with the
    value the file gave: '400' alone does not say km/h or m/s."""
    f = tmp_path / "s.toml"
    f.write_text(scene_text(extra))
    assert refused(capsys, f, key).endswith(expected)


def test_a_misspelt_required_key_is_named_as_the_typo():
    """`sigma_stiffnes` for the required sigma_stiffness is both an unknown key and a missing one: the one line names
    the typo with the key meant (before 2026-11-27 it said only "sigma_stiffness: missing key")."""
    from pydantic import ValidationError

    from crashlab.damage import DamageEvidence
    from crashlab.input_files import pydantic_error
    with pytest.raises(ValidationError) as err:
        DamageEvidence.model_validate({"side": "front", "profile": [0.1, 0.2], "width": 1.5, "sigma_crush": 0.02,
                                       "sigma_stiffnes": 0.1})
    text = str(pydantic_error("study.toml", err.value, "evidence.damage.V1.", DamageEvidence))
    assert "evidence.damage.V1.sigma_stiffnes" in text and "did you mean 'sigma_stiffness'" in text, text
