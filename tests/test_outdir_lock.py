"""`--out DIR` is locked while a run writes it (issue 27, crashlab.outdir): a second run, or a --resume of a
live run's folder, is refused with one line naming the live run's pid (exit 2); the lock of a run killed
with -9 does not block (the kernel released it) and is taken over with a note; a run that ends removes it."""
from __future__ import annotations

import importlib
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from conftest import assert_one_error_line
from test_reconstruction_truth import study_file

from crashlab.errors import InputError
from crashlab.outdir import LOCK_NAME, lock_out_dir

REPO = Path(__file__).resolve().parent.parent
HOLD = ("import sys, time\nfrom crashlab.outdir import lock_out_dir\n"
        "with lock_out_dir(sys.argv[1], 'test holder'):\n    print('held', flush=True)\n    time.sleep(600)\n")


def cli(*args, timeout=300):
    return subprocess.run([sys.executable, "-m", "crashlab.cli", *map(str, args)], capture_output=True,
                          text=True, timeout=timeout)


@pytest.fixture
def holder():
    """holder(DIR): a live process (its Popen) holding DIR's lock until the test ends."""
    procs = []

    def start(folder):
        proc = subprocess.Popen([sys.executable, "-c", HOLD, str(folder)], stdout=subprocess.PIPE, text=True)
        procs.append(proc)
        assert proc.stdout.readline().strip() == "held"
        return proc

    yield start
    for proc in procs:
        if proc.poll() is None:
            proc.kill()
        proc.wait(timeout=30)


def test_a_live_holder_refuses_a_second_writer_naming_its_pid(tmp_path, holder):
    proc = holder(tmp_path / "out")
    with pytest.raises(InputError) as err:
        with lock_out_dir(tmp_path / "out", "reconstruct"):
            pass
    line = str(err.value)
    print("\n" + line)
    assert line.startswith(f"{tmp_path / 'out'}: --out: another crashlab run is writing this folder (pid {proc.pid}, ")
    assert "crashlab test holder" in line and "\n" not in line
    assert (tmp_path / "out" / LOCK_NAME).is_file()  # the refused run leaves the holder's lock alone


def test_a_killed_holders_lock_is_taken_over_with_a_note(tmp_path, holder, capsys):
    proc = holder(tmp_path / "out")
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait(timeout=30)
    assert str(proc.pid) in (tmp_path / "out" / LOCK_NAME).read_text()  # the killed run's file is still there
    with lock_out_dir(tmp_path / "out", "reconstruct --resume"):
        assert (tmp_path / "out" / LOCK_NAME).read_text().startswith(f"{os.getpid()}\treconstruct --resume\t")
    note = capsys.readouterr().err
    print("\n" + note)
    assert note.count("\n") == 1 and f"pid {proc.pid}" in note and "taken over" in note
    assert not (tmp_path / "out" / LOCK_NAME).exists()  # a run that ends removes its lock


def test_re_entrant_in_one_process_and_released_after(tmp_path, capsys):
    out = tmp_path / "new"
    with lock_out_dir(out, "outer"):
        with lock_out_dir(out, "inner"):  # e.g. the command's lock and Study.run's
            assert (out / LOCK_NAME).read_text().split("\t")[1] == "outer"
        assert (out / LOCK_NAME).exists()  # still held by the outer
        (out / "result.csv").write_text("x\n")
    assert not (out / LOCK_NAME).exists() and (out / "result.csv").exists()
    with lock_out_dir(tmp_path / "empty", "refused early"):
        pass
    assert not (tmp_path / "empty").exists()  # a folder the run made and left empty is removed again
    with lock_out_dir(None):
        pass
    assert capsys.readouterr().err == ""


def test_an_out_that_is_a_file_is_one_line(tmp_path):
    (tmp_path / "f").write_text("")
    with pytest.raises(InputError, match=r"f: --out: "):
        with lock_out_dir(tmp_path / "f"):
            pass


def test_reconstruct_and_its_resume_refused_on_a_live_folder(tmp_path, holder):
    path = study_file(tmp_path, base="case3", pop_size=8, generations=2)  # no twin: no simulation at load
    proc = holder(tmp_path / "out")
    for extra in ((), ("--resume",)):
        res = cli("reconstruct", path, "--out", tmp_path / "out", "--no-progress", *extra)
        assert_one_error_line(res, tmp_path / "out", "--out", ["another crashlab run", f"pid {proc.pid}"])
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == [LOCK_NAME]  # nothing written beside it


def test_two_reconstructions_on_one_out_the_second_refused(tmp_path):
    """A real writer: the second reconstruct on its --out, started once the first has written its first
    checkpoint, is refused with one line; the first finishes with exit 0 and its outputs."""
    path = study_file(tmp_path, base="case3", pop_size=12, generations=30, polish="evaluations = 0")
    out = tmp_path / "out"
    first = subprocess.Popen([sys.executable, "-m", "crashlab.cli", "reconstruct", str(path), "--out", str(out),
                              "--no-progress"], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 240
    while not (out / "checkpoint.pkl").exists() and first.poll() is None and time.monotonic() < deadline:
        time.sleep(0.01)
    running = first.poll() is None
    second = cli("reconstruct", path, "--out", out, "--no-progress")
    assert first.wait(timeout=600) == 0, first.stderr.read()
    if not running:
        pytest.skip("the first run ended before the second started (machine too fast for this budget)")
    assert_one_error_line(second, out, "--out", ["another crashlab run", f"pid {first.pid}", "crashlab reconstruct"])
    assert (out / "pareto.csv").is_file() and not (out / LOCK_NAME).exists()


def test_monte_carlo_out_refused_on_a_live_folder(tmp_path, holder):
    proc = holder(tmp_path / "mc")
    res = cli("simulate", REPO / "studies" / "montecarlo" / "side.toml", "--model", "impulse", "--monte-carlo", "2",
              "--out", tmp_path / "mc")
    assert_one_error_line(res, tmp_path / "mc", "--out", [f"pid {proc.pid}"])


# the commands whose lock the command line takes (framework/cli/main.py: main() holds lock_out_dir(args.out,
# command) around the command)
@pytest.mark.parametrize("argv", [["infer", "s.toml"], ["avoid", "s.toml"], ["study", "stability", "--quick"]],
                         ids=["infer", "avoid", "study"])
def test_other_commands_refused_on_a_live_folder(tmp_path, holder, monkeypatch, capsys, argv):
    """main() refuses before the command runs (the command itself replaced by a stub that must not run)."""
    cli_main = importlib.import_module("crashlab.cli.main")
    ran = []
    for name in ("cmd_infer", "cmd_avoid", "cmd_study"):
        monkeypatch.setattr(cli_main, name, lambda args: ran.append(args) or 0)
    proc = holder(tmp_path / "o")
    assert cli_main.main([*argv, "--out", str(tmp_path / "o")]) == 2 and not ran
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"{tmp_path / 'o'}: --out: " in err and f"pid {proc.pid}" in err
