"""Rows of the impact table (framework/outcome.py IMPACT_COLUMNS, SI), one home for every model.

One impact (or contact episode) between vehicle i and vehicle j, or barrier j - nv when j >= nv (nv vehicles),
gives one row per vehicle: its delta-V and yaw-rate change, the pair's dissipated energy, the vehicle's share of
it (crush_energy, the energy split in proportion to 1 / mass; a barrier takes none), its energy-equivalent
speed (EES) from that share and the principal direction
of force (PDOF) from the direction of the impulse, or summed contact force, on it (docs/physics.md §21).
"""
from __future__ import annotations

import math


def barrier_name(k: int) -> str:
    """Name of barrier k (its index in the scene's barriers) in the `other` column."""
    return f"barrier{k}"


def pdof(fx, fy, heading):
    """Principal direction of force on a vehicle [rad]: where the force (fx, fy), global, comes from, in the
    vehicle frame of the given heading, 0 = from straight ahead, counter-clockwise positive."""
    ang = math.atan2(-fy, -fx) - heading
    return math.atan2(math.sin(ang), math.cos(ang))


def pair_rows(names, mass, i, j, t, energy, dv, push, heading, point, plane, kind, **extra) -> list[dict]:
    """Impact-table rows of one impact of vehicle i with vehicle or barrier j: one row for i, and one for j
    if it is a vehicle.

    names: vehicle names (nv of them); mass [kg] per vehicle; t [s]; energy [J] dissipated by the pair;
    per side s (0: i, 1: j; side 1 is not read for a barrier): dv[s] = (dvx, dvy, d_yaw_rate) [m/s, rad/s],
    push[s] = (fx, fy) the impulse or summed contact force on that vehicle (global; only its direction is
    used, for the PDOF), heading[s] [rad] the heading the PDOF is measured from; point = (x, y) [m],
    plane [rad] the contact plane; kind: "full", "sliding", "reversed" or "continuous"; extra: further keys of
    every row (the impulse model: slip_reversed).
    """
    nv = len(names)
    inv_i, inv_j = 1.0 / mass[i], (1.0 / mass[j] if j < nv else 0.0)
    sides = [(i, names[j] if j < nv else barrier_name(j - nv), inv_i)]
    if j < nv:
        sides.append((j, names[i], inv_j))
    rows = []
    for s, (q, other, inv_q) in enumerate(sides):
        # deformation energy split assuming crush stiffness proportional to mass (equal force: E_q ~ 1 / m_q)
        e_q = max(energy, 0.0) * inv_q / (inv_i + inv_j)
        rows.append({"t": t, "vehicle": names[q], "other": other, "dvx": dv[s][0], "dvy": dv[s][1],
                     "d_yaw_rate": dv[s][2], "energy": energy, "crush_energy": e_q,
                     "ees": math.sqrt(2.0 * e_q / mass[q]),
                     "pdof": pdof(push[s][0], push[s][1], heading[s]), "kind": kind,
                     "point_x": point[0], "point_y": point[1], "plane_angle": plane, **extra})
    return rows
