"""`crashlab avoid` and [[counterfactuals]] input found by fuzzing (crashlab.reconstruction.counterfactual): a
posterior.csv with a value that is no finite number in a variable column, or without rows, is refused in one
line naming the file and the column (exit 2, nothing written) instead of answering on draws that fail or are
overwritten by the change; two counterfactuals of one name (or one named "posterior", the row of the draws as
they are) are refused at load naming `counterfactuals.<k>.name`; a bad `keep` names the values it takes."""
from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest

import crashlab
from crashlab.cli import main
from crashlab.errors import InputError
from crashlab.reconstruction import counterfactual

REPO = Path(__file__).resolve().parent.parent
SRC = REPO / "studies" / "infer" / "twin_infer.toml"
V1_AT_40 = '\n[[counterfactuals]]\nname = "V1 at 40"\nset = { "vehicles.V1.speed" = 40.0 }\n'


def study(tmp_path: Path, extra: str = V1_AT_40) -> Path:
    """The twin_infer study (side.toml, V1 and V2 free) with `extra` appended, written into tmp_path."""
    text = SRC.read_text().replace('scene = "../pc_crash/side.toml"',
                                   f'scene = "{(REPO / "studies" / "pc_crash" / "side.toml").as_posix()}"')
    assert str(REPO / "studies" / "pc_crash") in text
    p = tmp_path / "study.toml"
    p.write_text(text + extra)
    return p


@pytest.fixture(scope="module")
def post(tmp_path_factory):
    from crashlab.reconstruction.posterior import load_posterior
    return load_posterior(study(tmp_path_factory.mktemp("post")))


def truth_table(post, n: int = 4) -> pd.DataFrame:
    """posterior.csv's table of n draws, each the scene's own values (as `crashlab infer` writes it)."""
    truth = [crashlab.fields.get(post.study.scene, v.path) for v in post.variables]
    return pd.DataFrame([truth] * n, columns=post.labels).assign(log_likelihood=-1.0)


def refused(capsys, key, *args, words=()):
    """The command refused in one line naming a file and `key` (exit 2); that line."""
    code = main([str(a) for a in args])
    out, err = capsys.readouterr()
    err = err.strip().splitlines()
    assert code == 2 and len(err) == 1, (code, out, err)
    assert err[0].startswith("crashlab: error: ") and f": {key}: " in err[0], err
    for w in words:
        assert w in err[0], err
    return err[0]


# 1: a corrupt posterior.csv
@pytest.mark.parametrize("value, shown", [(float("nan"), "nan"), (float("inf"), "inf"), ("", "nan"),
                                          (float("-inf"), "-inf")])
def test_avoid_refuses_a_posterior_with_a_value_that_is_no_finite_number(value, shown, post, tmp_path, capsys):
    """One bad cell of V1.speed (the counterfactual sets V1.speed: the bad draw would be simulated with the
    change as if it were good, and fail in the posterior's row): one line naming posterior.csv and the column,
    nothing written."""
    table = truth_table(post).astype(object)
    table.loc[2, "V1.speed"] = value
    table.to_csv(tmp_path / "posterior.csv", index=False)
    line = refused(capsys, "V1.speed", "avoid", study(tmp_path), "--out", tmp_path,
                   words=("posterior.csv", f"got {shown} in row 3"))
    assert str(tmp_path / "posterior.csv") in line
    assert not (tmp_path / "counterfactuals.csv").exists()
    assert not list(tmp_path.glob("*.png"))


def test_avoid_refuses_a_posterior_without_draws(post, tmp_path, capsys):
    truth_table(post, 0).to_csv(tmp_path / "posterior.csv", index=False)
    refused(capsys, "--out", "avoid", study(tmp_path), "--out", tmp_path, words=("posterior.csv", "no draws"))
    assert not (tmp_path / "counterfactuals.csv").exists()


def test_avoid_still_answers_a_good_posterior(post, tmp_path, capsys):
    truth_table(post).to_csv(tmp_path / "posterior.csv", index=False)
    assert main(["avoid", str(study(tmp_path)), "--out", str(tmp_path)]) == 0
    assert list(pd.read_csv(tmp_path / "counterfactuals.csv")["name"]) == ["posterior", "V1 at 40"]
    assert "V1 at 40: avoided in" in capsys.readouterr().out


@pytest.mark.parametrize("value, key, got", [("abc", "V2.speed", "got 'abc' in row 2"),
                                             (float("nan"), "V2.speed", "got nan in row 2"),
                                             ("inf", "V2.speed", "got inf in row 2")])
def test_posterior_draws_names_the_column_of_a_non_number(value, key, got, post):
    """The reading crashlab avoid needs (counterfactual.posterior_draws): a non-number is no traceback."""
    table = truth_table(post).astype(object)
    table.loc[1, "V2.speed"] = value
    with pytest.raises(InputError) as err:
        counterfactual.posterior_draws(table, post.labels, "out/posterior.csv")
    assert err.value.key == key and got in str(err.value) and "\n" not in str(err.value)
    with pytest.raises(InputError) as err:
        counterfactual.posterior_draws(truth_table(post).drop(columns="V2.speed"), post.labels, "p.csv")
    assert err.value.key == "V2.speed"
    X = counterfactual.posterior_draws(truth_table(post), post.labels, "p.csv")
    assert X.shape == (4, len(post.labels)) and X.dtype == float


# 2: duplicate names
@pytest.mark.parametrize("names, key, words", [
    (["V1 at 40", "V1 at 40"], "counterfactuals.1.name", ("'V1 at 40'", "counterfactuals.0")),
    (["a", "b", "a"], "counterfactuals.2.name", ("'a'", "counterfactuals.0")),
    (["posterior"], "counterfactuals.0.name", ("'posterior'", "draws as they are")),
])
def test_duplicate_counterfactual_names_are_refused(names, key, words, post):
    raw = [{"name": n, "set": {"vehicles.V1.speed": 40.0 + k}} for k, n in enumerate(names)]
    with pytest.raises(InputError) as err:
        counterfactual.parse(raw, post.study.scene, "study.toml")
    assert err.value.key == key and "\n" not in str(err.value)
    for w in words:
        assert w in str(err.value)


@pytest.mark.parametrize("command", ["avoid", "reconstruct", "infer"])
def test_every_command_refuses_duplicate_counterfactual_names_at_load(command, tmp_path, capsys):
    twice = V1_AT_40 + V1_AT_40.replace("40.0", "45.0")
    refused(capsys, "counterfactuals.1.name", command, study(tmp_path, twice), "--out", tmp_path / "out",
            words=("study.toml", "duplicate counterfactual name 'V1 at 40'"))
    assert not (tmp_path / "out" / "counterfactuals.csv").exists()


# 3: keep
def test_a_bad_keep_names_the_values_it_takes(post):
    raw = [{"name": "x", "set": {"vehicles.V1.speed": 40.0}, "keep": "nowhere"}]
    with pytest.raises(InputError) as err:
        counterfactual.parse(raw, post.study.scene, "study.toml")
    msg = str(err.value)
    assert err.value.key == "counterfactuals.0.keep" and "control characters" not in msg
    assert "'position'" in msg and "'arrival'" in msg and "\n" not in msg
    for keep in ("position", "arrival"):
        (cf,) = counterfactual.parse([dict(raw[0], keep=keep)], post.study.scene, "study.toml")
        assert cf.keep == keep
