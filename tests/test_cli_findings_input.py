"""Input messages found by fuzzing the command line (fuzz round 15): a pattern a value does not match is named by
what it requires (the words of an enumeration, the value given), a file written in US units has a refused bound
said in its own units and values, and a model named twice by compare --models is refused. Each refusal one line
naming the file (or "command line") and the key, exit 2."""
from __future__ import annotations

import math
from pathlib import Path

import pytest
from conftest import assert_refused_with_one_line
from pydantic import BaseModel, Field, ValidationError
from test_cli_input_findings import refused

from crashlab.input_files import pydantic_error
from crashlab.scene_file import load_scene
from crashlab.tools.examples import path as example

REPO = Path(__file__).resolve().parent.parent
SIDE = example("pc_crash/side.toml")
STUDY_SCENE = REPO / "studies" / "pc_crash" / "side.toml"


# ------------------------------------------------------------------ 1: a pattern's message says what it requires
class _Patterned(BaseModel):
    keep: str = Field("position", pattern="^(position|arrival)$")
    code: str = Field("A1", pattern=r"^[A-Z][0-9]$")


def _problem(**values) -> str:
    with pytest.raises(ValidationError) as err:
        _Patterned.model_validate(values)
    return pydantic_error("study.toml", err.value, "counterfactuals.0.", _Patterned).problem


def test_an_enumeration_pattern_names_its_words_and_the_value():
    """keep = "nowhere" against ^(position|arrival)$ was "no control characters (line breaks, tabs) allowed"."""
    assert _problem(keep="nowhere") == "one of position, arrival, got 'nowhere'"


def test_another_pattern_is_named_with_the_value():
    assert _problem(code="a1") == r"must match the pattern ^[A-Z][0-9]$, got 'a1'"


def test_a_name_with_a_control_character_still_says_so(tmp_path):
    scene = tmp_path / "scene.toml"
    scene.write_text(SIDE.read_text().replace('name = "V1"', 'name = "V\\t1"', 1))
    assert_refused_with_one_line(load_scene, scene, "vehicles.0.name", ["no control characters"])


def test_a_studys_keep_names_the_choices_and_the_value(tmp_path, capsys):
    """The fuzzer's case: [[counterfactuals]] keep = "nowhere" (a Literal now: its message gives the value too)."""
    text = (REPO / "studies" / "infer" / "twin_infer.toml").read_text().replace(
        'scene = "../pc_crash/side.toml"', f'scene = "{STUDY_SCENE.as_posix()}"')
    study = tmp_path / "study.toml"
    study.write_text(text + '\n[[counterfactuals]]\nname = "slower"\nset = { "vehicles.V1.speed" = 40.0 }\n'
                     'keep = "nowhere"\n')
    refused(capsys, study, "counterfactuals.0.keep", "avoid", study, "--out", tmp_path,
            words=("position", "arrival", "got 'nowhere'"))


# ------------------------------------------------------------------ 3: a US file's bound in its own units
def us_scene(tmp_path, old: str, new: str) -> Path:
    text = SIDE.read_text()
    assert old in text
    scene = tmp_path / "us.toml"
    scene.write_text('units = "us"\n' + text.replace(old, new, 1))
    return scene


def test_a_us_speed_beyond_its_bound_is_said_in_mph(tmp_path):
    """speed = 300 (mph) was "less than or equal to 400 km/h, got 482.80320000000006"."""
    text = SIDE.read_text()
    speed = next(line for line in text.splitlines() if line.startswith("speed = "))
    scene = us_scene(tmp_path, speed, "speed = 300")
    assert_refused_with_one_line(load_scene, scene, "vehicles.V1.speed",
                                 ["less than or equal to 248.5 mph (400 km/h), got 300 mph"])


def test_a_us_override_beyond_its_bound_is_said_in_lb(tmp_path):
    """overrides.mass = 100 (lb) was "greater than or equal to 50 kg, got 45.35923700000001"; the lower bound
    110.23 lb is rounded up, so that a refused value (110.2) is below the bound shown."""
    for mass, shown in (("100", "100"), ("110.2", "110.2")):
        scene = us_scene(tmp_path, "[vehicles.overrides]\n", f"[vehicles.overrides]\nmass = {mass}\n")
        assert_refused_with_one_line(load_scene, scene, "vehicles.V1.overrides.mass",
                                     [f"greater than or equal to 110.3 lb (50 kg), got {shown} lb"])


