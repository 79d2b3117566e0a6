"""kill -9 at seeded points across a run, then --resume: the outputs identical to the uninterrupted run's, for
every optimizer (crashlab reconstruct) and for crashlab infer (issue 27).

A point: the run is started on its own --out and killed (SIGKILL) at a seeded point (kill_and_resume: most
within the search, after a seeded number of checkpoint writes, the others in the polish and the outputs);
then `--resume` on that folder (the killed run's lock is
taken over) and its pareto.csv (reconstruct: case 3, 12 x 30 with a 30-evaluation polish) or posterior.csv
(infer: the twin, 12 walkers x 60 iterations, a checkpoint every 5) compared byte for byte with the
uninterrupted run's. A run that ended before its kill is counted and checked the same way (its outputs).

Default: 2 points for nsga3 and for infer (about 30 s each on 2 loaded cores: 8-11 s the uninterrupted run,
11-13 s a point). The slow marker:
50 points each, `python -m pytest -q -m slow tests/test_kill_resume.py -s` (prints the time per optimizer).
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from test_reconstruction_truth import OPTIMIZERS, study_file

REPO = Path(__file__).resolve().parent.parent
TWIN_INFER = REPO / "studies" / "infer" / "twin_infer.toml"
CLI = [sys.executable, "-m", "crashlab.cli"]
SEED = 27


def reconstruct_case(tmp_path, optimizer):
    path = study_file(tmp_path, base="case3", name=f"{optimizer}.toml", pop_size=12, generations=30,
                      replace={"o": ('name = "nsga-sharing"', f'name = "{optimizer}"')})
    return [*CLI, "reconstruct", str(path), "--no-progress"], "checkpoint.pkl", "pareto.csv"


def infer_case(tmp_path):
    text = TWIN_INFER.read_text().replace('scene = "../pc_crash/side.toml"',
                                          f'scene = "{(REPO / "studies" / "pc_crash" / "side.toml").as_posix()}"')
    head, _, tail = text.partition("[infer]")
    rest = tail[tail.index("\n[") :]  # the tables after [infer]
    small = "walkers = 12\nburn = 20\nsamples = 480\ncheckpoint_every = 5\ndraws_plotted = 0\nseed = 1\n"
    text = head + "[infer]\n" + small + rest
    path = tmp_path / "infer.toml"
    path.write_text(text)
    return [*CLI, "infer", str(path), "--no-progress"], "infer_checkpoint.pkl", "posterior.csv"


def _stamp(path: Path):
    try:
        st = path.stat()
        return st.st_ino, st.st_mtime_ns
    except FileNotFoundError:
        return None


def _watch(path: Path, proc, until_writes=None) -> int:
    """Poll (1 ms) the checkpoint: the number of writes seen (each is an atomic replace: a new inode) until
    `until_writes` are seen or the process ends."""
    seen, last = 0, None
    while proc.poll() is None and (until_writes is None or seen < until_writes):
        stamp = _stamp(path)
        if stamp is not None and stamp != last:
            seen, last = seen + 1, stamp
        time.sleep(0.001)
    return seen


def kill_and_resume(tmp_path, case, n_points, seed=SEED) -> dict:
    """The uninterrupted run (its checkpoint writes counted, the time after the last one measured), then
    n_points runs each killed at a seeded point: 80 % after a seeded number of checkpoint writes plus a
    seeded 0-30 ms (within the search), 20 % at a seeded time after the last checkpoint write (the polish
    and the outputs); each resumed and its result compared. Returns counts and times."""
    cmd, ckpt, result = case
    full = tmp_path / "full"
    t0 = time.monotonic()
    proc = subprocess.Popen([*cmd, "--out", str(full)], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    writes = _watch(full / ckpt, proc)
    t_last = time.monotonic()
    assert proc.wait(timeout=900) == 0, proc.stderr.read()
    t_after = time.monotonic() - t_last
    want = (full / result).read_bytes()
    rng = np.random.default_rng(seed)
    counts = {"killed": 0, "ended before the kill": 0, "identical": 0, "checkpoint writes": writes,
              "full run s": time.monotonic() - t0}
    t1 = time.monotonic()
    for i in range(n_points):
        in_search = rng.uniform() < 0.8
        k, delay = (int(rng.integers(1, max(writes, 1) + 1)), rng.uniform(0.0, 0.03)) if in_search else \
            (writes, rng.uniform(0.0, t_after))
        out = tmp_path / f"k{i}"
        proc = subprocess.Popen([*cmd, "--out", str(out)], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        _watch(out / ckpt, proc, until_writes=k)
        time.sleep(delay)
        if proc.poll() is None:
            os.kill(proc.pid, signal.SIGKILL)
        code = proc.wait(timeout=60)
        if code == -signal.SIGKILL:
            counts["killed"] += 1
            res = subprocess.run([*cmd, "--out", str(out), "--resume"], capture_output=True, text=True, timeout=900)
            assert res.returncode == 0, (i, k, delay, res.stderr)
            assert "Traceback" not in res.stderr
        else:
            counts["ended before the kill"] += 1
            assert code == 0, (i, k, delay)
        got = (out / result).read_bytes()
        assert got == want, f"point {i} (after {k} checkpoint writes + {delay:.3f} s): {result} differs"
        counts["identical"] += 1
    counts["s per point"] = (time.monotonic() - t1) / max(n_points, 1)
    return counts


def _report(what, counts):
    print(f"\n{what}: " + ", ".join(f"{k} {v:.1f}" if isinstance(v, float) else f"{k} {v}" for k, v in counts.items()))


@pytest.mark.parametrize("what", ["nsga3", "infer"])
def test_kill_and_resume_2_points(tmp_path, what):
    """The default run's variant: nsga3 (not reproducible before, issue 27) and infer, 2 points each (the other
    five optimizers: the slow test; in-process stops of every optimizer: test_reconstruction_truth)."""
    case = infer_case(tmp_path) if what == "infer" else reconstruct_case(tmp_path, what)
    counts = kill_and_resume(tmp_path, case, 2)
    _report(what, counts)
    assert counts["identical"] == 2 and counts["killed"] >= 1


@pytest.mark.slow
@pytest.mark.parametrize("optimizer", [*OPTIMIZERS, "infer"])
def test_kill_and_resume_50_points(tmp_path, optimizer):
    case = infer_case(tmp_path) if optimizer == "infer" else reconstruct_case(tmp_path, optimizer)
    counts = kill_and_resume(tmp_path, case, 50)
    _report(optimizer, counts)
    assert counts["identical"] == 50 and counts["killed"] >= 25  # most points kill the run, not its end
