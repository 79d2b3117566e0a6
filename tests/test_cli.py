"""The command line (README.md): models, simulate [--json] [--plot], compare [--json] [--plot] (one JSON shape
for both), help and defaults of every option, units in the printed headers, headings wrapped where a pose is
meant and continuous where a turn is, and bad input: status 2, one line on stderr naming the file and the key,
never a traceback."""
from __future__ import annotations

import json
import subprocess
import sys

import pytest


def run(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "crashlab.cli", *map(str, args)], capture_output=True,
                          text=True, timeout=300, cwd=cwd)


def main_out(capsys, *args):
    """crashlab.cli.main in this process (no interpreter start-up): (exit status, stdout)."""
    from crashlab.cli import main
    code = main([str(a) for a in args])
    return code, capsys.readouterr().out


def test_models_lists_impulse():
    res = run("models")
    assert res.returncode == 0, res.stderr
    first = res.stdout.splitlines()[0]
    assert first.startswith("models:") and "impulse" in first.split(":", 1)[1].replace(",", " ").split()


def test_simulate_json_shape(pc_crash_dir):
    res = run("simulate", pc_crash_dir / "head_on.toml", "--json")
    assert res.returncode == 0, res.stderr
    data = json.loads(res.stdout)
    assert set(data) == {"scene", "results", "references", "comparison", "spread", "units"}
    assert data["spread"] == []  # one model: no spread between models
    assert data["scene"] == {"name": "Head-on collision with a stopped car", "file": str(pc_crash_dir / "head_on.toml")}
    assert len(data["results"]) == 1
    result = data["results"][0]
    assert result["model"] == "impulse"
    assert set(result["vehicles"]) == {"V1", "V2"}
    rest = result["vehicles"]["V1"]["rest"]
    assert set(rest) == {"x", "y", "heading", "heading_continuous", "yaw_turned", "speed", "at_rest"}
    # PC-Crash's case 1 compares positions at 5 s of free-rolling cars: an end pose, not a rest pose
    assert rest["at_rest"] is False and rest["speed"] == pytest.approx(22.5, rel=1e-6)
    assert rest["x"] == pytest.approx(32.14, abs=0.5), "the same result as the Python API"
    assert result["vehicles"]["V2"]["final_velocity"]["vx"] == pytest.approx(27.5, rel=0.005)
    assert isinstance(result["impacts"], list) and len(result["impacts"]) == 2
    assert {"t", "vehicle", "other", "dvx", "dvy", "delta_v", "energy", "kind"} <= set(result["impacts"][0])
    assert result["wall_time_s"] >= 0 and result["ok"] is True
    assert {"x", "heading", "yaw_turned", "impacts.delta_v"} <= set(data["units"])
    # the rows of the comparison table: the model's and the published ones
    assert {(r["source"], r["vehicle"]) for r in data["comparison"]} >= {("impulse", "V1"), ("pc_crash", "V1")}


def test_compare_json_has_the_shape_of_simulate_json_with_a_result_per_model(pc_crash_dir, capsys):
    sim = json.loads(main_out(capsys, "simulate", pc_crash_dir / "side.toml", "--json")[1])
    code, text = main_out(capsys, "compare", pc_crash_dir / "side.toml", "--models", "impulse,pymunk", "--json")
    assert code == 0
    cmp = json.loads(text)
    assert set(cmp) == set(sim) and cmp["units"] == sim["units"] and cmp["references"] == sim["references"]
    assert [r["model"] for r in cmp["results"]] == ["impulse", "pymunk"]
    assert set(cmp["results"][1]) == set(sim["results"][0])
    assert cmp["results"][0]["vehicles"] == sim["results"][0]["vehicles"], "the same run, the same numbers"
    row = next(r for r in cmp["comparison"] if (r["source"], r["vehicle"]) == ("pymunk", "V2"))
    ref = cmp["references"]["pc_crash"]["V2"]
    rest = cmp["results"][1]["vehicles"]["V2"]["rest"]
    assert row["d_pc_crash_m"] == pytest.approx(((rest["x"] - ref["x"]) ** 2 + (rest["y"] - ref["y"]) ** 2) ** 0.5,
                                                abs=1e-5)


TURNED = """name = "turned twice"
duration = 10.0
[[vehicles]]
name = "V1"
vehicle = "clio"
heading = HEADING
speed = 50.0
wheels = "locked_after_impact"
[[vehicles]]
name = "V2"
vehicle = "clio"
x = 3.5
heading = 90.0
speed = 30.0
wheels = "locked_after_impact"
"""


