"""Forward Monte Carlo (crashlab.reconstruction.montecarlo, `crashlab simulate SCENE --monte-carlo N`), docs/physics.md
(uncertain parameters and Monte Carlo): the table of draws through the CLI, rest clouds that widen when
the friction's spread widens (sliding distance v^2 / (2 mu g)), momentum in every draw's delta-V with an
uncertain mass, failed draws counted and kept, and a scene without [[uncertain]] refused (exit 2)."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from conftest import REPO

import crashlab
from crashlab.cli import main
from crashlab.fields import set_fields
from crashlab.reconstruction import montecarlo
from crashlab.scene_file import load_scene

SIDE = REPO / "studies" / "montecarlo" / "side.toml"
BASE = SIDE.read_text().split("[[uncertain]]")[0]


def _scene_file(tmp_path: Path, entries: str, name="mc.toml", base=BASE) -> Path:
    p = tmp_path / name
    p.write_text(base + entries)
    return p


def test_cli_writes_the_table_of_draws(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["simulate", str(SIDE), "--monte-carlo", "24", "--seed", "3", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    df = pd.read_csv(out / "montecarlo.csv")
    fields = ["road.friction", "impact.restitution", "impact.friction", "vehicles.V1.speed", "vehicles.V2.speed"]
    per_vehicle = [f"{v}.{q}" for v in ("V1", "V2") for q in ("x", "y", "heading", "delta_v", "ok")]
    assert list(df.columns) == ["draw", *fields, *per_vehicle, "ok", "no_contact", "reason"]
    assert len(df) == 24 and df["ok"].all() and df["draw"].tolist() == list(range(24))
    assert (out / "montecarlo.png").stat().st_size > 10_000 and (out / "summary.csv").is_file()
    assert df["vehicles.V1.speed"].between(0, 400).all() and df["impact.restitution"].between(0.05, 0.2).all()
    # the same seed draws the same parameters and gives the same rest poses
    again = montecarlo.run(load_scene(SIDE), crashlab.get_model("impulse"), 24, seed=3).table
    cols = fields + ["V1.x", "V2.heading"]
    assert np.allclose(again[cols].to_numpy(), df[cols].to_numpy(), rtol=1e-5)
    assert "failed draws: 0 of 24" in text and "V1: x " in text


def test_a_draw_reruns_from_the_table_of_draws(tmp_path):
    """Each row of montecarlo.csv holds its draw's parameters to 10 significant figures: set on the scene
    (crashlab.fields.set_fields) they give the row's rest poses again (written to 6 figures until 2026-11-28, a
    draw re-run from the table came out 0.003 deg off in heading)."""
    out = tmp_path / "out"
    assert main(["simulate", str(SIDE), "--monte-carlo", "6", "--seed", "5", "--out", str(out)]) == 0
    df = pd.read_csv(out / "montecarlo.csv")
    fields = ["road.friction", "impact.restitution", "impact.friction", "vehicles.V1.speed", "vehicles.V2.speed"]
    model, scene = crashlab.get_model("impulse"), load_scene(SIDE)
    for _, row in df.iterrows():
        rest = model.simulate(set_fields(scene, fields, row[fields].to_numpy(float))).rest
        for v in ("V1", "V2"):
            got = rest.loc[v, ["x", "y", "heading"]].to_numpy(float)
            assert got == pytest.approx(row[[f"{v}.x", f"{v}.y", f"{v}.heading"]].to_numpy(float), rel=1e-8,
                                        abs=1e-7)


def test_rest_clouds_widen_with_the_friction_spread(tmp_path):
    """Only the road friction uncertain: the spread of each car's rest position grows with the friction's
    spread (after the impact the cars slide v^2 / (2 mu g)); a fourfold wider uniform gives a wider cloud
    by more than twice (about fourfold: the distance is smooth in mu over these ranges)."""
    model = crashlab.get_model("impulse")
    spread = {}
    for half in (0.025, 0.1):
        p = _scene_file(tmp_path, f'[[uncertain]]\nfield = "road.friction"\ndistribution = "uniform"\n'
                        f"lower = {0.8 - half}\nupper = {0.8 + half}\n", name=f"mc{half}.toml")
        r = montecarlo.run(load_scene(p), model, 40, seed=5)
        assert r.table["ok"].all(), r.failure_reasons()
        spread[half] = {v: math.sqrt(r.table[f"{v}.x"].var() + r.table[f"{v}.y"].var()) for v in ("V1", "V2")}
    for v in ("V1", "V2"):
        assert spread[0.1][v] > 2.0 * spread[0.025][v], spread


def test_delta_v_of_every_draw_conserves_momentum_with_an_uncertain_mass(tmp_path):
    """V1's mass uncertain: in every draw m1 dv1 = m2 dv2 (the impulse model's exchange is exact), so the
    drawn mass reaches the simulation."""
    p = _scene_file(tmp_path, '[[uncertain]]\nfield = "vehicles.V1.mass"\ndistribution = "uniform"\n'
                    "lower = 700\nupper = 1600\n")
    s = load_scene(p)
    r = montecarlo.run(s, crashlab.get_model("impulse"), 30, seed=2)
    t = r.table
    assert t["ok"].all()
    m2 = s.vehicle("V2").spec.mass
    assert np.allclose(t["vehicles.V1.mass"] * t["V1.delta_v"], m2 * t["V2.delta_v"], rtol=1e-6)
    assert t["V1.delta_v"].std() > 1.0  # km/h: the masses do change the split


def test_failed_draws_are_counted_not_dropped(tmp_path, capsys):
    """A run too short for the cars to stop: every draw's end pose is no rest pose, each is a failed draw
    with its reason, kept in the table; with every draw failed the command fails (exit 3, one line with the
    count and the first reason; it printed a summary of nan over 0 draws and exited 0 before)."""
    p = _scene_file(tmp_path, '[[uncertain]]\nfield = "road.friction"\ndistribution = "uniform"\n'
                    "lower = 0.7\nupper = 0.9\n", base=BASE.replace("duration = 10.0", "duration = 0.3"))
    out = tmp_path / "out"
    assert main(["simulate", str(p), "--monte-carlo", "8", "--out", str(out)]) == 3
    captured = capsys.readouterr()
    df = pd.read_csv(out / "montecarlo.csv")
    assert len(df) == 8 and not df["ok"].any()
    assert df["reason"].str.contains("still moving at the end").all()
    err = [line for line in captured.err.splitlines() if "all 8 draws failed" in line]
    assert len(err) == 1 and "V1, V2 still moving" in err[0], captured.err
    assert "nan" not in captured.out


def test_monte_carlo_without_uncertain_parameters_is_refused(capsys):
    scene = REPO / "studies" / "pc_crash" / "side.toml"
    assert main(["simulate", str(scene), "--monte-carlo", "10"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith(f"crashlab: error: {scene}: uncertain: "), err


@pytest.mark.parametrize("args, key", [(["--monte-carlo", "0"], "--monte-carlo"),
                                       (["--monte-carlo", "5", "--seed", "-1"], "--seed"), (["--seed", "3"], "--seed")])
def test_bad_monte_carlo_options(capsys, args, key):
    assert main(["simulate", str(SIDE), *args]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and f": {key}: " in err, err
