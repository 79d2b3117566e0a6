"""The README's main job as a new user meets it (issue 26 item 2): on a cold numba cache and without compiled
bytecode (a fresh install), the first thing on the terminal is the line saying a model compiles, before 5 s of
silence, and the job ends with exit 0. Slow marker (about two minutes: the cold compile); .ci/run runs it in
its fresh venv."""
from __future__ import annotations

import os
import re
import subprocess
import threading
import time
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
SILENCE_S = 5.0
pytestmark = pytest.mark.slow


def main_job() -> str:
    """The README's first command without its set-up part (venv and install): what runs the job."""
    block = re.search(r"```bash\n(.*?)\n```", (REPO / "README.md").read_text(), re.S).group(1)
    assert "pip install" in block, block
    return block.split('pip install -e ".[dev]" && ', 1)[1]


def timed_lines(command: str, env: dict) -> tuple[int, list[tuple[float, str]]]:
    """Exit status and every line of stdout and stderr with the seconds since the start it arrived at."""
    start = time.monotonic()
    proc = subprocess.Popen(["bash", "-c", command], cwd=REPO, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True, bufsize=1)
    lines = []

    def read():
        for line in proc.stdout:
            lines.append((time.monotonic() - start, line.rstrip("\n")))
    reader = threading.Thread(target=read)
    reader.start()
    rc = proc.wait(timeout=900)
    reader.join()
    return rc, lines


def test_main_job_says_it_compiles_before_five_seconds_of_silence(tmp_path):
    env = {**os.environ, "XDG_CACHE_HOME": str(tmp_path / "cache"), "PYTHONPYCACHEPREFIX": str(tmp_path / "pyc"),
           "PYTHONUNBUFFERED": "1"}
    env.pop("NUMBA_CACHE_DIR", None)  # crashlab's own cache, under XDG_CACHE_HOME: empty
    rc, lines = timed_lines(main_job(), env)
    assert rc == 0, "\n".join(text for _, text in lines[-20:])
    compile_at = next((i for i, (_, text) in enumerate(lines) if text.startswith("compiling the ")), None)
    assert compile_at is not None, "no compile line on a cold cache:\n" + "\n".join(t for _, t in lines[:10])
    stamps = [0.0] + [t for t, _ in lines[:compile_at + 1]]
    gaps = [b - a for a, b in zip(stamps, stamps[1:])]
    print(f"\ncompile line after {stamps[-1]:.1f} s (line {compile_at + 1}); job {lines[-1][0]:.0f} s")
    assert max(gaps) < SILENCE_S, f"{max(gaps):.1f} s of silence before: {lines[compile_at][1]}"
    assert any(text.startswith("compiled the ") for _, text in lines[compile_at:]), "no compile time printed"
