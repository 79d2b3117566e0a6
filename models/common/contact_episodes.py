"""Contact episodes of the 3D models (docs/physics.md §15, §21): a pair's contact from onset (first
penetration) to separation, its bookkeeping and its rows of the impact table.

Per episode, in the pair state PST (chassis_contact.S_*): onset time, approach velocity at onset, the
velocities (vx, vy, yaw rate) of both vehicles at onset, and the sums the models accumulate over their
accepted steps with their own quadrature weights (multibody: the Dormand-Prince weights of the stage forces;
exudyn: the trapezoidal rule over the step ends): impulse, work of the contact forces, peak normal force
(with the contact point and normal there) and the largest penetration. `close_episode` writes one record
IMP[n] (I_* columns) and resets the pair; `impact_rows` turns the records into the impact table;
`contact_intervals` merges episodes and road contact into the Outcome's contact intervals.
The numba helpers are called from multibody's time loop and from exudyn's Python step functions alike.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from crashlab.outcome import PUSH, PUSH_DV_MIN, PUSH_TIME, REIMPACT_SPEED, SEPARATION

from .chassis_contact import (
    ENDED,
    FM_ANY,
    G_CRUSH,
    G_DEL,
    G_ENG,
    G_FN,
    G_FX,
    G_MEAS,
    G_NS,
    G_OWN,
    G_POW,
    G_PX,
    G_PY,
    G_RAW,
    G_STRIP,
    G_TH,
    IN_CONTACT,
    N_FACE_BIN,
    NONE,
    P_I,
    P_J,
    P_MEFF,
    S_ACT,
    S_CI,
    S_CM,
    S_CM1,
    S_CM2,
    S_CMAX,
    S_CR,
    S_DD0,
    S_DD1,
    S_DDT,
    S_ENG,
    S_JR,
    S_JX,
    S_MAXPEN,
    S_PEAK,
    S_PTH,
    S_PUSH,
    S_PX,
    S_PY,
    S_RT,
    S_SIDE_I,
    S_SIDE_J,
    S_T0,
    S_T1,
    S_VEI,
    S_VEJ,
    S_VI,
    S_VJ,
    S_WORK,
)
from .impact_rows import pair_rows

# episode records IMP[k]: pair, onset and end time, impulse on i (3), peak normal force, max penetration,
# energy dissipated (-work), point and normal angle at the peak, velocity changes of i and j (vx, vy, yaw
# rate), approach velocity at onset, normal velocity at the end, still open at the end of the run, the struck sides
# of i and j (crush_structure.face_code; 0 for a barrier), whose structures share the energy (§21)
(I_I, I_J, I_T0, I_T1, I_JX, I_JY, I_JZ, I_PEAK, I_MAXPEN, I_ENERGY, I_PX, I_PY, I_TH, I_DVI, I_DVJ,
 I_DD0, I_DD1, I_OPEN, I_SIDE_I, I_SIDE_J) = 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 16, 19, 20, 21, 22, 23
# I_PUSH: the record's kind, as the pair state's S_PUSH while it is open: IMPACT (an impact, from the pair's first
# touch), PUSHING (the pair's contact later than PUSH_TIME after its impact or re-impact, kind "push") or REIMPACT (a
# re-touch later than PUSH_TIME, or in a push, closing at REIMPACT_SPEED or faster: its crushed structures damped as
# a push's; close_episode writes it as an impact row where its impulse changes the pair's relative velocity by
# REIMPACT_SPEED or more, else as a push's; docs/physics.md §15 "Re-impacts")
I_PUSH = 24
IMPACT, PUSHING, REIMPACT = 0.0, 1.0, 2.0
N_IMP = 25
# a re-touch within an episode whose contact carries less than this share of the episode's impulse so far is a graze:
# its end does not move the episode's end, so the impact's delta-V and duration are its pulse's, not the pulse's
# plus the tyre forces until the graze (docs/physics.md §15 "Episodes and pushes")
GRAZE_SHARE = 0.01
# m/s: the least normal approach speed at a touch whose rebound ratio an impact row reports as its restitution
# (a car's corner grazing a post touched at 0.001 m/s along a normal that then turned: "e" 2800)
APPROACH_MIN = 0.1
EPISODES_PER_PAIR = 64  # records per pair of bodies that can touch (two vehicles, a vehicle and a barrier)


def episode_capacity(n_vehicles: int, n_barriers: int) -> int:
    """Rows of a run's episode records: EPISODES_PER_PAIR for each pair that can touch (a fixed 64 per run failed
    5 of 30 random 3-5 car scenes whose resting pairs touched again and again; tests/test_guard_audit.py)."""
    pairs = n_vehicles * (n_vehicles - 1) // 2 + n_vehicles * n_barriers
    return EPISODES_PER_PAIR * max(1, pairs)


@njit(cache=True)
def open_episode(PST, p, t0, dd0, vel_i, vel_j):
    """Mark pair p active from t0 at its first touch with the approach velocity dd0 (also the touch's, the generic
    law's delta_dot0 S_DDT) and the velocities (vx, vy, yaw rate) of its vehicles (vel_j is ignored by the records
    of a barrier pair)."""
    _open_record(PST, p, t0, dd0, vel_i, vel_j)
    PST[p, S_DDT] = dd0


@njit(cache=True)
def _open_record(PST, p, t0, dd0, vel_i, vel_j):
    """open_episode's record: active from t0, its approach velocity dd0 and the vehicles' velocities."""
    PST[p, S_ACT] = IN_CONTACT
    PST[p, S_DD0] = dd0
    PST[p, S_T0] = t0
    PST[p, S_RT] = 0.0
    for k in range(3):
        PST[p, S_VI + k] = vel_i[k]
        PST[p, S_VJ + k] = vel_j[k]


@njit(cache=True)
def accumulate(PST, p, w, out):
    """Add w times the pair's outputs `out` (a PSG row: force, power) to its impulse and work."""
    for k in range(3):
        PST[p, S_JX + k] += w * out[G_FX + k]
    PST[p, S_WORK] += w * out[G_POW]