def test_headings_print_wrapped_and_turns_continuous(tmp_path, capsys):
    """`heading = 720` is the run of `heading = 0` (two whole turns): the rest heading prints wrapped to
    (-180, 180] and equal to the heading-0 run's, the turn since the start prints the same; only the JSON's
    heading_continuous carries the 720."""
    runs = {}
    for h in (0.0, 720.0):
        path = tmp_path / f"h{h:g}.toml"
        path.write_text(TURNED.replace("HEADING", str(h)))
        code, table = main_out(capsys, "simulate", path)
        assert code == 0
        header = next(line for line in table.splitlines() if "heading" in line)
        assert "heading [deg, -180..180]" in header and "yaw turned [deg]" in header
        row = next(line for line in table.splitlines() if line.split()[:1] == ["V1"]).split()
        data = json.loads(main_out(capsys, "simulate", path, "--json")[1])["results"][0]["vehicles"]["V1"]["rest"]
        runs[h] = (float(row[3]), float(row[4]), data)
    (w0, turn0, d0), (w720, turn720, d720) = runs[0.0], runs[720.0]
    assert -180 < w720 <= 180 and w720 == pytest.approx(w0, abs=1e-3) and turn720 == pytest.approx(turn0, abs=1e-3)
    assert d720["heading"] == pytest.approx(d0["heading"], abs=1e-6)
    assert d720["heading_continuous"] == pytest.approx(d0["heading_continuous"] + 720.0, abs=1e-6)
    assert d720["yaw_turned"] == pytest.approx(d0["yaw_turned"], abs=1e-6)


def test_simulate_and_compare_print_units_in_every_header(pc_crash_dir, capsys):
    sim = main_out(capsys, "simulate", pc_crash_dir / "side.toml")[1]
    for h in ("x [m]", "y [m]", "speed [km/h]", "vx [km/h]", "vy [km/h]", "yaw_rate [deg/s]", "delta_v [km/h]",
              "energy [J]"):
        assert h in sim, h
    cmp = main_out(capsys, "compare", pc_crash_dir / "side.toml", "--wide")[1]
    header = next(line for line in cmp.splitlines() if line.split()[:2] == ["source", "vehicle"])
    for h in ("x [m]", "heading [deg, -180..180]", "yaw turned [deg]", "vx [km/h]", "d_pc_crash [m]",
              "d_pc_crash [deg]"):
        assert h in header, h
    narrow = main_out(capsys, "compare", pc_crash_dir / "side.toml", "--models", "impulse,pymunk")[1]
    lines = narrow.splitlines()
    assert max(map(len, lines)) <= 100, "the default tables fit 100 columns"
    poses = next(line for line in lines if line.split()[:2] == ["source", "vehicle"])
    diffs = next(line for line in lines if line.split()[:2] == ["model", "vehicle"])
    for h in ("x [m]", "y [m]", "heading [deg]", "turned [deg]", "v [km/h]", "at_rest"):
        assert h in poses, h
    for h in ("reference", "distance [m]", "heading [deg]"):
        assert h in diffs, h
    assert "nan" not in narrow.lower() and "-0.00" not in narrow and " 1 " not in narrow
    assert "true" in narrow and "True" not in narrow


def test_booleans_print_as_true_false_and_the_wrong_kind_of_file_is_named(pc_crash_dir, capsys):
    out = main_out(capsys, "models", "--options", "impulse")[1]
    row = next(line for line in out.splitlines() if line.startswith("broad_phase"))
    assert row.split()[2] == "true"
    from crashlab.cli import main

    def status_and_err(*args):
        code = main([str(a) for a in args])
        return code, capsys.readouterr().err
    code, err = status_and_err("simulate", pc_crash_dir.parent / "reconstruction" / "case5.toml")
    assert code == 2 and "this is a study file" in err and len(err.strip().splitlines()) == 1
    code, err = status_and_err("reconstruct", pc_crash_dir / "side.toml")
    assert code == 2 and "this is a scene file" in err
    code, err = status_and_err("compare", pc_crash_dir / "side.toml", "--models", "impulse,pymnk")
    assert code == 2 and "--models: unknown model 'pymnk'; did you mean 'pymunk'?" in err


def _subparsers(parser):
    import argparse
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return dict(action.choices)
    return {}


