"""Inputs that gave tracebacks in issue 27's fuzz: each is refused with one line naming the file and the
key, exit 2 (crashlab.input_files.read_toml, crashlab.vehicle.load_vehicle, the study's scene path, [infer]
under `reconstruct`, an unreachable Dask scheduler)."""
from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import pytest
from conftest import assert_one_error_line

from crashlab.errors import InputError

REPO = Path(__file__).resolve().parent.parent
SIDE = (REPO / "studies" / "pc_crash" / "side.toml").read_text()
CASE1 = (REPO / "studies" / "reconstruction" / "case1.toml").read_text().replace(
    '"../pc_crash/side.toml"', repr(str(REPO / "studies" / "pc_crash" / "side.toml")).replace("'", '"'))


def _cli(capsys, *args):
    from crashlab.cli import main
    code = main([str(a) for a in args])
    captured = capsys.readouterr()
    return SimpleNamespace(returncode=code, stdout=captured.out, stderr=captured.err)


def _scene(tmp_path, text, name="scene.toml"):
    p = tmp_path / name
    p.write_text(text)
    return p


def test_an_integer_of_thousands_of_digits(tmp_path, capsys):
    p = _scene(tmp_path, SIDE.replace("name = ", "huge = " + "9" * 5000 + "\nname = ", 1))
    res = _cli(capsys, "simulate", p, "--model", "impulse")
    assert_one_error_line(res, p, "huge (line 3)", ["an integer of more than 4,300 digits"])


def test_arrays_nested_thousands_deep(tmp_path, capsys):
    p = _scene(tmp_path, SIDE.replace("name = ", "deep = " + "[" * 5000 + "]" * 5000 + "\nname = ", 1))
    res = _cli(capsys, "simulate", p, "--model", "impulse")
    assert_one_error_line(res, p, "deep (line 3)", ["nested too deep"])


def test_a_vehicle_path_longer_than_the_system_allows(tmp_path, capsys):
    p = _scene(tmp_path, SIDE.replace('vehicle = "clio"', 'vehicle = "' + "a" * 300 + '.toml"', 1))
    res = _cli(capsys, "simulate", p, "--model", "impulse")
    assert_one_error_line(res, p, "vehicles.V1", ["File name too long"])


def test_a_scene_path_longer_than_the_system_allows(tmp_path, capsys):
    p = _scene(tmp_path, CASE1.replace(str(REPO / "studies" / "pc_crash" / "side.toml"), "c" * 300 + ".toml"),
               "study.toml")
    res = _cli(capsys, "reconstruct", p, "--no-progress")
    assert_one_error_line(res, p, "scene", ["File name too long"])
    res = _cli(capsys, "simulate", tmp_path / ("b" * 300 + ".toml"))
    assert res.returncode == 2 and len(res.stderr.strip().splitlines()) == 1


@pytest.mark.parametrize("line, key", [("checkpoint_every = inf", "infer.checkpoint_every"),
                                       ('sampler = "hmc"', "infer.sampler"), ("bogus = 1", "infer.bogus")])
def test_reconstruct_checks_the_infer_table(tmp_path, capsys, line, key):
    p = _scene(tmp_path, CASE1 + f"\n[infer]\n{line}\n", "study.toml")
    res = _cli(capsys, "reconstruct", p, "--no-progress")
    assert_one_error_line(res, p, key)


def test_an_unreachable_scheduler_is_one_line(monkeypatch):
    """Refused with one line (exit 2 through the CLI's InputError), after Dask's connect timeout set to
    SCHEDULER_CONNECT_TIMEOUT_S (Dask's default is 30 s, then a traceback)."""
    import dask.distributed

    from crashlab.execution.executor import SCHEDULER_CONNECT_TIMEOUT_S, Executor
    with pytest.raises(InputError, match=r"^execution: scheduler: no Dask scheduler answers at 'tcp://127.0.0.1:1'") \
            as err:
        with Executor("dask", 1, "tcp://127.0.0.1:1"):
            pass
    assert "\n" not in str(err.value)
    seen = {}

    def client(address, **kw):
        seen.update(kw)
        raise OSError(f"Timed out trying to connect to {address}")

    monkeypatch.setattr(dask.distributed, "Client", client)
    with pytest.raises(InputError, match="within 5 s"):
        with Executor("dask", 1, "tcp://somewhere:8786"):
            pass
    assert seen["timeout"] == SCHEDULER_CONNECT_TIMEOUT_S == 5.0


def test_a_friction_zone_of_twenty_thousand_corners(tmp_path, capsys):
    """Issue 27: 20,000 corners took minutes (the crossing check is n^2 / 2 segment tests): refused above
    ZONE_CORNERS_MAX, naming the zone's key; a zone of ZONE_CORNERS_MAX corners is accepted."""
    import math

    from crashlab.scene import ZONE_CORNERS_MAX

    def zone(n):
        pts = ", ".join(f"[{50 + 40 * math.cos(2 * math.pi * k / n):.6f}, {40 * math.sin(2 * math.pi * k / n):.6f}]"
                        for k in range(n))
        return SIDE.replace("[impact]", f"[[road.zones]]\nfriction = 0.3\npolygon = [{pts}]\n\n[impact]", 1)

    assert "[impact]" in SIDE
    p = _scene(tmp_path, zone(20_000))
    res = _cli(capsys, "simulate", p, "--model", "impulse")
    assert_one_error_line(res, p, "road.zones.0.polygon", [f"20000 corners: at most {ZONE_CORNERS_MAX}"])
    from crashlab.scene_file import load_scene
    assert len(load_scene(_scene(tmp_path, zone(ZONE_CORNERS_MAX), "ok.toml")).road.zones[0].polygon) == 1000


def test_the_infer_table_has_one_schema():
    """reconstruct and infer check [infer] with the one schema of crashlab.reconstruction.infer_settings."""
    from crashlab.reconstruction import infer_settings, posterior
    assert posterior.InferSection is infer_settings.InferSection