@njit(cache=True)
def sync_crush(PST, p, out):
    """The continuous crush's reference (docs/physics.md §13a): the crush of the accepted evaluation `out`, its
    geometric measure and which one it is, and whether it was engaged (S_ENG; a pair the broad phase left out is not
    measured: kept)."""
    if out[G_MEAS] == 0.0:
        return
    PST[p, S_CI], PST[p, S_CR], PST[p, S_CM] = out[G_CRUSH], out[G_RAW], out[G_MEAS]
    PST[p, S_ENG] = out[G_ENG]


@njit(cache=True)
def track_peak(PST, p, out, PP, FM):
    """Keep the peak normal force (with the point and normal angle there) and the largest penetration (the
    overlap of the undeformed shapes, the total crush); in contact, the pair's largest crush S_CMAX and the
    vehicles' face memories FM (the structure law's memories, §13a, "Face memory": updated only here, at accepted
    evaluations); the continuous crush's reference (sync_crush: the models call this for the stages of an accepted
    step in order, the step's end last)."""
    sync_crush(PST, p, out)
    if out[G_FN] > PST[p, S_PEAK]:
        PST[p, S_PEAK] = out[G_FN]
        PST[p, S_PX], PST[p, S_PY], PST[p, S_PTH] = out[G_PX], out[G_PY], out[G_TH]
    if out[G_DEL] > 0.0:
        if out[G_CRUSH] > PST[p, S_MAXPEN]:
            PST[p, S_MAXPEN] = out[G_CRUSH]
        if out[G_CRUSH] > PST[p, S_CMAX]:
            PST[p, S_CMAX] = out[G_CRUSH]
        if out[G_NS] > 0.0:
            remember_strips(PST, p, out)
            remember_faces(FM, int(PP[p, P_I]), int(PP[p, P_J]), out)


@njit(cache=True)
def remember_strips(PST, p, out):
    """Each structure's own largest crush in pair p (S_CM1, S_CM2; §13a "Face memory"): its crush at the deepest
    bearing strip of the accepted evaluation `out` with its share of that strip's setback added back (G_OWN; one
    pair's loading alone gives its share of the pair's crush), kept where larger."""
    PST[p, S_CM1] = max(PST[p, S_CM1], out[G_OWN])
    PST[p, S_CM2] = max(PST[p, S_CM2], out[G_OWN + 1])


