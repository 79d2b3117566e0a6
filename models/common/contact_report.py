"""What the 3D models' chassis contact (chassis_contact.py) reports after a run: the guard's interpenetration check
with the contact bodies, the speed law's range warnings of the pairs' crushes (docs/physics.md §13a, §13b), and
the structures the contact used where they do not hold: a tilted vehicle's roof or underbody, a crush deeper than
the struck face's crush zone (§13a "A tilted body", §28 "Crush zone")."""
from __future__ import annotations

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