def test_every_option_has_help_and_shows_its_default():
    """Every argument of every command has help text; an option with a default shows it in --help."""
    import argparse

    from crashlab.cli import build_parser
    parser = build_parser()
    commands = _subparsers(parser)
    assert {"simulate", "compare", "bench", "stress", "models", "vehicles", "reconstruct", "infer", "study",
            "schema"} <= set(commands)
    for name, sub in [("crashlab", parser)] + sorted(commands.items()):
        text = sub.format_help()
        for action in sub._actions:
            if isinstance(action, (argparse._HelpAction, argparse._SubParsersAction)):
                continue
            assert action.help and action.help.strip(), f"{name} {action.dest}: no help"
            if action.option_strings and action.default not in (None, False, argparse.SUPPRESS):
                assert f"default: {action.default}" in " ".join(text.split()), f"{name} {action.dest}"
    simulate = " ".join(commands["simulate"].format_help().split())
    assert "(default: impulse)" in simulate and "(default: 25.0)" in simulate


def test_compare_plot_writes_png(pc_crash_dir, tmp_path, capsys):
    png = tmp_path / "cmp.png"
    assert main_out(capsys, "compare", pc_crash_dir / "side.toml", "--models", "impulse", "--plot", png)[0] == 0
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 1000


def test_simulate_plot_writes_png(pc_crash_dir, tmp_path):
    png = tmp_path / "side.png"
    res = run("simulate", pc_crash_dir / "side.toml", "--plot", png)
    assert res.returncode == 0, res.stderr
    assert png.stat().st_size > 1000
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_compare_shows_references(pc_crash_dir):
    res = run("compare", pc_crash_dir / "offset.toml", "--models", "impulse")
    assert res.returncode == 0, res.stderr
    lines = res.stdout.splitlines()
    assert any(line.split()[:2] == ["pc_crash", "V1"] for line in lines)
    assert any(line.split()[:2] == ["pc_crash", "V2"] for line in lines)
    assert any(line.split()[:2] == ["impulse", "V1"] for line in lines)
    assert any(line.split()[:3] == ["impulse", "V1", "pc_crash"] for line in lines), "the difference rows"
    assert "distance [m]" in res.stdout


SCENE = """name = "bad"
duration = 2.0
[[vehicles]]
name = "V1"
vehicle = "clio"
x = 0.0
speed = 50.0
"""
SECOND = """[[vehicles]]
name = "V2"
vehicle = "clio"
x = 3.0
heading = 180.0
"""

BAD = {
    # case: (file text or None for a missing file, extra CLI args, text the key part must contain)
    "malformed": (SCENE.replace('name = "bad"', 'name = "bad'), [], "(syntax)"),
    "missing_key": (SCENE.replace('vehicle = "clio"\n', ""), [], "vehicles.V1.vehicle"),
    "mistyped_key": (SCENE.replace("speed = 50.0", "sped = 50.0"), [], "vehicles.V1.sped"),
    "unknown_vehicle": (SCENE.replace('"clio"', '"clo"'), [], "vehicles.V1"),
    "unknown_model": (SCENE, ["--model", "impuls"], "--model"),
    "negative_mass": (SCENE + "[vehicles.overrides]\nmass = -1.0\n", [], "vehicles.V1.overrides.mass"),
    "overlap": (SCENE + SECOND, [], "vehicles"),
    "missing_file": (None, [], "scene"),
}


CASES = [("simulate", c) for c in sorted(BAD)] + [("compare", c) for c in ("malformed", "unknown_model",
                                                                          "overlap", "missing_file")]


@pytest.mark.parametrize("command, case", CASES)
def test_bad_input_one_line_status_2(tmp_path, case, command):
    text, extra, key = BAD[case]
    path = tmp_path / "scene.toml"
    if text is not None:
        path.write_text(text)
    if command == "compare":  # the option the user typed is the one named
        extra, key = (["--models", extra[1]], "--models") if extra else ([], key)
    res = run(command, path, *extra)
    assert res.returncode == 2, (res.stdout, res.stderr)
    assert "Traceback" not in res.stderr and "Traceback" not in res.stdout
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1, res.stderr
    line = lines[0]
    assert str(path) in line, "names the file"
    assert f": {key}: " in line, f"names the key {key}: {line}"
    if case in ("unknown_vehicle", "unknown_model", "mistyped_key"):
        assert "did you mean" in line
