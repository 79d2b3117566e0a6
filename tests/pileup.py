"""A 32-car pile-up for the tests (issue 27): 4 lanes of 8 Clios, parked bumper to bumper (or `gap` apart),
the last car of each lane driving into its column at 50-80 km/h, slightly askew, so that cars are pressed
between others and spin into the next lane."""
from __future__ import annotations

from conftest import build_scene

CLIO_LENGTH = 2 * 1.8875  # m


def pileup(n_lanes: int = 4, per_lane: int = 8, duration: float = 5.0, gap: float = 0.0):
    vehicles = []
    for lane in range(n_lanes):
        for q in range(per_lane):
            v = {"name": f"L{lane + 1}C{q + 1}", "x": q * (CLIO_LENGTH + gap), "y": 3.0 * lane}
            if q == 0:
                v |= {"speed": 50.0 + 10.0 * lane, "heading": 3.0 * (lane - 1.5), "x": -5.0}
            vehicles.append(v)
    return build_scene(vehicles, duration=duration, name="pile-up")
