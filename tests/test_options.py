"""Model options as schemas (crashlab.options) and the typed diagnostics core, for every registered model."""
import subprocess
import sys

import pytest

import crashlab
from crashlab.diagnostics import CORE, Diagnostics
from crashlab.options import FINER, OptionError, UnknownOptionError, accuracy_knobs, describe
from crashlab.registry import MODELS, available_models, load

MODEL_NAMES = available_models()


@pytest.fixture(scope="module")
def side_scene(pc_crash_dir):
    return crashlab.load_scene(pc_crash_dir / "side.toml")


@pytest.mark.parametrize("name", MODEL_NAMES)
def test_every_option_is_documented(name):
    rows = describe(load(MODELS, name).Options)
    assert rows, f"model {name} declares no options"
    for r in rows:
        assert r["description"], f"{name}.{r['name']} has no description"
        assert r["accuracy"] in ("",) + FINER
    # every model has at least one accuracy knob for the comparison studies to sweep
    assert accuracy_knobs(load(MODELS, name).Options), name


@pytest.mark.parametrize("name", MODEL_NAMES)
def test_defaults_round_trip(name):
    model = crashlab.get_model(name)
    opts = model.get_options()
    assert crashlab.get_model(name, **opts).get_options() == opts


@pytest.mark.parametrize("name", MODEL_NAMES)
def test_errors_name_the_key(name):
    schema = load(MODELS, name).Options
    with pytest.raises(UnknownOptionError, match="no_such_option"):
        crashlab.get_model(name, no_such_option=1)
    with pytest.raises(TypeError):  # an unknown option is also a TypeError, as an unknown keyword
        crashlab.get_model(name, no_such_option=1)
    knob = next(iter(accuracy_knobs(schema)))
    with pytest.raises(OptionError) as err:
        crashlab.get_model(name, **{knob: True})  # a bool is not a number
    assert err.value.key == knob
    with pytest.raises(OptionError) as err:
        crashlab.get_model(name, **{knob: float("nan")})
    assert err.value.key == knob


def test_cross_option_check_names_its_key():
    with pytest.raises(OptionError) as err:
        crashlab.get_model("impulse", dt=0.01, coarse_dt=0.001)
    assert err.value.key == "coarse_dt"


def test_cli_lists_options():
    r = subprocess.run([sys.executable, "-m", "crashlab.cli", "models", "--options", "impulse"],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert "dt" in r.stdout and "smaller" in r.stdout and "Heun" in r.stdout
    r = subprocess.run([sys.executable, "-m", "crashlab.cli", "models", "--options", "impuls"],
                       capture_output=True, text=True)
    assert r.returncode == 2 and "did you mean 'impulse'" in r.stderr


def test_diagnostics_mapping():
    d = Diagnostics.of({"steps": 12, "t_end": 3, "wheel_loads": [1, 2]})
    assert d.steps == 12 and d["t_end"] == 3.0 and isinstance(d.t_end, float)
    assert d["wheel_loads"] == [1, 2] and d.extra == {"wheel_loads": [1, 2]}
    assert "rejected_steps" not in d and d.get("rejected_steps", 0) == 0
    d["rejected_steps"] = 2
    assert set(d) == {"steps", "t_end", "rejected_steps", "wheel_loads"}


@pytest.mark.parametrize("name", MODEL_NAMES)
def test_every_model_fills_the_diagnostics_core(name, side_scene):
    out = crashlab.get_model(name).simulate(side_scene)
    core = out.diagnostics.core()
    missing = [k for k in CORE if core[k] is None]
    assert not missing, f"model {name} does not report {missing}"
    assert core["steps"] > 0 and core["episodes"] >= 1 and core["t_end"] > 0
    assert core["max_penetration"] >= 0 and core["energy_start"] > core["energy_end"] >= 0
    assert core["energy_impacts"] > 0
