"""The 3D models' warning of concurrent contacts (models/common/contact_report.concurrent_contact_warnings,
docs/physics.md §21 "Concurrent contacts"): which rows it names, on rows written by hand. The models' runs:
tests/test_pileup_3d.py::test_multibody_says_which_rows_hold_concurrent_contacts."""
from __future__ import annotations

from crashlab.models.common.contact_report import concurrent_contact_warnings

MASS = {"A": 1000.0, "B": 1500.0, "C": 1200.0}


def row(vehicle, other, t, duration, jx, dv=(1.0, 0.0)):
    return {"vehicle": vehicle, "other": other, "t": t, "duration": duration, "impulse_x": jx, "impulse_y": 0.0,
            "dvx": dv[0], "dvy": dv[1]}


def test_overlapping_partners_are_named_with_both_delta_vs():
    # A struck by B from 0.10 to 0.20 s and by C from 0.15 to 0.30 s: 5,000 N s over 1,000 kg is 18.0 km/h
    out = concurrent_contact_warnings([row("A", "B", 0.10, 0.10, 5000.0, (2.0, 0.0)),
                                       row("A", "C", 0.15, 0.15, -2000.0, (0.0, 1.5))], MASS)
    assert len(out) == 1
    assert out[0].startswith("A's contacts with different partners overlap in time")
    assert "with B at t = 0.100 s: 7.2 km/h, its own contact impulse 18.0 km/h" in out[0]
    assert "with C at t = 0.150 s: 5.4 km/h, its own contact impulse 7.2 km/h" in out[0]


def test_no_warning_for_one_partner_at_a_time():
    rows = [row("A", "B", 0.10, 0.10, 5000.0), row("A", "B", 0.12, 0.06, 5000.0),  # the same partner twice
            row("A", "C", 0.20, 0.10, 5000.0),  # begins where B's ends: no overlap
            row("B", "A", 0.10, 0.10, 5000.0), row("B", "barrier0", 0.5, 0.1, 5000.0)]
    assert concurrent_contact_warnings(rows, MASS) == []


def test_contacts_of_no_impulse_are_left_out():
    # parked cars touching from the start: an episode whose impulse changes A's speed by less than 0.1 m/s
    rows = [row("A", "B", 0.0, 1.0, 99.0), row("A", "C", 0.2, 0.1, 5000.0)]
    assert concurrent_contact_warnings(rows, MASS) == []
    assert len(concurrent_contact_warnings([row("A", "B", 0.0, 1.0, 100.0), row("A", "C", 0.2, 0.1, 5000.0)],
                                           MASS)) == 1
