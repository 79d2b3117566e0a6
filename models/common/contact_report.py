"""What the 3D models' chassis contact (chassis_contact.py) reports after a run: the guard's interpenetration check
with the contact bodies, the speed law's range warnings of the pairs' crushes (docs/physics.md §13a, §13b), the
structures the contact used where they do not hold: a tilted vehicle's roof or underbody, a crush deeper than
the struck face's crush zone (§13a "A tilted body", §28 "Crush zone"), a vehicle's contacts with different
partners at the same time, whose rows' delta-Vs each hold them all (§21 "Concurrent contacts"), and an impact row
whose delta-V the road forces of a long contact moved away from its contact impulse (§15 "Road forces in a row")."""
from __future__ import annotations

import math

from crashlab.outcome import PUSH, PUSH_TIME
from crashlab.restitution import range_warning
from crashlab.structure import TILTED_FACES, crush_zone_warning

from .chassis_contact import G_DEL, P_I, P_J, S_CMAX, S_VCLOSE


def end_overlap(names, PP, psg):
    """The guard's interpenetration check with the contact bodies (superellipsoid chassis, barrier boxes) at
    the last evaluation: a reason when a pair ends penetrating deeper than guard.PENETRATION_TOL, else None."""
    from crashlab.guard import PENETRATION_TOL
    nv = len(names)
    for p in range(PP.shape[0]):
        d = psg[p, G_DEL]
        if d > PENETRATION_TOL:
            i, j = int(PP[p, P_I]), int(PP[p, P_J])
            other = names[j] if j < nv else f"barrier {j - nv}"
            return f"{names[i]} and {other} end penetrating by {d:.2f} m (contact bodies)"
    return None


def speed_law_warnings(PST) -> list:
    """restitution = "speed": the reason for each pair whose (last) crush began at a closing speed outside the
    law's data (crashlab.restitution.range_warning); pairs that never touched have no closing speed."""
    out = []
    for p in range(PST.shape[0]):
        if PST[p, S_CMAX] > 0.0:
            why = range_warning(PST[p, S_VCLOSE])
            if why and why not in out:
                out.append(why)
    return out


def structure_warnings(scene, rows) -> list:
    """What the impact rows say of the structures the contact used: each tilted vehicle's roof or underbody
    struck, which no CRASH3 structure describes (its side structure is used; §13a "A tilted body"), and each
    vehicle face whose deepest crush (the rows' "crush", the vehicle's share of the pair's) lies beyond its crush
    zone (crashlab.structure.crush_zone_warning, §28)."""
    deepest: dict = {}
    for r in rows:
        key = (r["vehicle"], r["side"])
        deepest[key] = max(deepest.get(key, 0.0), r["crush"])
    specs = {vs.name: vs.spec for vs in scene.vehicles}
    out = []
    for (name, face), crush in deepest.items():
        if face in TILTED_FACES:
            out.append(f"{name} was struck on its {face} (the vehicle tilted): no CRASH3 structure describes a "
                       f"{face}, so the contact and the energy split took its side structure (docs/physics.md §13a "
                       f"\"A tilted body\")")
        why = crush_zone_warning(name, specs[name], face, crush)
        if why:
            out.append(why)
    return out


# a contact whose own impulse changes a vehicle's speed by less [m/s] is left out of concurrent_contact_warnings
# (parked cars touching from the start open episodes of no impulse)
CONCURRENT_DV = 0.1


def _contacts(rows, mass) -> dict:
    """{vehicle: (its rows whose own contact impulse changes its speed by CONCURRENT_DV at least, those of them that
    overlap in time (t to t + duration) with a row of another partner, by time)}."""
    by_vehicle: dict = {}
    for r in rows:
        if math.hypot(r["impulse_x"], r["impulse_y"]) >= CONCURRENT_DV * mass[r["vehicle"]]:
            by_vehicle.setdefault(r["vehicle"], []).append(r)
    return {name: (mine, sorted((a for a in mine if any(b["other"] != a["other"] and b["t"] < a["t"] + a["duration"]
                                                         and a["t"] < b["t"] + b["duration"] for b in mine)),
                                key=lambda a: a["t"]))
            for name, mine in by_vehicle.items()}


