"""The impulse model's impact at a small overlap (docs/physics.md §4 "Engaged width"): its impulse-momentum impact
engages fully at any overlap (a Clio head-on with a saloon at 50/50 km/h takes 60 km/h of delta-V at 0.02 m of
overlap as at full width), which the crush structures over so narrow a width cannot give. A run whose impact
dissipates more energy than the engaged width absorbs within the struck crush zones says so; the population route
says it as the Outcome does.

References written here: the engaged width of two cars head-on at a lateral offset (the overlap of their widths);
two CRASH3 lines through zero force in series (f = B C, the same force per width in both), crushed through the
zone D (the front overhang) of the one with the smaller B D: f = min(B D), each absorbing f^2 / 2B per unit width."""
import sys
from pathlib import Path

import numpy as np
import pytest

from crashlab import fields
from crashlab.registry import get_model

sys.path.insert(0, str(Path(__file__).parent))
from conftest import build_scene  # noqa: E402

W_SALOON, W_CLIO = 1.832, 1.64


def _head_on(overlap, speed=50.0):
    return build_scene([{"vehicle": "saloon", "speed": speed},
                        {"vehicle": "clio", "x": 5.0, "y": 0.5 * (W_SALOON + W_CLIO) - overlap, "heading": 180.0,
                         "speed": speed}],
                       impact={"restitution": 0.1, "friction": 0.3}, road={"friction": 0.8}, duration=3.0)


def _hand_capacity(scene, width):
    """f = min(B D) over the two fronts (D the front overhang), then width * sum f^2 / 2B."""
    parts = [(v.spec.structure["front"].B, v.spec.cg_to_front - v.spec.cg_to_front_axle) for v in scene.vehicles]
    f = min(B * D for B, D in parts)
    return width * sum(f * f / (2.0 * B) for B, _ in parts)


@pytest.mark.parametrize("overlap", [0.05, 0.26])
def test_a_small_overlap_impact_says_its_width_cannot_stop_it(overlap):
    scene = _head_on(overlap)
    out = get_model("impulse").simulate(scene)
    said = [w for w in out.warnings if "engaged width" in w]
    assert len(said) == 1, out.warnings
    assert f"engaged width {overlap:.2f} m" in said[0]
    assert f"at most {_hand_capacity(scene, overlap) / 1e3:.0f} kJ" in said[0]
    assert "V1's front (0.90 m) and V2's front (0.65 m)" in said[0]


def test_a_full_width_impact_within_the_crush_zones_is_quiet():
    """Full width at 40/40 km/h: about 134 kJ to dissipate, 257 kJ of capacity over the Clio's 1.64 m."""
    out = get_model("impulse").simulate(_head_on(W_CLIO, speed=40.0))
    assert not [w for w in out.warnings if "engaged width" in w], out.warnings


def test_the_population_says_it_as_the_outcome():
    """The speeds 20 and 50 km/h at 0.26 m of overlap through the population route: the warning where the Outcome
    has it (50 km/h: 206 kJ against 40 kJ) and not where it has not (20 km/h: 33 kJ)."""
    model = get_model("impulse")
    scene = _head_on(0.26)
    paths = [fields.resolve(scene, "vehicles.V1.speed"), fields.resolve(scene, "vehicles.V2.speed")]
    values = np.array([[20.0, 20.0], [50.0, 50.0]])  # km/h, the file units of a field
    pop = model.simulate_population(scene, paths, values)
    build = fields.setter(scene, paths)
    for k, row in enumerate(values):
        want = [w for w in model.simulate(build(row)).warnings if "engaged width" in w]
        got = [w for w in (pop.warnings[k] or "").split("\n") if "engaged width" in w]
        assert got == want
    assert [bool(w and "engaged width" in w) for w in pop.warnings] == [False, True]


def _into_barrier(length, width, y=0.0, speed=50.0):
    """The saloon (its nose 2.072 m ahead of its CG) at `speed` into a barrier `length` x `width` (its length across
    the car's path) 3 m ahead of the nose, centred `y` to the side."""
    return build_scene([{"vehicle": "saloon", "speed": speed}],
                       barriers=[{"x": 2.072 + 3.0 + 0.5 * width, "y": y, "heading": 90.0, "length": length,
                                  "width": width}],
                       impact={"restitution": 0.1, "friction": 0.3}, road={"friction": 0.8}, duration=3.0)


def test_a_narrow_barrier_is_judged_by_its_own_width():
    """A 0.3 m pole at 50 km/h: the width is the pole's (it was the car's before), 0.3 x B D^2 / 2 of the saloon's
    front (rigid barrier: f = B D) = 72 kJ against about 143 kJ dissipated; a wall as wide as the road at the same
    speed absorbs it (1.832 m: 438 kJ) and is quiet."""
    model = get_model("impulse")
    out = model.simulate(_into_barrier(0.3, 0.3))
    said = [w for w in out.warnings if "engaged width" in w]
    assert len(said) == 1, out.warnings
    spec = _into_barrier(0.3, 0.3).vehicles[0].spec
    B, D = spec.structure["front"].B, spec.cg_to_front - spec.cg_to_front_axle
    assert "engaged width 0.30 m" in said[0]
    assert f"at most {0.3 * B * D * D / 2.0 / 1e3:.0f} kJ" in said[0]
    assert "slides off the barrier" in said[0]
    wall = model.simulate(_into_barrier(20.0, 0.5))
    assert not [w for w in wall.warnings if "engaged width" in w], wall.warnings
