"""Input handling of the command line found by fuzzing it: each bad value is refused in one line on stderr naming
the file (or "command line") and the option, exit 2, before the run where it can be; a Monte Carlo whose every
draw failed exits 3 in one line; no option is accepted without effect; notes are in the chosen units; every file
written is named. Run in-process (crashlab.cli.main) with the impulse model and short runs."""
from __future__ import annotations

import gc
import warnings
from pathlib import Path

import pytest

from crashlab.cli import main
from crashlab.tools.examples import path as example

SIDE = example("pc_crash/side.toml")  # 10 s: both cars come to rest


def short_side(tmp_path: Path, extra: str = "", name: str = "side.toml") -> Path:
    """The bundled side collision cut to 0.5 s (both cars still moving at the end), with `extra` appended."""
    text = SIDE.read_text()
    assert "duration = 10.0" in text
    p = tmp_path / name
    p.write_text(text.replace("duration = 10.0", "duration = 0.5") + extra)
    return p


def run(capsys, *args):
    """(exit status, stdout, stderr lines) of crashlab.cli.main in this process."""
    code = main([str(a) for a in args])
    out, err = capsys.readouterr()
    return code, out, err.strip().splitlines()


def refused(capsys, where, key, *args, words=()):
    """The command refused in one line naming `where` and `key` (exit 2); that line."""
    code, out, err = run(capsys, *args)
    assert code == 2 and len(err) == 1, (code, out, err)
    assert err[0].startswith(f"crashlab: error: {where}: {key}: "), err
    for w in words:
        assert w in err[0], err
    return err[0]


# 1
@pytest.mark.parametrize("seed", [-1, 2**32])
def test_stress_refuses_a_seed_outside_what_numpy_takes(seed, capsys):
    """-1 was a numpy ValueError traceback; 2^32 was taken although simulate --seed refuses it."""
    refused(capsys, "command line", "--seed", "stress", "--runs", 0, "--seed", seed,
            words=("[0, 4294967295]", str(seed)))


@pytest.mark.parametrize("option, name", [("--plot", "x.png"), ("--animate", "x.gif"), ("--csv", "x.csv")])
def test_a_file_name_the_system_refuses_is_one_line(option, name, capsys):
    """A name of more than 255 bytes: Path.is_dir() raised OSError (a traceback, exit 1) in the checks made before
    the run (outdir.check_output_file)."""
    long = "y" * 300 + name
    args = ("stress", "--runs", 0, "--csv", long) if option == "--csv" else ("simulate", str(SIDE), option, long)
    refused(capsys, long, option, *args, words=("cannot write there",))


# 2
def test_examples_copy_under_a_file_is_one_line(tmp_path, capsys, monkeypatch):
    """A DIR under an ordinary file (NotADirectoryError) or where no folder can be made (FileNotFoundError under
    /proc) was a traceback."""
    monkeypatch.chdir(tmp_path)
    Path("afile").write_text("x")
    refused(capsys, "afile/sub", "examples copy DIR", "examples", "copy", "afile/sub", words=("Not a directory",))
    if Path("/proc/self").is_dir():
        refused(capsys, "/proc/crashlab-x", "examples copy DIR", "examples", "copy", "/proc/crashlab-x")


# 3
def test_animate_under_a_file_is_one_line_and_no_matplotlib_warning(tmp_path, capsys, monkeypatch):
    """The refusal came after the animation was built, and matplotlib's "Animation was deleted without rendering
    anything" followed the error line; now the path is refused before the run."""
    monkeypatch.chdir(tmp_path)
    Path("afile").write_text("x")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        refused(capsys, "afile/x.gif", "--animate", "simulate", short_side(tmp_path), "--animate", "afile/x.gif",
                words=("not a folder",))
        gc.collect()  # (the animation warns when it is collected)
    assert not [w for w in caught if "Animation" in str(w.message)], [str(w.message) for w in caught]


