"""Issue 24's features used from the command line as a reconstructionist would (the user pass of 2026-11-27):
damage evidence no run can score is named, not a traceback or a silent Pareto set of failed objectives; a law
used outside its data (restitution = "speed") is said by reconstruct and infer; the damage evidence's warnings
reach the terminal; a profile whose first depth is negative is one line naming the key."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from conftest import FREE_SPEEDS, assert_one_error_line

REPO = Path(__file__).resolve().parent.parent
SIDE = REPO / "studies" / "pc_crash" / "side.toml"  # V1's front strikes V2's left side (about 50 / 30 km/h)
SEARCH = ('[optimizer]\nname = "nsga2"\npop_size = 8\ngenerations = 1\nseed = 1\n[polish]\nevaluations = 30\n'
          '[execution]\nbackend = "serial"\n')
INFER = "[infer]\nsamples = 40\nburn = 5\nwalkers = 8\nseed = 1\ndraws_plotted = 0\n[execution]\nbackend = \"serial\"\n"


def study(scene: Path, side: str = "front", profile: str = "[0.12, 0.20, 0.20, 0.15]", tail: str = SEARCH) -> str:
    return (f'scene = "{scene.as_posix()}"\nmodel = "impulse"\n{FREE_SPEEDS}'
            "[evidence.rest.V1]\nx = 6.66\ny = 1.64\nsigma_xy = 0.5\n"
            f'[evidence.damage.V1]\nside = "{side}"\nprofile = {profile}\nwidth = 1.2\nsigma_crush = 0.02\n'
            f"sigma_stiffness = 0.15\n{tail}")


def crashlab(*args, timeout=300):
    return subprocess.run([sys.executable, "-m", "crashlab.cli", *map(str, args)], capture_output=True, text=True,
                          timeout=timeout)


def test_reconstruct_names_damage_on_a_side_no_run_strikes(tmp_path):
    """Damage on V1's rear where every run strikes its front: before, the polish raised ValueError ("Residuals are
    not finite in the initial point", exit 1) or, without a polish, every objective was 1000 with exit 0."""
    path = tmp_path / "rear.toml"
    path.write_text(study(SIDE, side="rear"))
    res = crashlab("reconstruct", path, "--no-progress", "--out", tmp_path / "out")
    assert "Traceback" not in res.stderr, res.stderr
    assert res.returncode == 4, (res.returncode, res.stderr)
    # the item named (it said "evidence.damage.<vehicle>.side" until 2026-11-28, where infer names it)
    assert "check evidence.damage.V1.side (rear);" in res.stderr.strip().splitlines()[-1]
    assert "strikes V1 on its front, not on its rear" in (tmp_path / "out" / "summary.md").read_text()


def test_infer_names_damage_on_a_side_no_run_strikes(tmp_path):
    path = tmp_path / "rear.toml"
    path.write_text(study(SIDE, side="rear", tail=INFER))
    res = crashlab("infer", path, "--no-progress", "--out", tmp_path / "out")
    assert_one_error_line(res, path, "evidence.damage.V1.side", ["front"])


def test_speed_restitution_outside_its_data_is_said_by_reconstruct_and_infer(tmp_path):
    """side.toml closes at 50 km/h, outside Cipriani's 3.6-28.8 km/h (docs/physics.md §13b): simulate warns; the
    searches ran the same law in silence before."""
    scene = tmp_path / "side_speed.toml"
    text = SIDE.read_text()
    assert "restitution = 0.1" in text
    scene.write_text(text.replace("restitution = 0.1", 'restitution = "speed"', 1))
    for command, tail in (("reconstruct", SEARCH), ("infer", INFER)):
        path = tmp_path / f"{command}.toml"
        path.write_text(study(scene, tail=tail))
        out = tmp_path / f"out_{command}"
        res = crashlab(command, path, "--no-progress", "--out", out)
        assert res.returncode == 0, res.stderr
        assert "outside the data of the law" in (out / "summary.md").read_text(), command
        assert "outside the data of the law" in (out / "report.html").read_text(), command
        assert "outside the data of the law" in res.stderr, command


def test_damage_evidence_warnings_reach_the_terminal(tmp_path):
    """A profile without residual crush gives an upper bound only (docs/physics.md §28): said on stderr."""
    path = tmp_path / "zero.toml"
    path.write_text(study(SIDE, profile="[0.0, 0.0, 0.0, 0.0]"))
    res = crashlab("reconstruct", path, "--no-progress")
    assert f"crashlab: warning: {path}: evidence.damage.V1: no residual crush" in res.stderr, res.stderr


@pytest.mark.parametrize("option", ["--profile", "--prof"])
def test_a_negative_first_crush_depth_is_one_line_naming_the_key(option):
    """argparse took "-0.1,0.2" for an option and printed its usage; now crashlab.damage refuses it by name, also
    after an abbreviation of the option (argparse's allow_abbrev; it gave the usage before 2026-11-27)."""
    res = crashlab("damage", "saloon", "--side", "front", option, "-0.1,0.2", "--width", "1.0")
    assert_one_error_line(res, "command line", "--profile[1]", ["negative"])


@pytest.mark.parametrize("argv, key", [
    (["--with", "clio:front:0.3,0.3:1.5", "--with", "saloon:front:0.3,0.3:1.5"], "--with"),
    (["--prof", "0.1,0.1"], "--profile")])
def test_an_option_given_twice_is_one_line_naming_it(argv, key):
    """The last of two --with (or --profile and --prof) won silently before 2026-11-27: the first vehicle dropped."""
    res = crashlab("damage", "clio", "--side", "front", "--profile", "0.3,0.3", "--width", "1.5", *argv)
    assert_one_error_line(res, "command line", key, ["given twice"])
