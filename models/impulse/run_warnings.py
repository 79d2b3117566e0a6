"""The warnings of a finished run of the impulse model, from its impact records: no contact, a slip that reverses
under a law that does not follow it (docs/physics.md §3), an impact whose sustained contact decides its row (§5), an
engagement not placed as asked (§4), an impact that dissipates more energy than its engaged width absorbs within the
crush zones (§4 "Engaged width"), restitution = "speed" held at its end value outside the law's data (§13b). One
home for the Outcome (model.py) and the population (population.py), so both carry the same words."""
from __future__ import annotations

import math

import numpy as np

from crashlab.models.common.impact_rows import barrier_name
from crashlab.restitution import SPEED, range_warning
from crashlab.structure import STRUCK_FACES, crush_zone
from crashlab.units import ms_to_kmh

from . import layout as L
from .laws import SLIP_REVERSES

# the plastic follow-up impulses of an impact's sustained contact (§5) that change its impulse by more than this share
# of the impact's own make its row more the rigid outlines' contact than the impact law's: said (§5 "Sustained share")
SUSTAINED_SHARE = 0.5


def _label(names, n, r) -> str:
    """'impact n (Vi-Vj at t = ... s)': how every warning here names impact record r (row n; a barrier by its name)."""
    nv, i, j = len(names), int(r[L.I_I]), int(r[L.I_J])
    return f"impact {n + 1} ({names[i]}-{names[j] if j < nv else barrier_name(j - nv)} at t = {r[L.I_T]:.3f} s)"


def run_warnings(scene, names, mass, imp, speed_law: bool | None = None,
                 engagement_depth: float | None = None) -> list[str]:
    """The warnings of a finished run from its impact records imp (its n_impacts rows) and the vehicles' masses:
    no contact, a slip that reverses under a law that does not follow it (§3), an engagement not placed as asked
    (§4; engagement_depth None: the scene's), restitution = "speed" held at its end value (§13b; speed_law None:
    the scene's [impact] restitution says whether the law applies). The Outcome's and the population's
    (population.py, a variant's own depth) alike."""
    warnings = [] if len(imp) else ["no contact between the vehicles"]
    if scene.impact.law != "routh":
        warnings += _slip_warnings(names, mass, imp, scene.impact.law)
    warnings += _sustained_warnings(names, mass, imp)
    if scene.impact.engagement:
        depth = scene.impact.engagement_depth if engagement_depth is None else engagement_depth
        warnings += _engagement_warnings(names, imp, depth)
    warnings += [_capacity_warning(scene, names, n, r) for n, r in enumerate(imp) if over_capacity(r)]
    if scene.impact.restitution_law == SPEED if speed_law is None else speed_law:
        closing = imp[:, L.I_CLOSING]  # (a push's or a re-impact's row has none: NaN, no restitution used)
        warnings += [w for w in map(range_warning, closing[np.isfinite(closing)].tolist()) if w]
    return warnings


def _slip_warnings(names, mass, imp, law):
    """A warning per impact whose slip stops and reverses on Routh's path, or stops and sticks there where the
    law's sliding impulse reverses it (I_REVERSED: laws.SLIP_REVERSES, SLIP_OVERSHOOT), which `law` (friction
    against the initial slip throughout) gets wrong: its delta-V, direction and yaw-rate changes beside Routh's
    for the impact's own impulse (docs/physics.md §3)."""
    out = []
    nv = len(names)
    for n, r in enumerate(imp):
        if r[L.I_REVERSED] < 0.5:
            continue
        what = ("stops and reverses, which law = \"{law}\" does not follow (friction against the initial slip, or "
                "sticking where it cannot stick)" if r[L.I_REVERSED] == SLIP_REVERSES else
                "stops and sticks, where the sliding impulse of law = \"{law}\" reverses it (its friction against "
                "the initial slip runs on past the stop)").format(law=law)
        i, j = int(r[L.I_I]), int(r[L.I_J])
        own, alt = math.hypot(r[L.I_OWN_PN], r[L.I_OWN_PT]), math.hypot(r[L.I_ALT_PN], r[L.I_ALT_PT])
        off = math.degrees(abs(math.remainder(math.atan2(r[L.I_OWN_PT], r[L.I_OWN_PN])
                                              - math.atan2(r[L.I_ALT_PT], r[L.I_ALT_PN]), 2.0 * math.pi)))
        sides = [(i, L.I_OWN_DR_I, L.I_ALT_DR_I)] + ([(j, L.I_OWN_DR_J, L.I_ALT_DR_J)] if j < nv else [])
        dv = ", ".join(f"{names[q]} {ms_to_kmh(own / mass[q]):.1f} instead of {ms_to_kmh(alt / mass[q]):.1f} km/h"
                       for q, _, _ in sides)
        yaw = ", ".join(f"{names[q]} {math.degrees(r[o]):.0f} instead of {math.degrees(r[a]):.0f} deg/s"
                        for q, o, a in sides)
        out.append(f"{_label(names, n, r)}: the slip at the point of impact "
                   f"{what}: delta-V "
                   f"{100.0 * (own / alt - 1.0):+.0f} % ({dv}), its direction {off:.0f} deg off, yaw-rate change "
                   f"{yaw}; use [impact] law = \"routh\" (docs/physics.md §3)")
    return out