def concurrent_contact_warnings(rows, mass, contacts=None) -> list:
    """One reason per vehicle whose contact episodes with different partners overlap in time (the rows' t to
    t + duration; pushes included): a 3D row's delta-V is the vehicle's CG velocity change over its episode, so
    each of those rows holds the other contacts' impulses too (§21 "Concurrent contacts"); the reason gives each
    such row's delta-V beside its own contact impulse (in plan) over the vehicle's mass. mass: {name: kg}; rows
    with the 3D models' impulse_x, impulse_y and duration; contacts: _contacts(rows, mass) where already found."""
    out = []
    for name, (_, hit) in (_contacts(rows, mass) if contacts is None else contacts).items():
        if not hit:
            continue
        shown = "; ".join(f"with {a['other']} at t = {a['t']:.3f} s: {3.6 * math.hypot(a['dvx'], a['dvy']):.1f} "
                          f"km/h, its own contact impulse "
                          f"{3.6 * math.hypot(a['impulse_x'], a['impulse_y']) / mass[name]:.1f} km/h" for a in hit[:4])
        more = f"; and {len(hit) - 4} more" if len(hit) > 4 else ""
        out.append(f"{name}'s contacts with different partners overlap in time: each of their rows' delta-V is "
                   f"{name}'s CG velocity change over its episode and holds the other contacts' impulses too "
                   f"({shown}{more}; docs/physics.md §21 \"Concurrent contacts\")")
    return out


# a row (an impact's, not a push's) whose contact lasts longer than a collision's pulse (about 0.1-0.2 s, §5; PUSH_TIME
# / 2) and whose delta-V differs from its own contact impulse over the vehicle's mass by more than ROAD_SHARE of the
# latter (in plan) is said: the road forces of the long contact moved it (§15 "Road forces in a row")
ROAD_SHARE = 0.1
LONG_CONTACT = PUSH_TIME / 2


def road_share_warnings(rows, mass, contacts=None) -> list:
    """One reason per impact row whose contact lasts longer than LONG_CONTACT and whose delta-V (the vehicle's CG
    velocity change over its episode, §15) lies more than ROAD_SHARE of its own contact impulse over the mass away
    from that (the vector difference in plan, printed as the road's part). Rows that overlap a contact with
    another partner are concurrent_contact_warnings' (their difference is the other contact's). mass: {name: kg};
    contacts: _contacts(rows, mass) where already found."""
    out = []
    for name, (mine, hit) in (_contacts(rows, mass) if contacts is None else contacts).items():
        concurrent = {id(a) for a in hit}
        for r in mine:
            if r["kind"] == PUSH or id(r) in concurrent or r["duration"] <= LONG_CONTACT:
                continue
            jx, jy = r["impulse_x"] / mass[name], r["impulse_y"] / mass[name]
            road = math.hypot(r["dvx"] - jx, r["dvy"] - jy)
            if road <= ROAD_SHARE * math.hypot(jx, jy):
                continue
            out.append(f"{name}'s delta-V in its impact with {r['other']} at t = {r['t']:.3f} s, "
                       f"{3.6 * math.hypot(r['dvx'], r['dvy']):.1f} km/h, is its CG's velocity change over the "
                       f"{1e3 * r['duration']:.0f} ms contact: its contact impulse alone gives "
                       f"{3.6 * math.hypot(jx, jy):.1f} km/h (as the impulse model and CRASH3 count it), and the road "
                       f"forces over the contact {3.6 * road:.1f} km/h ({100.0 * road / math.hypot(jx, jy):.0f} % "
                       "of that); a measured delta-V matches the one or the other as far as its window takes in the "
                       "tyres (docs/physics.md §15 \"Road forces in a row\")")
    return out


def row_warnings(scene, rows, mass) -> list:
    """What a 3D run's impact rows say (the models' one call): structure_warnings, concurrent_contact_warnings and
    road_share_warnings. mass: {name: kg}."""
    contacts = _contacts(rows, mass)  # (the vehicles' contacts and their concurrent ones, found once for both)
    return (structure_warnings(scene, rows) + concurrent_contact_warnings(rows, mass, contacts)
            + road_share_warnings(rows, mass, contacts))
