"""crashlab study validation on a tiny configuration: the impulse model on the NHTSA 10146 barrier test.
Asserts the CSV contract and one physical fact: the impulse model's rebound speed off a rigid barrier is
restitution x impact speed (within 1 %)."""
from __future__ import annotations

import csv
import math

from crashlab.comparison import validation
from crashlab.scene import load_scene


def test_validation_csv_and_rebound(tmp_path):
    tests = [t for t in validation.load_tests() if t["id"] == "nhtsa10146"]
    path = validation.run(["impulse"], tmp_path, quick=True, tests=tests)
    with open(path, newline="") as fh:
        reader = csv.DictReader(fh)
        rows = list(reader)
    assert reader.fieldnames[:6] == ["model", "test", "quantity", "published", "simulated", "error"]
    assert {"unit", "source", "ok"} <= set(reader.fieldnames)
    assert (tmp_path / "validation.md").is_file()
    assert rows and all(r["ok"] == "True" for r in rows)
    rebound = next(float(r["simulated"]) for r in rows if r["quantity"] == "rebound_speed")
    scene = load_scene(tests[0]["scene"])
    impact_speed = 57.09  # km/h; a little less at contact after 0.3 m of rolling, well within 1 %
    assert math.isclose(rebound, scene.impact.restitution * impact_speed, rel_tol=0.01)
    for r in rows:
        assert math.isclose(float(r["error"]), float(r["simulated"]) - float(r["published"]), abs_tol=1e-9)


def test_failed_model_is_recorded(tmp_path, monkeypatch):
    tests = [t for t in validation.load_tests() if t["id"] == "nhtsa10146"]

    def boom(model, scene):
        return None, "RuntimeError: boom"
    monkeypatch.setattr(validation, "_simulate", boom)
    path = validation.run(["impulse"], tmp_path, tests=tests)
    rows = list(csv.DictReader(open(path, newline="")))
    assert rows and all(r["ok"] == "False" and math.isnan(float(r["simulated"])) for r in rows)
