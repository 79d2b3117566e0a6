"""A tilted vehicle's struck face (docs/physics.md §13a "A tilted body"): a car lying on its side, struck on its roof
or its underbody, is struck there, not on the face its plan position suggests. Before 2026-11-27 the face came from
the contact point's body x and y alone: the roof of a car on its side, the point at the body's mid height, read
as its front or rear (or a flank), and the contact took that structure. No CRASH3 structure describes a roof or an
underbody: the side structure is used for them, with a warning; damage evidence stays on the four CRASH3 faces.

References written here: a point's face from its body coordinates by the bounding box's proportion rule; the
rotation R_z(90 deg) R_x(-90 deg) turns the body's +z (its roof) to -x in the plan.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from crashlab.models.common import chassis_contact as C
from crashlab.models.common.contact_force import FRICTION_V0, FRICTION_V1, FRICTION_VS
from crashlab.models.common.contact_report import structure_warnings
from crashlab.models.common.crush_structure import engagement_normal, face_code, structure_slot
from crashlab.models.common.impact_rows import pair_rows, struck_compliance
from crashlab.models.common.rotations import from_matrix
from crashlab.population import SIDE_INDEX
from crashlab.structure import IMPACT_FACES, STRUCK_FACES
from crashlab.vehicle import load_vehicle

SH = np.array([2.38, 0.916, 0.26, 0.5, 0.5, 0.0, 0.0])   # a saloon's chassis: a, b, c, eps1, eps2, offsets
A_FRONT, B_FRONT, B_SIDE = 48e3, 590e3, 370e3
STR = np.array([A_FRONT, B_FRONT, 1.832, 34e3, 304e3, 1.832, 16e3, B_SIDE, 4.7])


def _rz(t):
    return np.array([[math.cos(t), -math.sin(t), 0.0], [math.sin(t), math.cos(t), 0.0], [0.0, 0.0, 1.0]])


def _rx(t):
    return np.array([[1.0, 0.0, 0.0], [0.0, math.cos(t), -math.sin(t)], [0.0, math.sin(t), math.cos(t)]])


ON_ITS_SIDE = _rz(math.pi / 2) @ _rx(-math.pi / 2)        # roof (+z) towards -x, left flank (+y) down


def test_face_of_a_point_by_the_box_proportion():
    a, b, c = SH[:3]
    assert [face_code(a, 0.0, 0.0, a, b, c), face_code(-a, 0.1, 0.0, a, b, c), face_code(0.2, b, 0.0, a, b, c),
            face_code(0.2, -b, 0.1, a, b, c), face_code(0.5, 0.2, c, a, b, c), face_code(0.5, -0.2, -c, a, b, c)] \
        == [0, 1, 2, 3, 4, 5]
    # a barrier box (c = 0): its four upright faces only
    assert (face_code(1.0, 0.2, c, a, b, c), face_code(1.0, 0.2, c, a, b, 0.0)) == (4, 0)
    # the nose of a car pitched 30 deg down meets a horizontal push at its front, not its underbody
    d = np.array([math.cos(math.radians(30)), 0.0, math.sin(math.radians(30))])  # the push in the body frame
    s = np.sign(d) * np.abs(d * SH[:3]) ** (1 / 3) * SH[:3] ** (2 / 3)            # support point, exponent 4
    assert face_code(*s, a, b, c) == 0
    assert [structure_slot(k) for k in range(6)] == [0, 1, 2, 2, 2, 2]
    assert IMPACT_FACES[4:] == ("roof", "underbody") and set(STRUCK_FACES) < set(IMPACT_FACES)
    assert [SIDE_INDEX[f] for f in IMPACT_FACES] == list(range(6))


def test_engagement_normal_of_a_roof_turned_to_the_plan():
    """An upright car's front (+x) against the roof of a car on its side whose roof faces -x: the plan normal +x;
    an upright car's roof has no plan normal (no engagement)."""
    e0, e1, ok = engagement_normal(0, 4, np.eye(3), ON_ITS_SIDE, False)
    assert ok and (e0, e1) == pytest.approx((1.0, 0.0), abs=1e-12)
    assert not engagement_normal(0, 4, np.eye(3), np.eye(3) @ _rz(math.pi), False)[2]


def test_a_front_into_the_roof_of_a_car_on_its_side():
    """The contact kernel: V1 upright heading +x, V2 on its side ahead with its roof towards V1, 0.1 m of overlap.
    V2 is struck on its roof (code 4; before: its front, the point at its body's x = 0 and mid height), V1 on its
    front; the force pushes V1 back along -x and V2 along +x, from the front's B in series with V2's side B."""
    PP = C.pair_table(2, 0, 1e6, 1.5, np.array([STR, STR]), [1500.0, 1500.0])
    CT = C.contact_arrays(np.array([SH, SH]), PP, np.zeros((0, 5)), 2)
    CSH, BOXR, BOXA, BOXE, PP, PST, PSG, FX, BPC, OUT, FM = CT
    Y = np.zeros((2, 13))
    Y[0, :7] = [0.0, 0.0, 0.5, 1.0, 0.0, 0.0, 0.0]
    Y[1, :3] = [SH[0] + SH[2] - 0.1, 0.0, 0.5]
    Y[1, 3:7] = from_matrix(ON_ITS_SIDE)
    C.contacts(Y, 7, CSH, BOXR, BOXA, BOXE, PP, PST, PSG[0], FX, BPC, OUT, FM, 1.5, 0.0, 0.3, 0.0, FRICTION_V0,
               FRICTION_V1, FRICTION_VS, 1e-3, float(C.LAW_STRUCTURE), 0.1)
    assert (PST[0, C.S_SIDE_I], PST[0, C.S_SIDE_J]) == (0.0, 4.0)
    assert PSG[0, 0, C.G_DEL] > 0.0
    assert FX[0, 0] < 0.0 < FX[1, 0] and abs(FX[0, 1]) < 1e-6 * abs(FX[0, 0])


def test_roof_rows_book_the_side_structure_and_warn():
    """A roof strike's row: the side's compliance shares the energy and the crush; structure_warnings names the
    roof (and a crush past half the height, the roof's crush zone)."""
    spec = load_vehicle("saloon")

    class Vehicle:
        name, spec = "V2", None

    v1, v2 = Vehicle(), Vehicle()
    v1.name, v1.spec, v2.spec = "V1", spec, spec
    compliance = struck_compliance([spec, spec])
    assert compliance[1, 4] == compliance[1, 5] == pytest.approx(1 / spec.structure["side"].B)
    rows = pair_rows(["V1", "V2"], [1500.0, 1500.0], 0, 1, 0.0, 1e4, ((0, 0, 0), (0, 0, 0)), ((1, 0), (-1, 0)),
                     (0.0, 0.0), (0.0, 0.0), 0.0, "continuous", (0, 4), compliance, crush=0.9)
    b_f, b_s = spec.structure["front"].B, spec.structure["side"].B
    assert rows[1]["side"] == "roof"
    assert rows[1]["crush_energy"] == pytest.approx(1e4 * (1 / b_s) / (1 / b_f + 1 / b_s), rel=1e-12)

    class Scene:
        vehicles = [v1, v2]

    warned = structure_warnings(Scene, rows)
    assert any(w.startswith("V2 was struck on its roof") and "side structure" in w for w in warned), warned
    deep = rows[1]["crush"] > spec.height / 2
    assert any("half height" in w for w in warned) == deep
