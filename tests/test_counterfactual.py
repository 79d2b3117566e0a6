"""Counterfactuals (issue 28, crashlab.reconstruction.counterfactual): would it have been avoided?

A twin with a known answer: V1 at 58-66 km/h locks its wheels 1.0 s after the start (the hazard appearing),
V2 stands across its lane with its near side 31 m ahead of V1's front. Stopping distance (written here, not
the code under test): v t_r + v^2 / (2 mu g) with mu = 0.8 (locked wheels: Coulomb, whatever the load
transfer): 62 km/h needs 36.1 m (it hits V2 at sqrt(v^2 - 2 mu g (31 - v t_r)) = 32 km/h), 50 km/h 26.2 m
(it stops 4.8 m short), 62 km/h braking 0.5 s earlier 27.5 m (3.5 m short).
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import crashlab
from crashlab import fields
from crashlab.errors import InputError
from crashlab.models.impulse import ImpulseModel
from crashlab.reconstruction import counterfactual
from crashlab.scene_file import scene_from_dict
from crashlab.units import G

MU, T_R, GAP = 0.8, 1.0, 31.0
REPO = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def scene():
    clio = crashlab.get_model("impulse")  # (registers the models)
    del clio
    front = 0.0
    base = scene_from_dict({"name": "twin", "duration": 10.0, "stop_at_rest": True, "road": {"friction": MU},
                            "vehicles": [{"name": "V1", "vehicle": "clio", "x": 0.0, "speed": 62.0,
                                          "wheels": "rolling", "actions": [{"t": T_R, "wheels": "locked"}]},
                                         {"name": "V2", "vehicle": "clio", "x": 100.0, "y": 0.0, "heading": 90.0,
                                          "wheels": "locked"}]})
    v1, v2 = base.vehicles
    front = v1.spec.cg_to_front
    x2 = front + GAP + v2.spec.width / 2  # V2's near side GAP ahead of V1's front
    return base.with_vehicle("V2", x=x2)


def stopping(v_kmh, t_r=T_R):
    v = v_kmh / 3.6
    return v * t_r + v * v / (2 * MU * G)


def impact_speed(v_kmh, t_r=T_R):
    v = v_kmh / 3.6
    rest = GAP - v * t_r
    return 3.6 * math.sqrt(max(v * v - 2 * MU * G * rest, 0.0))


def test_the_analytic_twin_is_as_stated():
    assert stopping(58) > GAP and stopping(62) == pytest.approx(36.1, abs=0.1)
    assert stopping(50) == pytest.approx(26.2, abs=0.1) and stopping(62, 0.5) == pytest.approx(27.5, abs=0.1)


def test_a_lower_speed_and_earlier_braking_avoid_the_collision_the_draws_do_not(scene):
    model = ImpulseModel()
    var = [fields.resolve(scene, "vehicles.V1.speed")]
    X = np.linspace(58.0, 66.0, 41)[:, None]
    cfs = counterfactual.parse([{"name": "at the limit", "set": {"vehicles.V1.speed": 50.0}},
                                {"name": "braking 0.5 s earlier", "shift": {"vehicles.V1.actions.0.t": -0.5}},
                                {"name": "a little slower", "scale": {"vehicles.V1.speed": 0.99}},
                                {"name": "nothing", "scale": {"vehicles.V1.speed": 1.0}}], scene, "t.toml")
    rows = {r["name"]: r for r in counterfactual.answer(model, scene, var, X, cfs)}
    post, limit, early = rows["posterior"], rows["at the limit"], rows["braking 0.5 s earlier"]
    assert post["failed"] == 0 and post["p_avoided"] == 0.0
    want = np.quantile([impact_speed(v) for v in X[:, 0]], (0.05, 0.5, 0.95))
    got = [post[f"V1.impact_speed_{p}"] for p in (5, 50, 95)]
    print(f"\nimpact speed 5/50/95 %: {np.round(got, 2)} km/h, analytic {np.round(want, 2)}")
    np.testing.assert_allclose(got, want, atol=1.5)  # rolling resistance before the lock, the tyre model
    assert limit["p_avoided"] == 1.0 and early["p_avoided"] == 1.0
    assert 0.95 < limit["p_avoided_5"] < 1.0 and limit["p_avoided_95"] == 1.0
    # 1 % slower: 57.4-65.3 km/h still stops after 31 m (57.4 km/h: 32.2 m): every draw still collides
    assert rows["a little slower"]["p_avoided"] == 0.0
    same = {k: v for k, v in rows["nothing"].items() if k != "name"}  # a change that changes nothing
    assert same == {k: v for k, v in post.items() if k != "name"}
    lines = counterfactual.summary_lines(rows.values())
    assert lines[1].startswith("at the limit: avoided in 100.0 % of 41 draws")


def test_arrival_moves_the_start_so_the_car_arrives_when_it_did(scene):
    var = [fields.resolve(scene, p) for p in ("vehicles.V1.speed", "vehicles.V1.x")]
    X = np.array([[60.0, 0.0], [60.0, 1.0]])
    cf = counterfactual.parse([{"name": "slower", "set": {"vehicles.V1.speed": 40.0}, "keep": "arrival"}],
                              scene, "t.toml")[0]
    fs, V = counterfactual.changed_values(cf, scene, var, X, contact_t=np.array([2.0, np.nan]))
    assert [f.path for f in fs][:2] == ["vehicles.V1.speed", "vehicles.V1.x"]
    # (60 - 40) km/h x 2 s = 11.1 m further ahead along heading 0; no contact: the start kept
    np.testing.assert_allclose(V[:, 1], [20.0 / 3.6 * 2.0, 1.0])
    np.testing.assert_allclose(V[:, 0], 40.0)


@pytest.mark.parametrize("entry, key", [
    ({"name": "x", "set": {"vehicles.V3.speed": 50.0}}, "counterfactuals.0.set.vehicles.V3.speed"),
    ({"name": "x", "set": {"vehicles.V1.speed": 500.0}}, "counterfactuals.0.set.vehicles.V1.speed"),
    ({"name": "x"}, "counterfactuals.0"),
    ({"name": "x", "sett": {"vehicles.V1.speed": 50.0}}, "counterfactuals.0.sett"),
    ({"name": "x", "shift": {"vehicles.V1.actions.3.t": -0.5}}, "counterfactuals.0.shift.vehicles.V1.actions.3.t"),
])
def test_bad_counterfactuals_name_the_key(scene, entry, key):
    with pytest.raises(InputError) as err:
        counterfactual.parse([entry], scene, "study.toml")
    assert err.value.key == key and "\n" not in str(err.value)
    if "sett" in key:
        assert "did you mean 'set'" in str(err.value)


def test_avoid_answers_a_studys_counterfactuals_on_an_infer_runs_draws(tmp_path, capsys):
    """`crashlab avoid STUDY --out DIR` reads DIR/posterior.csv (as `crashlab infer` writes it) and writes
    DIR/counterfactuals.csv. The side collision: had V1 not started (its speed scaled by 0), V2 crosses 3.5 m
    ahead of V1's CG, its near side 0.8 m clear of V1's front (1.89 m ahead of the CG): avoided; had V2 stopped
    where it starts, in V1's path: not avoided."""
    import pandas as pd

    from crashlab.cli import main
    from crashlab.reconstruction.posterior import load_posterior
    src = REPO / "studies" / "infer" / "twin_infer.toml"
    text = src.read_text().replace('scene = "../pc_crash/side.toml"',
                                   f'scene = "{(REPO / "studies" / "pc_crash" / "side.toml").as_posix()}"')
    study = tmp_path / "study.toml"
    study.write_text(text + '\n[[counterfactuals]]\nname = "V1 stopped"\nscale = { "vehicles.V1.speed" = 0.0 }\n'
                     '\n[[counterfactuals]]\nname = "V2 stopped"\nset = { "vehicles.V2.speed" = 0.0 }\n')
    post = load_posterior(study)
    truth = [crashlab.fields.get(post.study.scene, v.path) for v in post.variables]
    pd.DataFrame([truth] * 5, columns=post.labels).to_csv(tmp_path / "posterior.csv", index=False)
    assert main(["avoid", str(study), "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    table = pd.read_csv(tmp_path / "counterfactuals.csv")
    assert list(table["name"]) == ["posterior", "V1 stopped", "V2 stopped"]
    assert list(table["p_avoided"]) == [0.0, 1.0, 0.0] and list(table["draws"]) == [5, 5, 5]
    assert "V1 stopped: avoided in 100.0 % of 5 draws" in out
    assert main(["avoid", str(src), "--out", str(tmp_path)]) == 2  # no [[counterfactuals]]: one line
    assert "counterfactuals: the study has no [[counterfactuals]]" in capsys.readouterr().err


def test_infer_answers_the_counterfactuals_in_its_outputs(tmp_path):
    """`crashlab infer` with [[counterfactuals]]: counterfactuals.csv beside posterior.csv, a section in
    summary.md and in report.html, the numbers equal to answering them again on posterior.csv."""
    import pandas as pd

    from crashlab.reconstruction.infer import run_posterior
    from crashlab.reconstruction.posterior import load_posterior
    text = (REPO / "studies" / "infer" / "twin_infer.toml").read_text().replace(
        'scene = "../pc_crash/side.toml"', f'scene = "{(REPO / "studies" / "pc_crash" / "side.toml").as_posix()}"')
    study = tmp_path / "study.toml"
    study.write_text(text + '\n[[counterfactuals]]\nname = "V1 stopped"\nscale = { "vehicles.V1.speed" = 0.0 }\n')
    post = load_posterior(study)
    post.settings = post.settings.model_copy(update={"walkers": 16, "burn": 20, "samples": 16 * 20,
                                                     "draws_plotted": 0})
    out = tmp_path / "out"
    res = run_posterior(post, out, progress=False)
    table = pd.read_csv(out / "counterfactuals.csv")
    assert list(table["name"]) == ["posterior", "V1 stopped"] and list(table["p_avoided"]) == [0.0, 1.0]
    assert table["draws"][0] == len(res.samples)
    again = counterfactual.answer(ImpulseModel(), post.study.scene, post.fields, res.samples, post.counterfactuals)
    np.testing.assert_allclose(table["V2.impact_speed_50"], [r["V2.impact_speed_50"] for r in again], rtol=1e-9)
    assert "## Counterfactuals" in (out / "summary.md").read_text()
    assert "Would it have been avoided?" in (out / "report.html").read_text()
