"""Impact-table rows (crashlab.models.common.impact_rows, used by every model; docs/physics.md §21): EES from the
dissipated energy split by the struck structures' compliance 1/B (in series they carry the same force), PDOF from
the impulse direction, barrier names. Values worked by hand."""
import math

import numpy as np
import pytest

from crashlab.models.common.impact_rows import pair_rows

NAMES = ["V1", "V2"]
MASS = [1000.0, 2000.0]
DV = ((-3.0, 1.0, 0.5), (1.5, -0.5, -0.2))


# m^2/N, 1/B of (front, rear, left, right: both flanks the side structure) per vehicle: V1's front B = 500 kN/m^2,
# V2's side 250 kN/m^2
COMPLIANCE = np.array([[1 / 5e5, 1 / 3e5, 1 / 2e5, 1 / 2e5], [1 / 6e5, 1 / 4e5, 1 / 2.5e5, 1 / 2.5e5]])
FRONT, REAR, LEFT = 0, 1, 2


def test_energy_split_by_the_struck_structures_and_pdof_from_the_impulse():
    # force on V1 from straight ahead (heading 0, pushed backwards), on V2 from its left (heading 90 deg)
    rows = pair_rows(NAMES, MASS, 0, 1, 0.1, 3000.0, DV, ((-1.0, 0.0), (1.0, 0.0)), (0.0, math.pi / 2),
                     (1.0, 2.0), 0.3, "full", (FRONT, LEFT), COMPLIANCE, t_end=0.2)
    assert [r["vehicle"] for r in rows] == ["V1", "V2"] and [r["other"] for r in rows] == ["V2", "V1"]
    assert [r["side"] for r in rows] == ["front", "left"]
    # the same force f per unit width on both: E_q = f^2 / 2 B_q, so E_1 : E_2 = 1/500 : 1/250 = 1 : 2;
    # E_1 = 1000 J -> EES sqrt(2 * 1000 / 1000) = sqrt(2) m/s; E_2 = 2000 J -> sqrt(2 * 2000 / 2000) = sqrt(2) m/s
    assert [r["crush_energy"] for r in rows] == [pytest.approx(1000.0, rel=1e-12), pytest.approx(2000.0, rel=1e-12)]
    assert rows[0]["ees"] == pytest.approx(math.sqrt(2.0), rel=1e-12)
    assert rows[1]["ees"] == pytest.approx(math.sqrt(2.0), rel=1e-12)
    assert rows[0]["pdof"] == pytest.approx(0.0, abs=1e-12)
    assert rows[1]["pdof"] == pytest.approx(math.pi / 2, rel=1e-12)  # force +x on a car facing +y
    assert (rows[1]["dvx"], rows[1]["dvy"], rows[1]["d_yaw_rate"]) == DV[1]
    assert all(r["energy"] == 3000.0 and r["t_end"] == 0.2 and r["point_x"] == 1.0 and r["plane_angle"] == 0.3
               for r in rows)


def test_a_barrier_takes_no_energy_and_has_no_row():
    rows = pair_rows(NAMES, MASS, 1, 3, 0.0, 4000.0, DV[::-1], ((0.0, -1.0), None), (0.0, None), (0.0, 0.0),
                     0.0, "continuous", (REAR, None), COMPLIANCE)
    assert len(rows) == 1 and rows[0]["vehicle"] == "V2" and rows[0]["other"] == "barrier1"
    assert rows[0]["side"] == "rear"
    assert rows[0]["ees"] == pytest.approx(2.0, rel=1e-12)  # sqrt(2 * 4000 / 2000)
    assert rows[0]["pdof"] == pytest.approx(math.pi / 2, rel=1e-12)  # force towards -y: comes from the left


def test_negative_energy_gives_zero_ees():
    rows = pair_rows(NAMES, MASS, 0, 1, 0.0, -5.0, DV, ((1.0, 0.0), (-1.0, 0.0)), (0.0, 0.0), (0.0, 0.0), 0.0,
                     "sliding", (FRONT, FRONT), COMPLIANCE)
    assert [r["ees"] for r in rows] == [0.0, 0.0]