def test_a_us_cross_field_check_says_its_numbers_are_si(tmp_path):
    """A check that joins several fields quotes the converted numbers: overrides.track = 80 (ft) was "track
    (24.384 m) must not exceed the width (1.64 m)" with nothing to say the file's 80 became 24.384."""
    scene = us_scene(tmp_path, "[vehicles.overrides]\n", "[vehicles.overrides]\ntrack = 80\n")
    assert_refused_with_one_line(load_scene, scene, "vehicles.V1.overrides.track",
                                 ["24.384 m", "numbers in SI units: the file's US values converted"])
    si = tmp_path / "si.toml"
    si.write_text(SIDE.read_text().replace("[vehicles.overrides]\n", "[vehicles.overrides]\ntrack = 24.384\n", 1))
    from crashlab.errors import InputError
    with pytest.raises(InputError) as err:
        load_scene(si)
    assert "US values" not in str(err.value)


def test_an_si_bound_is_said_as_before(tmp_path):
    scene = tmp_path / "si.toml"
    text = SIDE.read_text()
    speed = next(line for line in text.splitlines() if line.startswith("speed = "))
    scene.write_text(text.replace(speed, "speed = 500", 1))
    assert_refused_with_one_line(load_scene, scene, "vehicles.V1.speed",
                                 ["less than or equal to 400 km/h, got 500"])


def test_a_us_bound_is_rounded_towards_the_values_it_accepts():
    from crashlab.input_files import _towards
    x = 400 / 1.609344  # 248.548... mph
    assert _towards(x, up=False) == "248.5" and _towards(x, up=True) == "248.6"
    assert float(_towards(0.1 / 0.3048, up=True)) >= 0.1 / 0.3048 and _towards(0.0, up=True) == "0"
    assert math.isclose(float(_towards(60000 / 0.45359237, up=False)), 132277.3)


# ------------------------------------------------------------------ 4: a model named twice
@pytest.mark.parametrize("models", ["impulse,impulse", "impulse, impulse"])
def test_compare_refuses_a_model_named_twice(capsys, models):
    """compare --models impulse,impulse ran it once and exited 0."""
    refused(capsys, "command line", "--models", "compare", SIDE, "--models", models, words=["'impulse'", "twice"])


def test_study_refuses_a_model_named_twice(capsys, tmp_path):
    """crashlab study ran a model named twice twice (its rows doubled); refused as compare refuses it, before any
    run."""
    refused(capsys, "command line", "--models", "study", "scaling", "--models", "impulse,pymunk,impulse", "--out",
            tmp_path, words=["'impulse'", "twice"])


@pytest.mark.parametrize("units, value, words", [
    ("us", "300", ["248.5 mph (400 km/h), got 300 mph"]),
    ("si", "500", ["less than or equal to 400 km/h, got 500"]),
])
def test_a_references_bound_is_said_in_its_unit(tmp_path, units, value, words):
    """reference.pc_crash.V1.vx = 300 in a US scene said "less than or equal to 400, got 482.80320000000006" (a
    probe, 2026-11-28): the unit of a key under a table of the file's own names (source, vehicle) was not found."""
    text = SIDE.read_text().replace("[reference.pc_crash.V1]\n", f"[reference.pc_crash.V1]\nvx = {value}\n", 1)
    scene = tmp_path / "s.toml"
    scene.write_text(('units = "us"\n' if units == "us" else "") + text)
    assert_refused_with_one_line(load_scene, scene, "reference.pc_crash.V1.vx", words)


def test_a_typo_under_a_vehicles_evidence_gets_the_nearest_key(tmp_path):
    """evidence.rest.V1.sigma_xz said "unknown key" alone: the keys under a table of the file's own names (the
    vehicle) were not found for the suggestion (2026-11-28, with the unit above)."""
    from crashlab.reconstruction import load_study
    study = example("tutorial/study.toml")
    path = tmp_path / "typo.toml"
    path.write_text(study.read_text().replace("sigma_xy", "sigma_xz", 1)
                    .replace('scene = "scene.toml"', f'scene = "{(study.parent / "scene.toml").as_posix()}"'))
    assert_refused_with_one_line(load_study, path, "evidence.rest.V1.sigma_xz",
                                 ["unknown key; did you mean 'sigma_xy'?"])
