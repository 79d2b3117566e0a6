"""Restitution as a law of the closing speed, `[impact] restitution = "speed"` (docs/physics.md §13b):
the law against the published regression written here independently, each model's outcome following it,
and the bad input."""
from __future__ import annotations

import math
from types import SimpleNamespace

import pytest
from conftest import PC_CRASH, assert_one_error_line

from crashlab.restitution import restitution_at, speed_restitution
from crashlab.scene import Impact

KMH = 1 / 3.6


def cipriani_mph(closing_mph):
    """Cipriani et al. 2002 (SAE 2002-01-0540) in the form it is usually quoted: closing speed in mph, the
    log of the speed in m/s (1 mph = 0.44704 m/s)."""
    lg = math.log10(closing_mph * 0.44704)
    return 0.47477 - 0.26139 * lg + 0.03382 * lg ** 2 - 0.11639 * lg ** 3


@pytest.mark.parametrize("mph", [2.5, 5.0, 8.0, 12.0, 17.0])
def test_law_is_the_published_regression(mph):
    assert speed_restitution(mph * 0.44704) == pytest.approx(cipriani_mph(mph), abs=1e-12)


def test_law_held_at_its_ends_with_a_warning():
    """Outside 1..8 m/s the end value, with the reason; within, no warning; a constant is itself."""
    imp = Impact(restitution_law="speed")
    e_hi, why = restitution_at(57 * KMH, imp)  # NHTSA 10146's barrier speed
    assert e_hi == pytest.approx(cipriani_mph(8.0 / 0.44704), abs=1e-12) and "outside" in why
    e_lo, why = restitution_at(0.5, imp)
    assert e_lo == pytest.approx(cipriani_mph(1.0 / 0.44704), abs=1e-12) and "outside" in why
    assert restitution_at(4.0, imp)[1] is None
    assert restitution_at(4.0, Impact(restitution=0.25)) == (0.25, None)


def _barrier_scene(make_scene, kmh, restitution="speed"):
    return make_scene([{"speed": kmh, "overrides": {"rolling_resistance": 0.0}}],
                      impact={"restitution": restitution, "friction": 0.3},
                      barriers=[{"x": 5.0, "y": 0.0, "heading": 0.0, "length": 1.0, "width": 4.0}],
                      duration=1.5)


@pytest.mark.parametrize("kmh", [10.0, 25.0])
def test_impulse_barrier_rebound_follows_the_law(impulse_model, make_scene, kmh):
    """Central impact into a rigid barrier: rebound / approach speed = e(closing speed) within 1e-6
    (the impact is one instantaneous impulse; the row's delta-V is -(1 + e) v)."""
    out = impulse_model.simulate(_barrier_scene(make_scene, kmh))
    assert out.outcome_ok and not out.warnings, out.warnings
    row = out.impacts.iloc[0]
    e = -row.dvx / kmh - 1.0
    assert e == pytest.approx(cipriani_mph(kmh / 3.6 / 0.44704), abs=1e-6)


def test_impulse_warns_outside_the_law(impulse_model, make_scene):
    out = impulse_model.simulate(_barrier_scene(make_scene, 57.0))
    assert any("outside the data of the law" in w for w in out.warnings), out.warnings
    row = out.impacts.iloc[0]
    assert -row.dvx / 57.0 - 1.0 == pytest.approx(cipriani_mph(8.0 / 0.44704), abs=1e-6)


def test_bad_restitution_word(tmp_path, capsys):
    """restitution = "fast": `crashlab simulate` exits 2 with one line naming the file and impact.restitution."""
    from crashlab.cli import main
    src = (PC_CRASH / "head_on.toml").read_text()
    path = tmp_path / "fast.toml"
    path.write_text(src.replace("restitution = 0.1", 'restitution = "fast"'))
    assert 'restitution = "fast"' in path.read_text()
    code = main(["simulate", str(path)])
    captured = capsys.readouterr()
    assert_one_error_line(SimpleNamespace(returncode=code, stdout=captured.out, stderr=captured.err), path,
                          "impact.restitution", words=('"speed"',))


