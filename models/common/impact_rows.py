"""Rows of the impact table (framework/outcome.py IMPACT_COLUMNS, SI), one home for every model.

One impact (or contact episode) between vehicle i and vehicle j, or barrier j - nv when j >= nv (nv vehicles),
gives one row per vehicle: its delta-V and yaw-rate change, the pair's dissipated energy, the face it is struck on
(front, rear, left or right; a tilted vehicle in a 3D model also roof or underbody), its share of the energy
(crush_energy: the two struck structures in series carry the same force, so each takes the energy in proportion
to its crush compliance 1/B; a barrier takes none), its energy-equivalent speed (EES) from that share and the
principal direction of force (PDOF) from the direction of the impulse, or summed contact force, on it
(docs/physics.md §21).
"""
from __future__ import annotations

import math

import numpy as np

from crashlab.structure import FACE_STRUCTURE, IMPACT_FACES


def barrier_name(k: int) -> str:
    """Name of barrier k (its index in the scene's barriers) in the `other` column."""
    return f"barrier{k}"


def pdof(fx, fy, heading):
    """Principal direction of force on a vehicle [rad]: where the force (fx, fy), global, comes from, in the
    vehicle frame of the given heading, 0 = from straight ahead, counter-clockwise positive."""
    ang = math.atan2(-fy, -fx) - heading
    return math.atan2(math.sin(ang), math.cos(ang))


def struck_compliance(specs) -> np.ndarray:
    """(nv, 6) crush compliance 1/B [m^2/N] of each vehicle's front, rear, left, right, roof and underbody
    (IMPACT_FACES, the codes of crush_structure.face_code; both flanks, the roof and the underbody the side
    structure), from its crashlab.structure (file or class default, docs/physics.md §28)."""
    return np.array([[1.0 / spec.structure[FACE_STRUCTURE[face]].B for face in IMPACT_FACES]
                     for spec in specs]).reshape(-1, len(IMPACT_FACES))


def pair_rows(names, mass, i, j, t, energy, dv, push, heading, point, plane, kind, sides, compliance, crush=None,
              **extra) -> list[dict]:
    """Impact-table rows of one impact of vehicle i with vehicle or barrier j: one row for i, and one for j
    if it is a vehicle.

    names: vehicle names (nv of them); mass [kg] per vehicle; t [s]; energy [J] dissipated by the pair;
    per side s (0: i, 1: j; side 1 is not read for a barrier): dv[s] = (dvx, dvy, d_yaw_rate) [m/s, rad/s],
    push[s] = (fx, fy) the impulse or summed contact force on that vehicle (global; only its direction is
    used, for the PDOF), heading[s] [rad] the heading the PDOF is measured from; point = (x, y) [m],
    plane [rad] the contact plane; kind: "full", "sliding", "reversed", "push" or "continuous"; sides = (s_i, s_j) the
    struck face codes of i and j (crush_structure.face_code: 0 front, 1 rear, 2 left, 3 right, 4 roof, 5 underbody
    (a tilted vehicle in a 3D model); s_j not read for a
    barrier); compliance: the vehicles' (nv, 6) crush compliance table (struck_compliance); crush [m]: the pair's
    largest total crush (the 3D models; None for an impulse), shared as the energy is (the same force on both:
    C_q = crush (1/B_q) / (1/B_i + 1/B_j), all of it the vehicle's against a barrier), each row's "crush"; extra:
    further keys of every row (the impulse model: slip_reversed).
    """
    nv = len(names)
    c_i = compliance[i, int(sides[0])]
    c_j = compliance[j, int(sides[1])] if j < nv else 0.0
    struck = [(i, names[j] if j < nv else barrier_name(j - nv), c_i, int(sides[0]))]
    if j < nv:
        struck.append((j, names[i], c_j, int(sides[1])))
    rows = []
    for s, (q, other, c_q, side) in enumerate(struck):
        # §21: the struck structures in series carry the same force f, each absorbing f^2/2B: E_q ~ 1/B_q
        share = c_q / (c_i + c_j)
        e_q = max(energy, 0.0) * share
        own = {} if crush is None else {"crush": crush * share}
        rows.append({"t": t, "vehicle": names[q], "other": other, "dvx": dv[s][0], "dvy": dv[s][1],
                     "d_yaw_rate": dv[s][2], "energy": energy, "crush_energy": e_q,
                     "ees": math.sqrt(2.0 * e_q / mass[q]),
                     "pdof": pdof(push[s][0], push[s][1], heading[s]), "kind": kind, "side": IMPACT_FACES[side],
                     "point_x": point[0], "point_y": point[1], "plane_angle": plane, **own, **extra})
    return rows