# 4: --plot refuses a name without a figure format's extension, as --animate refuses one without .gif/.mp4
# (--csv takes a folder); it wrote NAME.png and printed "wrote NAME"
@pytest.mark.parametrize("command", ["simulate", "compare"])
@pytest.mark.parametrize("name", ["afile", "folder"])
def test_plot_without_an_extension_is_refused(command, name, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    Path("afile").write_text("x")
    Path("folder").mkdir()
    refused(capsys, name, "--plot", command, short_side(tmp_path), "--plot", name,
            words=("no extension", ".png"))
    assert not list(tmp_path.glob("*.png"))


# 5
def test_monte_carlo_whose_every_draw_failed_exits_3(tmp_path, capsys):
    """0.5 s is too short for the cars to stop: every draw ends with both still moving, a failed draw. It printed
    nan medians "over the 0 draws" and exited 0."""
    scene = short_side(tmp_path, '\n[[uncertain]]\nfield = "road.friction"\ndistribution = "uniform"\n'
                       "lower = 0.6\nupper = 0.9\n")
    code, out, err = run(capsys, "simulate", scene, "--monte-carlo", 3)
    assert code == 3 and len(err) == 1, (code, out, err)
    assert err[0].startswith(f"crashlab: simulation failed: {scene}: model impulse: all 3 draws failed"), err
    assert "V1, V2 still moving at the end of the run" in err[0]
    assert "nan" not in out.lower()


# 6
@pytest.mark.parametrize("option, value", [("--fps", 10), ("--slow-motion", 2)])
def test_animation_options_without_animate_are_refused(option, value, tmp_path, capsys):
    refused(capsys, "command line", option, "simulate", short_side(tmp_path), option, value,
            words=("--animate",))


@pytest.mark.parametrize("args, key", [
    (["simulate", "SCENE", "--csv", ""], "--csv"),
    (["simulate", "SCENE", "--plot", ""], "--plot"),
    (["simulate", "SCENE", "--animate", ""], "--animate"),
    (["simulate", "MC", "--monte-carlo", 2, "--out", ""], "--out"),
    (["compare", "SCENE", "--plot", ""], "--plot"),
    (["stress", "--runs", 0, "--csv", ""], "--csv"),
    (["bench", "--scene", "", "--batch", 2, "--repeat", 1], "--scene"),
    (["reconstruct", "SCENE", "--out", ""], "--out"),
    (["infer", "SCENE", "--out", ""], "--out"),
    (["avoid", "SCENE", "--out", ""], "--out"),
])
def test_an_empty_path_is_refused(args, key, tmp_path, capsys, monkeypatch):
    """An empty path was taken as no option at all (--csv, --plot, --animate, --scene: the default scene) or as the
    current folder (--out; reconstruct, infer and avoid locked it before refusing their file, here a scene)."""
    monkeypatch.chdir(tmp_path)
    mc = short_side(tmp_path, '\n[[uncertain]]\nfield = "road.friction"\ndistribution = "uniform"\n'
                    "lower = 0.6\nupper = 0.9\n", name="mc.toml")
    args = [{"SCENE": short_side(tmp_path), "MC": mc}.get(a, a) for a in args]
    refused(capsys, "command line", key, *args)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mc.toml", "side.toml"]  # nothing written


@pytest.fixture
def study_runs(monkeypatch):
    """The pc_crash study's run replaced by a recorder of the models it was given (no study is run)."""
    import crashlab.comparison.pc_crash as pc_crash
    calls = []

    def fake(models, out, quick=False, system="si"):
        calls.append(models)
        return Path(out) / "pc_crash.md"
    monkeypatch.setattr(pc_crash, "run", fake)
    return calls


@pytest.mark.parametrize("models", ["", " , "])
def test_study_refuses_empty_models_as_compare_does(models, study_runs, tmp_path, capsys):
    """study --models "" ran every model; compare --models "" is refused."""
    line = refused(capsys, "command line", "--models", "study", "pc_crash", "--models", models, "--quick", "--out",
                   tmp_path / "out")
    assert "at least one model" in line and not study_runs
    refused(capsys, "command line", "--models", "compare", SIDE, "--models", models, words=("at least one model",))


def test_study_refuses_an_empty_out(study_runs, tmp_path, capsys, monkeypatch):
    """study --out "" wrote into the current folder."""
    monkeypatch.chdir(tmp_path)
    refused(capsys, "command line", "--out", "study", "pc_crash", "--models", "impulse", "--quick", "--out", "")
    assert not study_runs and not list(tmp_path.iterdir())


# 7
@pytest.mark.parametrize("option, value", [("--slow-motion", "inf"), ("--fps", "inf")])
def test_a_bad_animation_speed_names_its_option(option, value, tmp_path, capsys):
    """--slow-motion inf got past the check (1/inf = 0) and was refused as "--animate: fps and speed must be
    positive"; --fps inf was an OverflowError."""
    refused(capsys, "command line", option, "simulate", short_side(tmp_path), "--animate", tmp_path / "x.gif", option,
            value)
    assert not (tmp_path / "x.gif").exists()


@pytest.mark.parametrize("batch, repeat, key", [(0, 1, "--batch"), (2, 0, "--repeat")])
def test_bench_names_the_count_that_is_wrong(batch, repeat, key, capsys):
    refused(capsys, "command line", key, "bench", "--batch", batch, "--repeat", repeat, words=("at least 1",))


def test_bench_says_a_study_is_no_scene(capsys):
    """It said "scene: unknown key"; simulate says it is a study file."""
    study = example("reconstruction/case1.toml")
    refused(capsys, study, "(top level)", "bench", "--scene", study, "--batch", 2, "--repeat", 1,
            words=("study file", "bench"))


# 8
def test_the_end_pose_note_is_in_the_chosen_units(tmp_path, capsys):
    """The tables were in ft and mph, the note under them said "end pose (moving 14.1 km/h)"."""
    code, out, _ = run(capsys, "simulate", short_side(tmp_path), "--units", "us")
    notes = [line for line in out.splitlines() if "not a rest pose" in line]
    assert code == 0 and len(notes) == 2, out
    assert all("mph) at t = 0.50 s" in n and "km/h" not in n for n in notes), notes


# 9
def test_stress_names_the_csv_it_wrote(tmp_path, capsys):
    """Every other command says "wrote FILE"; stress --csv overwrote FILE silently."""
    csv = tmp_path / "st.csv"
    csv.write_text("old\n")
    code, out, err = run(capsys, "stress", "--runs", 0, "--csv", csv)
    assert code == 0 and f"wrote {csv}" in err, (out, err)
    assert csv.read_text().startswith("scene,")
