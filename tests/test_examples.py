"""The bundled examples as package data (crashlab.tools.examples, `crashlab examples [copy DIR]`): every
scene and study file of studies/ is bundled, copied out it loads and runs from there, and `copy` refuses a
folder that holds files. The installed wheel itself is run by .ci/run."""
import tomllib
from pathlib import Path

import pytest

from crashlab.cli import main
from crashlab.tools import examples

REPO = Path(__file__).resolve().parents[1]


def test_every_studies_file_is_bundled_and_declared_as_package_data():
    bundled = {rel for rel, _ in examples.files()}
    on_disk = {p.relative_to(REPO / "studies").as_posix() for p in (REPO / "studies").rglob("*")
               if p.is_file() and p.suffix in examples.SUFFIXES and "__pycache__" not in p.parts
               and p.name != "__init__.py"}
    assert on_disk and on_disk <= bundled
    assert {f"vehicles/{p.name}" for p in (REPO / "framework" / "vehicles").glob("*.toml")} <= bundled
    # the wheel takes what pyproject's package data names: each bundled file matches one of its patterns
    patterns = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]["package-data"]
    from fnmatch import fnmatch
    missing = [rel for rel in on_disk if not any(fnmatch(rel, pat) and rel.count("/") == pat.count("/")
                                                 for pat in patterns["crashlab.examples"])]
    assert not missing, missing


def test_copy_writes_runnable_examples(tmp_path, capsys):
    import crashlab
    from crashlab.reconstruction import load_study
    dest = tmp_path / "ex"
    assert main(["examples", "copy", str(dest)]) == 0
    assert (dest / "vehicles" / "clio.toml").is_file()
    out = crashlab.simulate(dest / "pc_crash" / "side.toml", model="impulse")
    assert out.outcome_ok
    ref = crashlab.simulate(REPO / "studies" / "pc_crash" / "side.toml", model="impulse")
    assert out.rest.equals(ref.rest)  # the same file, the same result
    assert load_study(dest / "tutorial" / "study.toml").variables


def test_copy_refuses_a_folder_with_files(tmp_path, capsys):
    (tmp_path / "x.txt").write_text("mine")
    assert main(["examples", "copy", str(tmp_path)]) == 2
    assert "not an empty folder" in capsys.readouterr().err
    assert (tmp_path / "x.txt").read_text() == "mine"


def test_listing_names_each_file(capsys):
    assert main(["examples"]) == 0
    text = capsys.readouterr().out
    assert "pc_crash/side.toml" in text and "vehicles/clio.toml" in text


def test_bench_default_scene_is_the_bundled_one():
    from crashlab.tools.bench import default_scene_path
    assert default_scene_path().is_file()
    assert default_scene_path() == examples.path("pc_crash/side.toml")


def test_bad_examples_commands(capsys):
    with pytest.raises(SystemExit):  # argparse: not a choice
        main(["examples", "move", "x"])
    assert main(["examples", "copy"]) == 2
    assert "copy DIR" in capsys.readouterr().err
