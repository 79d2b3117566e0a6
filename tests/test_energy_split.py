"""The impact rows' energy split (docs/physics.md §21): the two struck structures in series carry the same force f,
each absorbing f^2 / 2B over the same engaged width, so a vehicle's share of an impact's dissipated energy is
(1/B_own) / (1/B_own + 1/B_other), B of the side each one is struck on (front, rear, or a flank: the side
structure), in every model.
The reference is the vehicle files' B of the sides the scene strikes, written here; a split by 1/mass (the rule
before, which these equal-mass pairs split 1 : 1) fails it."""
from __future__ import annotations

from pathlib import Path

import pytest

import crashlab
from crashlab import fields
from crashlab.registry import get_model

REPO = Path(__file__).resolve().parent.parent
SIDE = REPO / "studies" / "pc_crash" / "side.toml"  # V1's front into the left side of V2 (two Clios)
REAR = REPO / "studies" / "validation" / "gbb_fiesta_polo_rear.toml"  # V1's front into V2's rear


def first_impact_shares(outcome) -> dict:
    """vehicle -> (crush_energy, energy) of the run's first impact."""
    t0 = min(r["t"] for r in outcome.impact_rows)
    return {r["vehicle"]: (r["crush_energy"], r["energy"]) for r in outcome.impact_rows if r["t"] == t0}


def expected_share(scene, struck: dict) -> dict:
    """vehicle -> its share of the energy from the files' B of the struck structures (front, rear, side)."""
    c = {v.name: 1.0 / v.spec.structure[struck[v.name]].B for v in scene.vehicles}
    return {name: c[name] / sum(c.values()) for name in c}


@pytest.mark.parametrize("heading", [0.0, 10.0, -10.0])  # V1 square on, or turned: its corner strikes first
@pytest.mark.parametrize("model_name, options", [("impulse", {}), ("pymunk", {}), ("multibody", {}),
                                                 ("multibody", {"contact_law": "generic"}), ("exudyn", {})])
def test_a_front_into_a_side_shares_the_energy_by_the_struck_structures(model_name, options, heading):
    scene = fields.set_field(crashlab.load_scene(SIDE), "vehicles.V1.heading", heading)
    want = expected_share(scene, {"V1": "front", "V2": "side"})
    assert want["V2"] == pytest.approx(0.64, abs=0.01)  # the Clio's side is the softer: B 241 against 429 kN/m^2
    out = get_model(model_name, **options).simulate(scene)
    got = first_impact_shares(out)
    assert set(got) == {"V1", "V2"}
    assert {r["vehicle"]: r["side"] for r in out.impact_rows if r["t"] == min(x["t"] for x in out.impact_rows)} == \
        {"V1": "front", "V2": "left"}
    for name, (crush, energy) in got.items():
        assert energy > 1e3 and crush == pytest.approx(want[name] * energy, rel=1e-9), (name, crush, energy)


def test_a_front_into_a_rear_shares_it_by_the_front_and_the_rear():
    scene = crashlab.load_scene(REAR)
    want = expected_share(scene, {"V1": "front", "V2": "rear"})
    got = first_impact_shares(get_model("impulse").simulate(scene))
    for name, (crush, energy) in got.items():
        assert crush == pytest.approx(want[name] * energy, rel=1e-9), name


def test_the_side_codes_are_the_struck_faces_in_order():
    """crush_structure.side_code's 0-3 index crashlab.structure.STRUCK_FACES (the rows' names, the compliance
    table's columns and Population.crush_energy's last axis; left is +y in vehicle axes), and structure_slot takes
    each to its structure's row (crush_structure.structure_row: front, rear, side)."""
    from crashlab.models.common.crush_structure import side_code, structure_slot
    from crashlab.structure import FACE_STRUCTURE, STRUCK_FACES, STRUCTURE_SIDES
    points = {"front": (1.9, 0.1), "rear": (-1.9, -0.1), "left": (0.1, 0.9), "right": (0.1, -0.9)}  # a 4 x 2 box
    assert {name: STRUCK_FACES[side_code(x, y, 2.0, 1.0)] for name, (x, y) in points.items()} == \
        {name: name for name in points}
    assert [STRUCTURE_SIDES[structure_slot(k)] for k in range(4)] == [FACE_STRUCTURE[f] for f in STRUCK_FACES]