def _sustained_warnings(names, mass, imp):
    """A warning per impact whose episode's plastic follow-up impulses (§5: the rigid outlines touching on after the
    impact, up to PUSH_TIME) change its impulse by more than SUSTAINED_SHARE of the impact's own (`sustained`):
    the impact's own impulse as a share of the row's, and each vehicle's delta-V of the row beside the impact's own
    (docs/physics.md §5 "Sustained share")."""
    out = []
    nv = len(names)
    for n, r in enumerate(imp):
        if r[L.I_N_FOLLOW] < 1 or not sustained(r):  # (the scalar test first: most impacts have no follow-up)
            continue
        own = math.hypot(r[L.I_OWN_PN], r[L.I_OWN_PT])
        i, j = int(r[L.I_I]), int(r[L.I_J])
        sides = [(i, L.I_DVX_I, L.I_DVY_I)] + ([(j, L.I_DVX_J, L.I_DVY_J)] if j < nv else [])
        dv = "; ".join(f"{names[q]} {ms_to_kmh(math.hypot(r[x], r[y])):.1f} km/h, the impact's own "
                       f"{ms_to_kmh(own / mass[q]):.1f}" for q, x, y in sides)
        row = math.hypot(r[L.I_PN], r[L.I_PT])
        part = f"{100.0 * own / row:.0f} % of its row's" if row > 0.0 else "cancelled in its row"
        out.append(f"{_label(names, n, r)}: the impact's own impulse is "
                   f"{part}, the rest the plastic impulses of its sustained contact ({int(r[L.I_N_FOLLOW])} over "
                   f"{1e3 * (r[L.I_T_END] - r[L.I_T]):.0f} ms): its delta-V ({dv}) rests on the rigid outlines "
                   "touching on, which the impact law, taking the collision as over at once, does not "
                   "model; check it with a model that crushes (crashlab compare --models impulse,multibody; "
                   "docs/physics.md §5 \"Sustained share\")")
    return out


def sustained(recs):
    """Impact records (not a push's) whose follow-up impulses after the impact's instant change the impulse by more
    than SUSTAINED_SHARE of the impact's own (I_PN, I_PT: the row's; I_OWN_PN, I_OWN_PT: the impact's; §5
    "Sustained share"). A row whose follow-ups all came at the impact's instant (I_T_END = I_T: the sweeps over
    simultaneous contacts, a car squeezed against a wall) has no sustained contact. Any shape (..., N_IMP): a run's
    row, the population's records."""
    added = np.hypot(recs[..., L.I_PN] - recs[..., L.I_OWN_PN], recs[..., L.I_PT] - recs[..., L.I_OWN_PT])
    later = (recs[..., L.I_N_FOLLOW] >= 1) & (recs[..., L.I_T_END] > recs[..., L.I_T])
    return (recs[..., L.I_KIND] != L.PUSH) & later & \
        (added > SUSTAINED_SHARE * np.hypot(recs[..., L.I_OWN_PN], recs[..., L.I_OWN_PT]))


def _engagement_warnings(names, imp, depth):
    """A warning per impact that [impact] point = "engagement" could not place as asked (I_ENGAGE,
    contact._engagement, docs/physics.md §4)."""
    out = []
    for n, r in enumerate(imp):
        flag = int(r[L.I_ENGAGE])
        if flag not in (L.ENGAGE_AMBIGUOUS, L.ENGAGE_FALLBACK):
            continue
        what = _label(names, n, r)
        if flag == L.ENGAGE_AMBIGUOUS:
            out.append(f"{what}: the crushed faces at engagement give no contact plane (the smaller principal "
                       f"value is {100.0 * r[L.I_ENGAGE_RATIO]:.0f} % of the larger, above "
                       f"{100.0 * L.AMBIGUOUS_RATIO:.0f} %): the plane of the struck edge at first touch is used; give "
                       "[impact] point and plane_angle, or another engagement_depth (docs/physics.md §4)")
        else:
            out.append(f"{what}: the outlines moved along their velocities never overlap engagement_depth = "
                       f"{depth:g} m (or would not approach there): the contact-zone point and the first-touch "
                       "contact plane are used (docs/physics.md §4)")
    return out


def over_capacity(recs):
    """Impact records (not a push's) that dissipate more energy than their engaged width absorbs within the struck
    crush zones (I_CAPACITY, planar_vehicle.engaged_capacity); any shape (..., N_IMP): a run's row, the population's
    records."""
    return (recs[..., L.I_KIND] != L.PUSH) & (recs[..., L.I_ENERGY] > recs[..., L.I_CAPACITY])


def _capacity_warning(scene, names, n, r):
    """The structures of impact n cannot stop its overlap: the cars likely pass each other (a small overlap or a
    glance), or a vehicle crushes past its crush zone into a narrow barrier, where the impulse model's impact
    engages fully (docs/physics.md §4 "Engaged width")."""
    nv = len(names)
    i, j = int(r[L.I_I]), int(r[L.I_J])
    parts = [(names[q], scene.vehicles[q].spec, STRUCK_FACES[int(r[k])]) for q, k in ((i, L.I_SIDE_I), (j, L.I_SIDE_J))
             if q < nv]
    zones = " and ".join(f"{name}'s {face} ({crush_zone(spec, face)[0]:.2f} m)" for name, spec, face in parts)
    likely = ("the cars likely pass each other (a small overlap or a glance)" if j < nv else
              f"{names[i]} likely crushes past its crush zone or slides off the barrier (a narrow one, or its end)")
    return (f"{_label(names, n, r)}: its engaged width {r[L.I_WIDTH]:.2f} m "
            f"absorbs at most {r[L.I_CAPACITY] / 1e3:.0f} kJ within the crush zone{'s' if j < nv else ''} of {zones}, "
            f"the impact dissipates {r[L.I_ENERGY] / 1e3:.0f} kJ: the structures cannot stop the overlap and "
            f"{likely}, which the impulse model's impact, fully engaged, does not follow "
            f"(docs/physics.md §4 \"Engaged width\")")