@njit(cache=True)
def remember_faces(FM, i, j, out):
    """The face memory (§13a "Face memory") of vehicles i and j (j >= nv: a barrier, none) after the accepted
    evaluation `out` (its G_STRIP records): each bin keeps the largest over the evaluations of the least crush of
    the strips on it (a bin's strips crush unevenly where the face slopes across the normal: its least crush is
    the memory every strip on it has reached) and, from FM_ANY, of their largest (what any place on it reached),
    kept on the bin and its two neighbours on the face."""
    nv = FM.shape[0]
    ns = int(out[G_NS])
    for side in range(2):
        q = i if side == 0 else j
        if q >= nv:
            continue
        cur, low, high = -1, 0.0, 0.0
        for k in range(ns + 1):
            b = int(out[G_STRIP + 4 * k + 2 * side]) if k < ns else -1
            c = out[G_STRIP + 4 * k + 2 * side + 1] if k < ns else 0.0
            if b == cur and b >= 0:
                low, high = min(low, c), max(high, c)
                continue
            if cur >= 0:
                FM[q, cur] = max(FM[q, cur], low)
                # what any place reached, on the bin and its neighbours on the face: every pair of bins a later
                # strip reads between (chassis_contact._face_memory) holds the crush of the strips near it (24
                # strips over 32 bins leave bins without a strip of their own)
                first = cur - cur % N_FACE_BIN
                for nb in range(max(cur - 1, first), min(cur + 2, first + N_FACE_BIN)):
                    FM[q, FM_ANY + nb] = max(FM[q, FM_ANY + nb], high)
            cur, low, high = b, c, c


@njit(cache=True)
def reset_sums(PST, p):
    """Clear the pair's episode sums (impulse, peak, max penetration, work)."""
    for k in range(S_JX, S_WORK + 1):
        PST[p, k] = 0.0


@njit(cache=True)
def close_episode(IMP, n, PP, PST, p, t1, dd1, is_open, vel_i, vel_j):
    """Write the episode of pair p ending at t1 (normal velocity dd1 there, vehicles' velocities vel_i,
    vel_j now) as record IMP[n] if there is room, deactivate and reset the pair; returns n + 1 (n for a push below
    PUSH_DV_MIN, not written). A re-impact's record whose impulse changes the pair's relative velocity by less
    than REIMPACT_SPEED is a push's: its closing speed at the touch was a corner's turning or a step end's, not the
    pair's (exudyn's NHTSA 4363: 2.6 m/s at the touch, 0.2 m/s of exchange)."""
    jj = PST[p, S_JX] ** 2 + PST[p, S_JX + 1] ** 2 + PST[p, S_JX + 2] ** 2
    kind = PST[p, S_PUSH]
    if kind == REIMPACT and jj < (REIMPACT_SPEED * PP[p, P_MEFF]) ** 2:
        kind = PUSHING
    skip = kind == PUSHING and jj < (PUSH_DV_MIN * PP[p, P_MEFF]) ** 2
    if not skip and n < IMP.shape[0]:
        r = IMP[n]
        r[I_I], r[I_J], r[I_T0], r[I_T1] = PP[p, P_I], PP[p, P_J], PST[p, S_T0], t1
        for k in range(3):
            r[I_JX + k] = PST[p, S_JX + k]
            r[I_DVI + k] = vel_i[k] - PST[p, S_VI + k]
            r[I_DVJ + k] = vel_j[k] - PST[p, S_VJ + k]
        r[I_PEAK], r[I_MAXPEN], r[I_ENERGY] = PST[p, S_PEAK], PST[p, S_MAXPEN], -PST[p, S_WORK]
        r[I_PX], r[I_PY], r[I_TH] = PST[p, S_PX], PST[p, S_PY], PST[p, S_PTH]
        r[I_DD0], r[I_DD1], r[I_OPEN] = PST[p, S_DD0], dd1, is_open
        r[I_SIDE_I], r[I_SIDE_J] = PST[p, S_SIDE_I], PST[p, S_SIDE_J]
        r[I_PUSH] = kind
    PST[p, S_ACT] = NONE
    PST[p, S_PUSH] = IMPACT
    reset_sums(PST, p)
    return n if skip else n + 1


@njit(cache=True)
def _close_ended(IMP, n, PP, PST, p):
    """Write the ended episode of pair p with its end (S_T1, S_DD1, the velocities there)."""
    return close_episode(IMP, n, PP, PST, p, PST[p, S_T1], PST[p, S_DD1], 0.0,
                         (PST[p, S_VEI], PST[p, S_VEI + 1], PST[p, S_VEI + 2]),
                         (PST[p, S_VEJ], PST[p, S_VEJ + 1], PST[p, S_VEJ + 2]))


