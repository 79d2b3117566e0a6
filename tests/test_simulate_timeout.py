"""`crashlab simulate --timeout SECONDS` (issue 27): the run in a worker process killed when it overruns,
exit 3 with one line naming the model and the time; a run within its time gives the in-process result.
(The option itself is declared in framework/cli/main.py; here `args.timeout` is set on the parsed options.)"""
from __future__ import annotations

import importlib
import json
import time
from pathlib import Path

import pytest

from crashlab.models.pymunk import PymunkModel

REPO = Path(__file__).resolve().parent.parent
SIDE = REPO / "studies" / "pc_crash" / "side.toml"
cli_main = importlib.import_module("crashlab.cli.main")
COMPILE_NOTICE = ("compiling the ", "compiled the ")  # crashlab.cli.simulate.announce_compile's two lines


class SleepingPymunk(PymunkModel):
    """pymunk that hangs for 120 s on a scene longer than 1 s (the worker's warm-up is 0.05 s: not that)."""

    def simulate(self, scene):
        if scene.duration > 1.0:
            time.sleep(120.0)
        return super().simulate(scene)


def run(argv, timeout):
    args = cli_main.build_parser().parse_args(["simulate", str(SIDE), *argv])
    args.timeout = timeout
    return args.fn(args)


def test_a_run_over_its_time_is_stopped_exit_3_one_line(capsys):
    model = f"{__name__}:SleepingPymunk"
    assert run(["--model", model], 2.0) == 3
    err = capsys.readouterr().err.strip().splitlines()
    print("\n" + "\n".join(err))
    err = [line for line in err if not line.startswith(COMPILE_NOTICE)]  # a cold numba cache announces itself
    assert err == [f"crashlab: simulation failed: {SIDE}: model {model}: the run took longer than --timeout 2 s "
                   "and was stopped"]


def test_a_run_within_its_time_gives_the_in_process_result(capsys):
    assert run(["--model", "pymunk", "--json"], 300.0) == 0
    timed = json.loads(capsys.readouterr().out)
    assert run(["--model", "pymunk", "--json"], None) == 0
    plain = json.loads(capsys.readouterr().out)
    for d in (timed, plain):
        for r in d["results"]:
            r.pop("wall_time_s")
    assert timed == plain


@pytest.mark.parametrize("value", [0.0, -1.0, float("nan"), float("inf"), 1e-9, 0.099])
def test_a_bad_timeout_is_one_line(value):
    from crashlab.errors import InputError
    with pytest.raises(InputError, match=r"command line: --timeout: seconds, at least 0.1"):
        run(["--model", "pymunk"], value)


def test_timeout_with_monte_carlo_is_refused():
    from crashlab.errors import InputError
    with pytest.raises(InputError, match=r"--timeout: limits a single run, not --monte-carlo"):
        run(["--model", "pymunk", "--monte-carlo", "2"], 5.0)


def test_the_worker_says_ready_once_before_the_run_and_returns_its_outcome():
    """crashlab.execution.simulate_with_timeout itself: on_ready is called once, when the warm-up has ended and
    before the run's Outcome comes back, and the Outcome is the in-process one (rest poses equal)."""
    from crashlab.execution import simulate_with_timeout
    from crashlab.scene_file import load_scene
    scene = load_scene(SIDE)
    events = []
    out = simulate_with_timeout("pymunk", scene, 300.0, on_ready=lambda: events.append("ready"))
    events.append("done")
    assert events == ["ready", "done"]
    assert out.outcome_ok
    plain = PymunkModel().simulate(scene)
    assert out.rest.equals(plain.rest)
