"""The crush zone behind a struck face (docs/physics.md §28 "Crush zone"): a crush deeper than the front or rear
overhang, or than half the width for a flank, extrapolates the CRASH3 line past the structure it holds for, and
is said: by `crashlab damage` for a measured profile, by the 3D models for their simulated crush (each vehicle's
share of the pair's crush, split as the energy is by the struck structures in series, §21).

References written here: the overhangs from the saloon's file read with tomllib (front overhang = CG to bumper
less CG to front axle); the series split of one force per width f on two structures, C_q = f / B_q.
"""
from __future__ import annotations

import math
import sys
import tomllib
from importlib import resources
from pathlib import Path

import numpy as np
import pytest

from crashlab import damage
from crashlab.models.common.impact_rows import pair_rows
from crashlab.structure import crush_zone, crush_zone_warning
from crashlab.vehicle import load_vehicle

sys.path.insert(0, str(Path(__file__).parent))
from conftest import build_scene  # noqa: E402

SALOON = tomllib.loads(resources.files("crashlab").joinpath("vehicles/saloon.toml").read_text())
FRONT = SALOON["cg_to_front"] - SALOON["cg_to_front_axle"]                     # 0.900 m by its file's comment
REAR = (SALOON["length"] - SALOON["cg_to_front"]) - (SALOON["wheelbase"] - SALOON["cg_to_front_axle"])
HALF_WIDTH = SALOON["width"] / 2


def test_the_crush_zone_is_the_overhang_or_half_the_width():
    spec = load_vehicle("saloon")
    assert FRONT == pytest.approx(0.900, abs=1e-9)
    for face, depth in (("front", FRONT), ("rear", REAR), ("left", HALF_WIDTH), ("right", HALF_WIDTH)):
        assert crush_zone(spec, face)[0] == pytest.approx(depth, abs=1e-12)
        assert crush_zone_warning("V1", spec, face, depth) is None
        why = crush_zone_warning("V1", spec, face, depth + 0.01)
        assert why.startswith(f"V1's {face}: crush {depth + 0.01:.2f} m is deeper than its crush zone")
        assert f"{depth:.2f} m" in why and "too deep" in why


def test_each_vehicle_takes_its_structure_s_share_of_the_crush():
    """One force per width f on both structures in series: C_q = f / B_q, so a front of B 600 kN/m^2 against a
    side of 300 kN/m^2 crushes a third of the pair's 0.9 m and the side two thirds; against a barrier the car
    takes all of it."""
    b_front, b_side = 600e3, 300e3
    f = 0.9 / (1 / b_front + 1 / b_side)
    compliance = np.array([[1 / b_front, 1.0, 1.0, 1.0], [1.0, 1.0, 1 / b_side, 1 / b_side]])
    kw = dict(t=0.0, energy=1e4, dv=((0, 0, 0), (0, 0, 0)), push=((1, 0), (-1, 0)), heading=(0.0, 0.0),
              point=(0.0, 0.0), plane=0.0, kind="continuous", compliance=compliance)
    rows = pair_rows(["V1", "V2"], [1500.0, 1500.0], 0, 1, sides=(0, 2), crush=0.9, **kw)
    assert [r["crush"] for r in rows] == pytest.approx([f / b_front, f / b_side], rel=1e-12)
    assert [r["crush"] for r in rows] == pytest.approx([0.3, 0.6], rel=1e-12)
    barrier = pair_rows(["V1"], [1500.0], 0, 1, sides=(0, 0), crush=0.9, **{**kw, "compliance": compliance[:1]})
    assert [r["crush"] for r in barrier] == pytest.approx([0.9])
    assert "crush" not in pair_rows(["V1", "V2"], [1500.0, 1500.0], 0, 1, sides=(0, 2), **kw)[0]  # an impulse


@pytest.mark.parametrize("model", ["multibody", "exudyn"])
def test_a_small_overlap_crush_past_the_overhang_is_said(model):
    """Two saloons head-on at 50/50 km/h with 25 % overlap crush each front about 1.1 m, past the 0.90 m overhang
    (docs/physics.md §13a: the per-width structure has nothing behind it): each front is warned about, with its
    crush, the run stays ok (a warning, not a failure); each car's crush is half the pair's largest (equal
    structures). Full width at 30/30 km/h: about 0.4 m each, no warning."""
    from crashlab.registry import get_model
    width = SALOON["width"]

    def run(overlap, speed):
        sc = build_scene([{"vehicle": "saloon", "speed": speed},
                          {"vehicle": "saloon", "x": 5.2, "y": overlap * width, "heading": 180.0, "speed": speed}],
                         impact={"restitution": 0.1, "friction": 0.3}, road={"friction": 0.8}, duration=3.0)
        return get_model(model).simulate(sc)

    out = run(0.75, 50.0)
    assert out.outcome_ok, out.warnings
    first = [r for r in out.impact_rows if r["t"] == out.impact_rows[0]["t"]]
    assert [r["crush"] for r in first] == pytest.approx([0.5 * first[0]["max_penetration"]] * 2, rel=1e-12)
    deepest = {n: max(r["crush"] for r in out.impact_rows if r["vehicle"] == n and r["side"] == "front")
               for n in ("V1", "V2")}
    assert all(FRONT + 0.1 < c < 1.5 for c in deepest.values()), deepest
    zone = [w for w in out.warnings if "crush zone" in w]
    assert len(zone) == 2, out.warnings
    for n in ("V1", "V2"):
        assert any(w.startswith(f"{n}'s front: crush {deepest[n]:.2f} m") and f"front overhang {FRONT:.2f} m" in w
                   for w in zone), zone
    mild = run(0.0, 30.0)
    assert mild.outcome_ok and not [w for w in mild.warnings if "crush zone" in w], mild.warnings
    assert all(0.2 < r["crush"] < FRONT for r in mild.impact_rows), [r["crush"] for r in mild.impact_rows]


def test_a_measured_profile_past_the_crush_zone_warns():
    """`crashlab damage`: a front profile reaching 0.95 m (overhang 0.90 m) warns that its energy extrapolates the
    line; 0.85 m does not; a flank's zone is half the width (0.916 m)."""
    spec = load_vehicle("saloon")

    def zone(side, deepest):
        rep = damage.report(spec, side, [0.2, 0.5, deepest, 0.4], 1.5)
        return [w for w in rep["warnings"] if "crush zone" in w]

    assert zone("front", 0.85) == [] and zone("left", 0.9) == []
    (why,) = zone("front", 0.95)
    assert "measured crush 0.95 m" in why and "front overhang 0.90 m" in why and "likely low" in why
    (why,) = zone("right", 0.95)
    assert f"half width {HALF_WIDTH:.2f} m" in why
    assert math.isclose(crush_zone(spec, "left")[0], HALF_WIDTH)