@njit(cache=True)
def _open_late(PST, p, t0, dd, vel_i, vel_j, touch, kind):
    """Open the record of pair p at t0 that follows its impact's (or re-impact's) record, of kind PUSHING or
    REIMPACT (I_PUSH): at a re-touch (touch) the generic law's delta_dot0 is its approach velocity dd; a contact
    that goes on keeps its own. Both are damped (crushed structures, §13a "Push damping")."""
    _open_record(PST, p, t0, max(dd, 0.0), vel_i, vel_j)
    if touch:
        PST[p, S_DDT] = max(dd, 0.0)
    PST[p, S_PUSH] = kind


@njit(cache=True)
def episode_step(IMP, n, PP, PST, p, t, t_part, t_touch, d, gap, dd, vel_i, vel_j):
    """The episode of an active pair p at the end of an accepted step at t (docs/physics.md §15 "Episodes and
    pushes"): in contact d = G_DEL > 0, shapes' gap `gap`, normal velocity dd, velocities vel_i, vel_j (vx, vy, yaw
    rate); t_part, t_touch: when within the step the contact ended or began again. A contact that ends is kept
    (ENDED, its end remembered) until the pair is SEPARATION apart, then written; a re-touch before continues the
    episode. The contact later than PUSH_TIME after the episode's start is a push, from the first step end where
    the pair is not separating (dd >= 0): the episode is written there and a push record opened, which later
    re-touches continue; a re-touch later than PUSH_TIME (or in a push) that closes at REIMPACT_SPEED or faster
    opens a re-impact's record instead, which a push follows by the same rule (close_episode writes it as an impact
    row where its impulse is a collision's). Returns the number of records written so far."""
    state = PST[p, S_ACT]
    late = PST[p, S_PUSH] != PUSHING   # an impact's or re-impact's record, which a push follows
    if state == IN_CONTACT:
        if d <= 0.0:
            PST[p, S_ACT] = ENDED
            if not _graze(PST, p):
                PST[p, S_T1], PST[p, S_DD1] = t_part, dd
                for k in range(3):
                    PST[p, S_VEI + k], PST[p, S_VEJ + k] = vel_i[k], vel_j[k]
            PST[p, S_RT] = 0.0
        elif late and t - PST[p, S_T0] >= PUSH_TIME and dd >= 0.0:
            # not while the pair separates: an impact still unloading (a soft or narrow contact longer than
            # PUSH_TIME) keeps its rebound, which the push's damping would take (§15 "Episodes and pushes")
            n = close_episode(IMP, n, PP, PST, p, t, dd, 0.0, vel_i, vel_j)
            _open_late(PST, p, t, dd, vel_i, vel_j, False, PUSHING)
    elif state == ENDED:
        if d > 0.0:
            hard = dd >= REIMPACT_SPEED
            if (late and t_touch - PST[p, S_T0] >= PUSH_TIME) or (not late and hard):
                # a re-touch after the pulse: the push, or closing as fast as a collision, a re-impact
                n = _close_ended(IMP, n, PP, PST, p)
                _open_late(PST, p, t_touch, dd, vel_i, vel_j, True, REIMPACT if hard else PUSHING)
            else:  # a re-touch within the episode: the generic law's delta_dot0 is its own (chassis_contact S_DDT)
                PST[p, S_ACT], PST[p, S_DDT] = IN_CONTACT, max(dd, 0.0)
                PST[p, S_RT] = 1.0
                for k in range(3):
                    PST[p, S_JR + k] = PST[p, S_JX + k]
        elif gap >= SEPARATION:
            n = _close_ended(IMP, n, PP, PST, p)
    return n


@njit(cache=True)
def _graze(PST, p):
    """Whether the contact of pair p now ending is a graze: a re-touch within its episode whose impulse is less than
    GRAZE_SHARE of the episode's before it (a light touch of the swiping fronts after an oblique impact, 0.2 s after
    its pulse; the 2026-11-28 probe: the impulse of NHTSA 4364's impact row equal to 4 digits with or without)."""
    if PST[p, S_RT] == 0.0:
        return False
    dj = jr = 0.0
    for k in range(3):
        dj += (PST[p, S_JX + k] - PST[p, S_JR + k]) ** 2
        jr += PST[p, S_JR + k] ** 2
    return dj < GRAZE_SHARE * GRAZE_SHARE * jr