def test_a_number_set_on_the_field_replaces_the_law(make_scene):
    """A restitution drawn or searched as a field (crashlab.fields) is a constant: the law is off."""
    from crashlab.fields import set_field
    scene = _barrier_scene(make_scene, 20.0)
    assert scene.impact.restitution_law == "speed"
    changed = set_field(scene, "impact.restitution", 0.3)
    assert (changed.impact.restitution, changed.impact.restitution_law) == (0.3, "constant")


def test_the_generic_3d_contact_law_warns_that_it_keeps_a_constant():
    """multibody / exudyn with contact_law = "generic" cannot follow the law (its damping is set once): it says so."""
    from crashlab.models.common.crush_structure import speed_law_setting
    assert speed_law_setting(Impact(restitution_law="speed"), "structure", None) is None
    assert 'contact_law = "structure"' in speed_law_setting(Impact(restitution_law="speed"), "generic", None)
    assert speed_law_setting(Impact(restitution=0.9), "structure", "clamped") == "clamped"
    assert speed_law_setting(Impact(restitution=0.9), "generic", "clamped") is None


@pytest.mark.parametrize("model", ["multibody", "exudyn"])
def test_the_generic_law_run_says_only_that_it_keeps_the_constant(model):
    """A head-on at 50/50 km/h (closing 100 km/h) with contact_law = "generic" and restitution = "speed": the run
    warns that the constant is kept, and no more: before 2026-11-27 it also said the law was held at its end value
    e = 0.475 at a closing speed of 0.0 km/h (the generic law never sets the pair's closing speed), neither of
    which was so."""
    import sys
    from pathlib import Path
    sys.path.insert(0, str(Path(__file__).parent))
    from conftest import build_scene

    from crashlab.registry import get_model
    sc = build_scene([{"vehicle": "saloon", "speed": 50.0},
                      {"vehicle": "saloon", "x": 5.2, "heading": 180.0, "speed": 50.0}],
                     impact={"restitution": "speed"}, duration=1.0)
    out = get_model(model, contact_law="generic").simulate(sc)
    assert out.outcome_ok
    law = [w for w in out.warnings if "restitution" in w]
    assert len(law) == 1 and 'needs contact_law = "structure"' in law[0], out.warnings


def test_numbers_drawn_or_searched_for_the_restitution_say_they_replace_the_law(tmp_path):
    """A scene with restitution = "speed" whose [[uncertain]] (or a study's [[free]]) restitution replaces the law
    in every run (the test above) said nothing of it (a fuzzer): the uncertain entry's description and the
    study's notes say it now; with a number in the scene they say nothing more."""
    import crashlab
    from crashlab.reconstruction import load_study
    src = (PC_CRASH / "side.toml").read_text()
    unc = '\n[[uncertain]]\nfield = "impact.restitution"\ndistribution = "uniform"\nlower = 0.1\nupper = 0.3\n'
    for law, said in (('"speed"', True), ("0.1", False)):
        scene_path = tmp_path / f"side_{said}.toml"
        scene_path.write_text(src.replace("restitution = 0.1", f"restitution = {law}", 1) + unc)
        (u,) = crashlab.load_scene(scene_path).uncertain
        assert ('replace the scene\'s restitution = "speed"' in u.describe()) is said
        study = tmp_path / f"study_{said}.toml"
        study.write_text(f'scene = "{scene_path.as_posix()}"\nmodel = "impulse"\n[[free]]\nfield = "restitution"\n'
                         "lower = 0.05\nupper = 0.4\n[[free]]\nvehicle = \"V1\"\nfield = \"speed\"\nlower = 30.0\n"
                         "upper = 70.0\n[evidence.rest.V1]\nx = 10.0\ny = 0.0\nheading = 0.0\nsigma_xy = 1.0\n"
                         "sigma_heading = 10.0\n")
        notes = load_study(study).notes
        assert any('replace the scene\'s restitution = "speed"' in n for n in notes) is said, notes