@njit(cache=True)
def finish_episode(IMP, n, PP, PST, p, t, dd, vel_i, vel_j):
    """At the run's end: an ENDED episode written with its end, one still in contact as open at t."""
    if PST[p, S_ACT] == ENDED:
        return _close_ended(IMP, n, PP, PST, p)
    if PST[p, S_ACT] == IN_CONTACT:
        return close_episode(IMP, n, PP, PST, p, t, dd, 1.0, vel_i, vel_j)
    return n


def impact_rows(names, mass, imp, compliance, heads=None):
    """Impact table rows (SI; impact_rows.pair_rows: delta-V, EES from the energy split by the struck sides'
    compliance (nv, 6), impact_rows.struck_compliance, PDOF), one per vehicle per
    contact episode (kind "continuous"): t = episode start, dvx, dvy, d_yaw_rate = CG velocity / yaw-rate
    change over the episode, energy = work dissipated by the contact forces over the episode (whole pair), pdof
    from the impulse on the vehicle (heading at the episode start, from heads[v] = (t, heading) records),
    point_x/y = contact point at peak force, plane_angle = tangent of the contact plane at peak force; plus:
    peak_force [N] (normal), duration [s], impulse [N s] (magnitude of the contact impulse on the vehicle) and
    its global components impulse_x, impulse_y, impulse_z, max_penetration [m] (the pair's largest total crush),
    crush [m] (the vehicle's share of it, pair_rows), approach_speed /
    separation_speed [m/s] (relative normal velocity at the contact point at onset and at separation;
    restitution = separation/approach; None for a push, no impact, and where the ratio is no restitution: an
    approach below APPROACH_MIN (a car's corner grazing a post along a normal that then turned, cars parked
    touching), no separation (an impact still closing where its push took over) or the contact still open), open
    (contact still active when the run ended). A push's record (I_PUSH) gives rows of kind "push"
    (crashlab.outcome.PUSH)."""
    nv = len(names)
    rows = []
    for r in imp:
        i, j = int(r[I_I]), int(r[I_J])
        J = r[I_JX:I_JX + 3]
        dd0, dd1 = r[I_DD0], r[I_DD1]
        heading = [float(np.interp(r[I_T0], heads[q][0], heads[q][1])) if heads is not None and q < nv else 0.0
                   for q in (i, j)]
        pair = pair_rows(names, mass, i, j, r[I_T0], r[I_ENERGY], (r[I_DVI:I_DVI + 3], r[I_DVJ:I_DVJ + 3]),
                         ((J[0], J[1]), (-J[0], -J[1])), heading, (r[I_PX], r[I_PY]), r[I_TH] + math.pi / 2,
                         PUSH if r[I_PUSH] == PUSHING else "continuous", (r[I_SIDE_I], r[I_SIDE_J]), compliance,
                         crush=r[I_MAXPEN], peak_force=r[I_PEAK],
                         duration=r[I_T1] - r[I_T0], impulse=math.sqrt(J[0] * J[0] + J[1] * J[1] + J[2] * J[2]))
        for row, sgn in zip(pair, (1.0, -1.0)):
            row.update(impulse_x=sgn * J[0], impulse_y=sgn * J[1], impulse_z=sgn * J[2],
                       max_penetration=r[I_MAXPEN], approach_speed=dd0, separation_speed=-dd1,
                       restitution=(-dd1 / dd0) if r[I_PUSH] != PUSHING and dd0 >= APPROACH_MIN and dd1 <= 0
                       and not r[I_OPEN] else None,
                       open=bool(r[I_OPEN]))
        rows += pair
    return rows


def contact_intervals(t0, t1, t_rec, road):
    """Merged (t_start, t_end) [s] of every contact: the chassis-chassis / chassis-barrier episodes (t0, t1)
    and the chassis-road contact (road[k, v] = 1: vehicle v touched the road between records k-1 and k)."""
    iv = [(float(a), float(b)) for a, b in zip(t0, t1)]
    for v in range(road.shape[1]):
        for k in range(road.shape[0]):
            if road[k, v] > 0:
                iv.append((float(t_rec[k - 1, v]) if k > 0 else 0.0, float(t_rec[k, v])))
    return merged_intervals(iv)


def merged_intervals(iv):
    """The union of intervals (t_start, t_end) [s], sorted; intervals that touch are one."""
    out = []
    for a, b in sorted(iv):
        if out and a <= out[-1][1]:
            out[-1] = (out[-1][0], max(out[-1][1], b))
        else:
            out.append((a, b))
    return out
