"""The compiled time loop of the impulse model: vehicle motion, contact onset, impulses, rest.

Everything per scene runs inside one numba function (no Python loop over time steps); a batch of
scenes runs in parallel with `prange`. Step-size policy:
  * fine steps (Heun, 2nd order) of at most `dt`, and below 1 / (fastest decay rate of the regularised
    tyre forces) (planar_vehicle.stiffest_rate), whenever a tyre force can change or vehicles are close;
  * while every moving vehicle runs straight and no pair can touch within the step, the step grows up
    to `coarse_dt` (straight running has constant forces, Heun is exact for it);
  * a vehicle at rest sleeps (no force evaluation) until an impulse wakes it; the loops of a step run
    over the awake vehicles and the pairs with an awake member only (lists rebuilt when a vehicle sleeps or
    wakes, pairs in the order of the full i < k loop, so results do not depend on the skipping), and the
    bounding circles reject distant pairs before the outline test; a pair of an awake vehicle and a static
    partner (sleeping vehicle, barrier) more than 2 REACH apart is left out until a vehicle has moved REACH
    (_near_pairs): a parked or distant vehicle costs (nearly) nothing;
  * the run ends when every vehicle sleeps (stop_at_rest) or at `duration`.
Contact onset is located by bisection of the step until the outlines overlap by at most `onset_tol`.

Contact episodes (the model docstring argues the choice): a pair's touch after being apart by more than
SEPARATION is an impact (restitution e, a row of the impact table); until the pair is that far apart
again, every step in which the outlines overlap and approach gets plastic (e = 0) Coulomb-limited
contact impulses, booked into that impact's row, and a position projection keeps the overlap below
CONTACT_SLOP. Reaching max_impacts or MAX_STEPS stops and fails the run.

The time loop and its step policy live here, as named stages (simulate_one calls them in order; docs/physics.md
§5); the pieces they use, one module per reason to change:
contact.py (outlines, contact geometry, the engagement point, the position projection), impacts.py (the impulse
at a point and the impact record), motion.py (the Heun step and the wheels' road friction), pairs.py (which
vehicles and pairs a step visits), layout.py (the arrays' layouts).
"""
import math
from collections import namedtuple

import numpy as np
from numba import njit, prange

from crashlab.geometry import clip_convex, contact_zone_centroid, overlap_centroid, penetration
from crashlab.models.common.driver_inputs import (
    PATCH,
    ahead,
    driver_inputs,
    effective_mode,
    next_change,
    ramping,
    steady_next,
)
from crashlab.models.common.planar_vehicle import P_A, P_B, P_TRACK, stiffest_rate
from crashlab.models.common.wheel_states import BRAKED, ROLLING
from crashlab.units import G

from .contact import _centre, _circles_apart, _engagement, _outline, _point_velocity, _project_apart, _radius
from .impacts import _apply_impulse, _kinetic, _merge_impact, _record_impact, _struck
from .layout import (
    D_BISECT,
    D_COARSE,
    D_CONTACT_T,
    D_E_IMPACT,
    D_FOLLOW,
    D_IMPACTS,
    D_KE0,
    D_MAX_DEPTH,
    D_NARROW,
    D_NREC,
    D_PROJECTED,
    D_STATUS,
    D_STEPS,
    D_T_END,
    D_VEHICLE_STEPS,
    I_ENGAGE,
    I_ENGAGE_RATIO,
    I_T,
    IN_BRAKE,
    IN_COS_HEADING,
    IN_COS_STEER,
    IN_MODE,
    IN_SIN_HEADING,
    IN_SIN_STEER,
    IN_STEER,
    N_IN,
    SETTINGS,
    STATUS_IMPACT_CAP,
    STATUS_NAN,
    STATUS_NOT_APPROACHING,
    STATUS_OK,
    STATUS_STEP_LIMIT,
)
from .motion import _heun, _near_zone
from .pairs import _awake_sets, _moved, _near_pairs

MAX_STEPS = 200_000  # a guard: no scene needs more (duration <= 120 s at dt >= 1 ms)
V_EPS = 1e-6  # m/s: an overlapping pair approaching slower needs no contact impulse (round-off level)
CONTACT_SLOP = 0.002  # m: overlap tolerated in sustained contact (no bisection, no projection below it)
SEPARATION = 0.05  # m: a pair further apart than this has ended its contact episode
DEEPEN = 2.0 * CONTACT_SLOP  # m: a touching pair's overlap deepening past this within a step is bisected
MAX_SWEEPS = 50  # sequential-impulse sweeps over simultaneous contacts per step
STOP_MARGIN = 0.5  # m/s: coarse steps end this far above the speed a coarse step could brake away
REACH = 1.0  # m: a pair with a static member further apart than 2 REACH is left out until a vehicle moved REACH

Settings = namedtuple("Settings", SETTINGS.names)  # the run's settings (layout.SETTINGS) as the stages read them
# the run's working state, grouped (arrays only: the stages change their contents)
# Motion: the Heun step's scratch (_heun) and the wheels' cached road frictions
Motion = namedtuple("Motion", "Snew k1 k2 tmp acc wheel_reach zcache")
# Drivers: each vehicle's driver inputs at the step's start (inp, layout.IN_*), the law read last (driver_inputs,
# next_change, ramping), until when it holds (steady_next) and the step bound of its wheel state (stiffest_rate)
Drivers = namedtuple("Drivers", "inp held mode brake change ramp rate_mode rate_h")
# Pairs: which pairs touch (in_contact), the impact row of a pair's open contact episode (episode, -1: none), the
# overlap the projection leaves (allowed: a collision position's start overlap), the awake vehicles and the pairs
# with an awake member (_awake_sets), the listed pairs that can touch soon (_near_pairs, from ref), the overlap
# test of each listed pair at the step's end (pen: depth, normal) and the outlines of the pair under test (oa, ob)
Pairs = namedtuple("Pairs", "in_contact episode allowed radius awake pair_i pair_k near_i near_k ref pen oa ob")
# Contacts: the overlapping pairs of a step (i, k), their depth, normal, overlap centroid and polygon (vertices, count),
# the states before the impulse being applied (before) and an empty impact row (no_row: a contact impulse's)
Contacts = namedtuple("Contacts", "i k depth normal point poly n_poly before no_row")

# The stages are inlined into simulate_one by numba (inline="always"), so that the compiled loop is one function as
# before they were named: as separate functions, (1) LLVM inlined the then small simulate_one into simulate_many's
# parallel loop and its loop strength reduction recursed past the stack (segfault while compiling, numba 0.68 /
# llvmlite 0.50), (2) each call passing the working state's arrays made simulate_batch 2x slower (measured).


# ---------------------------------------------------------------- the run's start
@njit(cache=True, inline="always")
def _settings(cfg):
    """The run's settings (a layout.SETTINGS record) as a Settings tuple (read once; numba keeps its scalars in
    registers)."""
    return Settings(cfg.road_friction, cfg.restitution, cfg.impact_friction, cfg.law, cfg.duration, cfg.stop_at_rest,
                    cfg.given, cfg.given_x, cfg.given_y, cfg.given_plane, cfg.given_i, cfg.given_j, cfg.dt,
                    cfg.coarse_dt, cfg.record_dt, cfg.onset_tol, cfg.v_rest, cfg.max_impacts, cfg.crush_time,
                    cfg.broad_phase, cfg.sleeping, cfg.engagement, cfg.engagement_depth)


@njit(cache=True, inline="always")
def _working_state(P, S, B):
    """The run's working arrays (Motion, Drivers, Pairs, Contacts) for nv vehicles and nb barriers: no contact, no
    driver input read yet (steer 0), no wheel friction cached."""
    nv, nb = P.shape[0], B.shape[0]
    nk = nv + nb
    m = Motion(np.empty_like(S), np.empty_like(S), np.empty_like(S), np.empty_like(S), np.zeros((nv, 2)),
               np.empty(nv), np.zeros((nv, 12)))
    m.zcache[:, 3:8] = -1.0  # (_wheel_frictions: nothing cached)
    for i in range(nv):  # the CG-centred circle holding every wheel (_wheel_frictions)
        m.wheel_reach[i] = math.sqrt(max(P[i, P_A], P[i, P_B]) ** 2 + (0.5 * P[i, P_TRACK]) ** 2)
    inp = np.zeros((nv, N_IN))
    inp[:, IN_COS_STEER] = 1.0
    dr = Drivers(inp, np.full(nv, -math.inf), np.zeros(nv, np.int64), np.zeros(nv), np.zeros(nv),
                 np.zeros(nv, np.bool_), np.full(nv, -1, np.int64), np.full(nv, math.inf))
    radius = np.empty(nk)
    for k in range(nk):
        radius[k] = _radius(P, B, k, nv)
    pr = Pairs(np.zeros((nv, nk), np.bool_), np.full((nv, nk), -1, np.int64), np.zeros((nv, nk)), radius,
               np.empty(nv, np.int64), np.empty(nv * nk, np.int64), np.empty(nv * nk, np.int64),
               np.empty(nv * nk, np.int64), np.empty(nv * nk, np.int64), np.zeros((nv, 2)), np.empty((nv * nk, 3)),
               np.empty((4, 2)), np.empty((4, 2)))
    n = nv * nk
    cl = Contacts(np.empty(n, np.int64), np.empty(n, np.int64), np.empty(n), np.empty((n, 2)), np.empty((n, 2)),
                  np.empty((n, 8, 2)), np.zeros(n, np.int64), np.empty_like(S), np.empty(0))
    return m, dr, pr, cl


@njit(cache=True, inline="always")
def _start_contacts(P, S, B, broad, pr):
    """Outlines that overlap at the start are in contact (a collision position): the projection leaves their
    start overlap (docs/physics.md §5)."""
    in_contact, radius, oa, ob, allowed = pr.in_contact, pr.radius, pr.oa, pr.ob, pr.allowed
    nv, nk = in_contact.shape
    for i in range(nv):
        for k in range(i + 1, nk):
            if broad and _circles_apart(S, B, radius, i, k, nv):
                continue
            d0 = penetration(_outline(P, S, B, i, nv, oa), _outline(P, S, B, k, nv, ob))[0]
            if d0 > 0.0:
                in_contact[i, k] = True
                allowed[i, k] = d0


@njit(cache=True, inline="always")
def _max_road_friction(mu, zones):
    """The largest road friction anywhere (friction zones): it bounds the step and the stopping speed."""
    mu_max = mu
    for z in range(zones[2].shape[0]):
        mu_max = max(mu_max, zones[2][z])
    return mu_max


@njit(cache=True, inline="always")
def _come_to_rest(S, i, v_rest, sleeping, asleep):
    """Vehicle i, if slower than v_rest (speed, yaw rate), stops; with `sleeping` it sleeps until an impulse wakes
    it (kernel docstring). Returns whether it stopped."""
    if math.hypot(S[i, 3], S[i, 4]) < v_rest and abs(S[i, 5]) < v_rest:
        S[i, 3:6] = 0.0
        asleep[i] = sleeping
        return True
    return False


@njit(cache=True, inline="always")
def _record_contact_state(S, contact):
    """The vehicles' poses and speeds at the first impact: x, y, heading, speed."""
    for q in range(contact.shape[0]):
        contact[q, 0], contact[q, 1], contact[q, 2] = S[q, 0], S[q, 1], S[q, 2]
        contact[q, 3] = math.hypot(S[q, 3], S[q, 4])


@njit(cache=True, inline="always")
def _given_impact(P, S, B, cfg, contact, imp, diag, hit, asleep, pr, cl):
    """The impact at t = 0 at the given point of impact and contact plane (PC-Crash style, docs/physics.md §4),
    the normal from vehicle given_i toward its partner's centre. It keeps its own row (the collision position's
    impulse as given); contact after it, where the pair's overlap deepens, opens an episode of its own.
    Returns (impacts recorded, status)."""
    S_before, in_contact = cl.before, pr.in_contact
    nv = P.shape[0]
    i0, j = cfg.given_i, cfg.given_j
    px, py, th = cfg.given_x, cfg.given_y, cfg.given_plane
    nx, ny = math.sin(th), -math.cos(th)
    cjx, cjy = _centre(S, B, j, nv)
    if nx * (cjx - S[i0, 0]) + ny * (cjy - S[i0, 1]) < 0.0:
        nx, ny = -nx, -ny
    _record_contact_state(S, contact)
    diag[D_CONTACT_T] = 0.0
    S_before[:] = S
    pn, pt, kind, energy, gn = _apply_impulse(P, S, i0, j, nv, px, py, nx, ny, cfg.restitution, cfg.impact_friction,
                                              cfg.law, imp[0])
    if kind < 0:
        return 0, STATUS_NOT_APPROACHING
    _record_impact(imp, 0, 0.0, i0, j, nv, S_before, S, pn, pt, kind, energy, px, py, nx, ny)
    diag[D_E_IMPACT] += energy
    _struck(i0, j, nv, hit, asleep)
    in_contact[i0, j] = True
    return 1, STATUS_OK


# ---------------------------------------------------------------- free motion: the step
@njit(cache=True, inline="always")
def _read_inputs(A, NA, t, i, dr):
    """Vehicle i's driver inputs' law at t (common/driver_inputs): wheel state, brake, steer, its next change,
    whether it ramps, and until when it holds."""
    law_mode, law_brake, law_change, law_ramp, held, inp = dr.mode, dr.brake, dr.change, dr.ramp, dr.held, dr.inp
    law_mode[i], law_brake[i], steer = driver_inputs(A[i], NA[i], t)
    law_change[i] = next_change(A[i], NA[i], t)
    law_ramp[i] = ramping(A[i], NA[i], t)
    held[i] = steady_next(A[i], NA[i], t)
    if steer != inp[i, IN_STEER]:
        inp[i, IN_STEER] = steer
        inp[i, IN_COS_STEER], inp[i, IN_SIN_STEER] = ((math.cos(steer), math.sin(steer)) if steer != 0.0
                                                            else (1.0, 0.0))


@njit(cache=True, inline="always")
def _fine_step(P, S, A, NA, t, dt, coarse_dt, hit, zones, mu_max, na, pr, dr):
    """The fine step (kernel docstring): at most dt and 1 / the stiffest tyre-force decay rate of each awake
    vehicle's wheel state (planar_vehicle.stiffest_rate), and sets each awake vehicle's inputs for the step
    (dr.inp). Returns (h, the next change of a driver input's law, quiet: every moving vehicle runs straight
    with constant inputs, away from friction zones, too fast to stop within a coarse step)."""
    inp, awake, held, law_change = dr.inp, pr.awake, dr.held, dr.change
    law_ramp, law_mode, law_brake, rate_mode = dr.ramp, dr.mode, dr.brake, dr.rate_mode
    rate_h, radius = dr.rate_h, pr.radius
    h = dt
    t_change = math.inf
    quiet = True
    zoned = zones[2].shape[0] > 0
    for a in range(na):
        i = awake[a]
        if not ahead(t, held[i]):  # the inputs' law changed (or changes continuously): read it again
            _read_inputs(A, NA, t, i, dr)
        t_change = min(t_change, law_change[i])
        if law_ramp[i]:
            quiet = False
        mode, brake, steer = effective_mode(law_mode[i], hit[i]), law_brake[i], inp[i, IN_STEER]
        inp[i, IN_MODE], inp[i, IN_BRAKE] = mode, brake
        if mode == ROLLING and brake > 0.0:
            mode = BRAKED  # a braking rolling wheel is as stiff as a braked one
        if mode != rate_mode[i]:  # (the bound changes with the wheel state only: mu_max is fixed)
            rate = stiffest_rate(P[i], mu_max, mode)  # 0 for locked wheels on ice: no tyre force
            rate_mode[i], rate_h[i] = mode, 1.0 / rate if rate > 0.0 else math.inf
        h = min(h, rate_h[i])
        c, sn = math.cos(S[i, 2]), math.sin(S[i, 2])
        inp[i, IN_COS_HEADING], inp[i, IN_SIN_HEADING] = c, sn
        lat = -sn * S[i, 3] + c * S[i, 4]
        speed = math.hypot(S[i, 3], S[i, 4])
        if abs(S[i, 5]) > 1e-9 or abs(lat) > 1e-9 or steer != 0.0:
            quiet = False
        elif zoned and _near_zone(S, i, radius[i] + speed * coarse_dt + PATCH, zones[3]):
            quiet = False
        # a vehicle that can come to a stop within a coarse step (deceleration <= mu g) is near
        # the discontinuity of Coulomb friction: a coarse Heun step there oscillates about v = 0
        if speed < 2.0 * mu_max * G * coarse_dt + STOP_MARGIN:
            quiet = False
    return h, t_change, quiet


@njit(cache=True, inline="always")
def _coarse_step(S, B, coarse_dt, n_pairs, pr):
    """Straight running (constant forces, Heun exact): the coarse step, shortened so that no listed pair can
    close more than half its bounding circles' gap (a sleeping vehicle and a barrier: not listed, closing 0)."""
    pair_i, pair_k, radius = pr.pair_i, pr.pair_k, pr.radius
    nv = S.shape[0]
    h_gap = coarse_dt
    for p in range(n_pairs):
        i, k = pair_i[p], pair_k[p]
        ckx, cky = _centre(S, B, k, nv)
        gap = math.hypot(S[i, 0] - ckx, S[i, 1] - cky) - radius[i] - radius[k]
        closing = math.hypot(S[i, 3], S[i, 4])
        if k < nv:
            closing += math.hypot(S[k, 3], S[k, 4])
        if closing > 0.0:
            h_gap = min(h_gap, 0.5 * gap / closing)
    return h_gap


@njit(cache=True, inline="always")
def _step_size(P, S, B, A, NA, t, cfg, hit, zones, mu_max, na, n_pairs, pr, dr, diag):
    """The step from t (kernel docstring): fine, or coarse while every moving vehicle runs straight and
    nothing can touch; it ends where a driver's input changes its law and at the run's duration."""
    h, t_change, quiet = _fine_step(P, S, A, NA, t, cfg.dt, cfg.coarse_dt, hit, zones, mu_max, na, pr, dr)
    if quiet and cfg.coarse_dt > cfg.dt:
        h_gap = _coarse_step(S, B, cfg.coarse_dt, n_pairs, pr)
        if h_gap > h:
            h = h_gap
            diag[D_COARSE] += 1
    return min(h, cfg.duration - t, t_change - t)


@njit(cache=True, inline="always")
def _step(P, S, t, h, A, NA, hit, zones, mu, na, pr, m, dr):
    """The awake vehicles' Heun step from S at t over h into m.Snew (motion._heun, docs/physics.md §1-§2)."""
    Snew, wheel_reach, zcache, awake = m.Snew, m.wheel_reach, m.zcache, pr.awake
    acc, k1, k2, tmp = m.acc, m.k1, m.k2, m.tmp
    inp, held = dr.inp, dr.held
    _heun(P, S, t, A, NA, hit, zones, wheel_reach, zcache, awake, na, mu, acc, h, Snew, k1, k2, tmp,
          inp, held)


@njit(cache=True, inline="always")
def _accept_step(S, Snew, awake, na):
    """The awake vehicles' states at the step's end become the current ones."""
    for a in range(na):
        i = awake[a]
        for q in range(6):
            S[i, q] = Snew[i, q]


# ---------------------------------------------------------------- onset of contact
@njit(cache=True, inline="always")
def _listed_pairs(S, Snew, B, broad, asleep, na, n_pairs, n_near, near_stale, pr):
    """The pairs tested this step: with the broad phase, pairs with a static partner far away are left out
    (_near_pairs, rebuilt once an awake vehicle has moved REACH); a step longer than REACH tests every listed
    pair. Returns (pair_i, pair_k, count, n_near, near_stale)."""
    pair_i, pair_k, awake, ref = pr.pair_i, pr.pair_k, pr.awake, pr.ref
    radius, near_i, near_k, in_contact = pr.radius, pr.near_i, pr.near_k, pr.in_contact
    episode, allowed = pr.episode, pr.allowed
    nv, nb = S.shape[0], B.shape[0]
    li, lk, nl = pair_i, pair_k, n_pairs
    if broad and (na < nv or nb > 0):
        if near_stale or _moved(S, Snew, awake, na, ref, REACH):
            near_stale = _moved(S, Snew, awake, na, S[:, 0:2], REACH)  # the step itself longer
            if not near_stale:
                n_near = _near_pairs(S, B, radius, asleep, awake, na, pair_i, pair_k, n_pairs, ref,
                                     REACH, near_i, near_k, in_contact, episode, allowed)
        if not near_stale:
            li, lk, nl = near_i, near_k, n_near
    return li, lk, nl, n_near, near_stale


@njit(cache=True, inline="always")
def _bisect_step(P, S, B, A, NA, t, h, i, k, lo_d, hi_d, hit, zones, mu, na, pr, m, dr, diag):
    """The step length (bisection of h, at most 60 halvings) at whose end pair i, k overlaps by more than lo_d
    and at most hi_d; m.Snew holds the state there."""
    Snew, oa, ob = m.Snew, pr.oa, pr.ob
    nv = S.shape[0]
    lo, hi = 0.0, h
    for _ in range(60):
        hm = 0.5 * (lo + hi)
        _step(P, S, t, hm, A, NA, hit, zones, mu, na, pr, m, dr)
        diag[D_BISECT] += 1
        depth = penetration(_outline(P, Snew, B, i, nv, oa), _outline(P, Snew, B, k, nv, ob))[0]
        if depth > hi_d:
            hi = hm
        elif depth <= lo_d:
            lo = hm
        else:
            break
    return hm


@njit(cache=True, inline="always")
def _locate_onset(P, S, B, A, NA, t, h, cfg, hit, zones, li, lk, nl, na, pr, m, dr, diag):
    """Onset of a new contact (kernel docstring): the step is bisected until the overlap is at most onset_tol;
    a touching pair whose overlap deepens past DEEPEN within the step (another part of it approaching, e.g. a
    rotating car's far corner) is bisected likewise, to an overlap between CONTACT_SLOP and DEEPEN. Keeps each
    listed pair's overlap test of the step's end (pr.pen). Returns (h, whether the step was bisected)."""
    pen, Snew, radius, oa = pr.pen, m.Snew, pr.radius, pr.oa
    ob, in_contact, allowed, episode = pr.ob, pr.in_contact, pr.allowed, pr.episode
    nv = S.shape[0]
    bisected = False
    for p in range(nl):
        i, k = li[p], lk[p]
        if cfg.broad_phase and _circles_apart(Snew, B, radius, i, k, nv):
            continue
        diag[D_NARROW] += 1
        depth, nx, ny, _ = penetration(_outline(P, Snew, B, i, nv, oa), _outline(P, Snew, B, k, nv, ob))
        pen[p, 0], pen[p, 1], pen[p, 2] = depth, nx, ny
        if in_contact[i, k]:
            if allowed[i, k] > 0.0 or depth <= DEEPEN:
                continue
            lo_d, hi_d = CONTACT_SLOP, DEEPEN
        else:
            if depth <= cfg.onset_tol or (episode[i, k] >= 0 and depth <= CONTACT_SLOP):
                continue
            lo_d, hi_d = 0.0, cfg.onset_tol
        bisected = True
        h = _bisect_step(P, S, B, A, NA, t, h, i, k, lo_d, hi_d, hit, zones, cfg.road_friction, na, pr, m, dr, diag)
    return h, bisected


# ---------------------------------------------------------------- contacts: impacts and contact episodes
@njit(cache=True, inline="always")
def _collect_contacts(P, S, B, broad, bisected, li, lk, nl, pr, cl, diag):
    """The step's contacts (cl: pair, depth, normal, overlap centroid and polygon): the listed pairs that
    overlap at the step's end beyond a collision position's start overlap. Updates which pairs touch, and ends
    the contact episode of a pair further apart than SEPARATION (docs/physics.md §5). Returns their count."""
    radius, in_contact, episode, allowed = pr.radius, pr.in_contact, pr.episode, pr.allowed
    oa, ob, pen, cl_m = pr.oa, pr.ob, pr.pen, cl.n_poly
    cl_v, cl_i, cl_k, cl_d = cl.poly, cl.i, cl.k, cl.depth
    cl_n, cl_p = cl.normal, cl.point
    nv = S.shape[0]
    nc = 0
    for p in range(nl):
        i, k = li[p], lk[p]
        if broad and _circles_apart(S, B, radius, i, k, nv):
            in_contact[i, k] = False
            episode[i, k] = -1
            allowed[i, k] = 0.0
            continue
        if bisected:  # the step's end moved since the onset test
            diag[D_NARROW] += 1
            depth, nx, ny, _ = penetration(_outline(P, S, B, i, nv, oa), _outline(P, S, B, k, nv, ob))
        else:
            depth, nx, ny = pen[p, 0], pen[p, 1], pen[p, 2]
        if depth <= 0.0:
            in_contact[i, k] = False
            allowed[i, k] = 0.0
            if -depth > SEPARATION:
                episode[i, k] = -1
            continue
        in_contact[i, k] = True
        if depth <= allowed[i, k] + CONTACT_SLOP and allowed[i, k] > 0.0:
            # a collision position's start overlap, not deepening: the given impulse resolved it
            allowed[i, k] = min(allowed[i, k], depth)
            continue
        diag[D_MAX_DEPTH] = max(diag[D_MAX_DEPTH], depth)
        ci, ck = _outline(P, S, B, i, nv, oa), _outline(P, S, B, k, nv, ob)
        px, py, area = overlap_centroid(ci, ck)
        if math.isnan(px):
            continue
        poly, npoly = clip_convex(ci, ck)
        cl_m[nc] = min(npoly, cl_v.shape[1])
        cl_v[nc, :cl_m[nc]] = poly[:cl_m[nc]]
        cl_i[nc], cl_k[nc], cl_d[nc] = i, k, depth
        cl_n[nc, 0], cl_n[nc, 1], cl_p[nc, 0], cl_p[nc, 1] = nx, ny, px, py
        nc += 1
    return nc


@njit(cache=True, inline="always")
def _approach(S, i, k, px, py, nx, ny, poly, n_poly, sustained):
    """The normal approach speed of i and k at (px, py), and in sustained contact the overlap's vertex that
    approaches fastest (rigid bodies: the normal velocity is linear over the overlap, so its extremes are at
    vertices, docs/physics.md §5). Returns (approach, px, py)."""
    nv = S.shape[0]
    v1x, v1y = _point_velocity(S, i, nv, px, py)
    v2x, v2y = _point_velocity(S, k, nv, px, py)
    approach = -((v2x - v1x) * nx + (v2y - v1y) * ny)
    if sustained:
        for q in range(n_poly):
            qx, qy = poly[q, 0], poly[q, 1]
            v1x, v1y = _point_velocity(S, i, nv, qx, qy)
            v2x, v2y = _point_velocity(S, k, nv, qx, qy)
            aq = -((v2x - v1x) * nx + (v2y - v1y) * ny)
            if aq > approach:
                approach, px, py = aq, qx, qy
    return approach, px, py


@njit(cache=True, inline="always")
def _impact_point(P, S, B, cfg, i, k, px, py, nx, ny, approach, pr):
    """An impact's point (docs/physics.md §4): the middle of the contact zone the approach will crush within
    crush_time, or (point = "engagement") the overlap's centroid at engagement with its contact plane; the
    overlap's centroid where neither exists. Returns (px, py, nx, ny, engagement flag, engagement ratio)."""
    oa, ob = pr.oa, pr.ob
    nv = S.shape[0]
    zx, zy, e_flag, e_ratio = math.nan, math.nan, 0, math.nan
    if cfg.engagement:
        zx, zy, nx, ny, e_flag, e_ratio = _engagement(P, S, B, i, k, nv, cfg.engagement_depth, nx, ny, oa, ob)
    if math.isnan(zx):
        zx, zy, _ = contact_zone_centroid(_outline(P, S, B, i, nv, oa), _outline(P, S, B, k, nv, ob), nx, ny,
                                          cfg.crush_time * approach)
    if not math.isnan(zx):
        px, py = zx, zy
    return px, py, nx, ny, e_flag, e_ratio


@njit(cache=True, inline="always")
def _contact_impulses(P, S, B, cfg, t, n_imp, max_imp, nc, contact, imp, hit, asleep, pr, cl, diag):
    """The step's impulses (docs/physics.md §3-§5): an impact (the first touch of an episode) gets its own row;
    a pair in an open episode that overlaps and approaches gets a plastic contact impulse booked into the
    episode's row. Several contacts at once (a car squeezed between a car and a wall) are resolved together by
    sweeps of sequential impulses (projected Gauss-Seidel): after the first sweep a pair is approaching again
    only through its neighbours' impulses of this instant, so its further impulses are plastic and booked into
    its row. Returns (impacts recorded, whether the impact cap stopped the run, whether a sleeper woke)."""
    cl_i, cl_k, cl_n, episode = cl.i, cl.k, cl.normal, pr.episode
    cl_p, cl_v, cl_m, S_before = cl.point, cl.poly, cl.n_poly, cl.before
    no_row = cl.no_row
    nv = S.shape[0]
    woke = False
    for _ in range(MAX_SWEEPS if nc > 1 else 1):
        active = False
        for c in range(nc):
            i, k = cl_i[c], cl_k[c]
            nx, ny = cl_n[c, 0], cl_n[c, 1]
            row = episode[i, k]
            sustained = row >= 0 and imp[row, I_T] != t
            approach, px, py = _approach(S, i, k, cl_p[c, 0], cl_p[c, 1], nx, ny, cl_v[c], cl_m[c],
                                         sustained)
            if approach <= V_EPS:
                continue
            is_impact = row < 0
            e_flag, e_ratio = 0, math.nan
            if is_impact:
                if n_imp >= max_imp:
                    return n_imp, True, woke
                px, py, nx, ny, e_flag, e_ratio = _impact_point(P, S, B, cfg, i, k, px, py, nx, ny, approach, pr)
            e_k = cfg.restitution if is_impact else 0.0  # follow-ups are plastic (no bounce chatter)
            S_before[:] = S
            alt = imp[n_imp] if is_impact else no_row  # (the impact's row: its slip-reversal check)
            pn, pt, kind, energy, gn = _apply_impulse(P, S, i, k, nv, px, py, nx, ny, e_k, cfg.impact_friction,
                                                      cfg.law, alt)
            if kind < 0:
                continue
            active = True
            if is_impact:
                if n_imp == 0:
                    diag[D_CONTACT_T] = t
                    _record_contact_state(S_before, contact)
                _record_impact(imp, n_imp, t, i, k, nv, S_before, S, pn, pt, kind, energy, px, py, nx, ny)
                imp[n_imp, I_ENGAGE], imp[n_imp, I_ENGAGE_RATIO] = e_flag, e_ratio
                episode[i, k] = n_imp
                n_imp += 1
            else:
                _merge_impact(imp, row, t, i, k, nv, S_before, S, pn, pt, energy, nx, ny)
                diag[D_FOLLOW] += 1
            diag[D_E_IMPACT] += energy
            woke = woke or asleep[i] or (k < nv and asleep[k])
            _struck(i, k, nv, hit, asleep)
        if not active:
            break
    return n_imp, False, woke


@njit(cache=True, inline="always")
def _project_contacts(P, S, Snew, nc, asleep, near_stale, pr, cl, diag):
    """Non-penetration at the position level (docs/physics.md §5): the velocity-level contact impulse stops the
    approach at the end of a step but not the overlap gained within it (~ a h^2 / 2); each contact's overlap is
    projected down to CONTACT_SLOP (or a collision position's start overlap). Returns near_stale (a static
    partner moved)."""
    cl_i, cl_k, cl_d, allowed, cl_n = cl.i, cl.k, cl.depth, pr.allowed, cl.normal
    nv = S.shape[0]
    for c in range(nc):
        i, k, depth = cl_i[c], cl_k[c], cl_d[c]
        target = max(allowed[i, k], CONTACT_SLOP)
        if depth > target:
            _project_apart(P, S, i, k, nv, cl_n[c, 0], cl_n[c, 1], depth - target)
            diag[D_PROJECTED] += depth - target
            Snew[i] = S[i]  # (a sleeping vehicle's row of Snew equals its row of S)
            if k < nv:
                Snew[k] = S[k]
                near_stale = near_stale or asleep[k]
            near_stale = near_stale or asleep[i]
        allowed[i, k] = min(allowed[i, k], depth)
    return near_stale


# ---------------------------------------------------------------- rest and recording
@njit(cache=True, inline="always")
def _rest(S, Snew, v_rest, sleeping, asleep, na, pr):
    """A vehicle that has (almost) stopped goes to sleep (kernel docstring); an impulse wakes it. Returns
    (some vehicle fell asleep, every vehicle sleeps, a state is NaN). A sleeping vehicle's state is only moved
    by the projection, finite: NaN can arise in awake ones."""
    awake = pr.awake
    all_asleep, slept, nan = True, False, False
    for a in range(na):
        i = awake[a]
        if _come_to_rest(S, i, v_rest, sleeping, asleep) and sleeping:
            Snew[i] = S[i]
            slept = True
        if not asleep[i]:
            all_asleep = False
        if math.isnan(S[i, 0]) or math.isnan(S[i, 3]):
            nan = True
    return slept, all_asleep, nan


@njit(cache=True, inline="always")
def _record_state(traj, n_rec, t, S):
    """Trajectory sample n_rec: t and every vehicle's state. Returns the samples' count."""
    traj[n_rec, :, 0] = t
    traj[n_rec, :, 1:7] = S
    return n_rec + 1


# ---------------------------------------------------------------- the run
@njit(cache=True)
def simulate_one(P, S0, B, cfg, A, NA, zones, rest, final, contact, imp, traj, diag):
    """Simulate one scene. P (nv, N_PARAMS), S0 (nv, 6) start states, B (nb, 5) barriers
    (x, y, heading, half length, half width), cfg the run's settings (a layout.SETTINGS record), A, NA the
    driver's action tables, zones the friction zones (common/driver_inputs.pack_action_tables, pack_zones).
    Outputs are written into the arrays passed in. The stages in their order, each step: record, step size,
    free motion, contact onset, contacts (impacts and contact episodes), projection, rest."""
    cfg = _settings(cfg)
    nv, nk = P.shape[0], P.shape[0] + B.shape[0]
    duration, rec_dt, mu = cfg.duration, cfg.record_dt, cfg.road_friction
    max_imp = min(cfg.max_impacts, imp.shape[0])
    S = S0.copy()
    m, dr, pr, cl = _working_state(P, S, B)
    asleep = np.zeros(nv, np.bool_)
    hit = np.zeros(nv, np.bool_)
    _start_contacts(P, S, B, cfg.broad_phase, pr)
    mu_max = _max_road_friction(mu, zones)
    for i in range(nv):
        _come_to_rest(S, i, cfg.v_rest, cfg.sleeping, asleep)
    diag[:] = 0.0
    diag[D_CONTACT_T] = math.nan
    contact[:] = math.nan
    for i in range(nv):
        diag[D_KE0] += _kinetic(P, S, i, nv)
    n_imp, n_rec, t, next_rec, status = 0, 0, 0.0, 0.0, STATUS_OK
    if cfg.given and nk >= 2:
        n_imp, status = _given_impact(P, S, B, cfg, contact, imp, diag, hit, asleep, pr, cl)
    na, n_pairs = _awake_sets(asleep, nk, pr.awake, pr.pair_i, pr.pair_k)
    m.Snew[:] = S  # a sleeping vehicle's row of Snew stays equal to its row of S (_heun leaves it)
    steps, n_near, near_stale = 0, 0, True
    while t < duration - 1e-12:
        if rec_dt > 0.0 and t >= next_rec - 1e-12 and n_rec < traj.shape[0] - 1:
            n_rec = _record_state(traj, n_rec, t, S)
            next_rec += rec_dt
        h = _step_size(P, S, B, A, NA, t, cfg, hit, zones, mu_max, na, n_pairs, pr, dr, diag)
        _step(P, S, t, h, A, NA, hit, zones, mu, na, pr, m, dr)
        steps += 1
        diag[D_VEHICLE_STEPS] += na
        if steps > MAX_STEPS:
            status = STATUS_STEP_LIMIT
            break
        li, lk, nl, n_near, near_stale = _listed_pairs(S, m.Snew, B, cfg.broad_phase, asleep, na, n_pairs, n_near,
                                                       near_stale, pr)
        h, bisected = _locate_onset(P, S, B, A, NA, t, h, cfg, hit, zones, li, lk, nl, na, pr, m, dr, diag)
        t += h
        _accept_step(S, m.Snew, pr.awake, na)
        nc = _collect_contacts(P, S, B, cfg.broad_phase, bisected, li, lk, nl, pr, cl, diag)
        n_imp, capped, woke = _contact_impulses(P, S, B, cfg, t, n_imp, max_imp, nc, contact, imp, hit, asleep, pr,
                                                cl, diag)
        if capped:
            status = STATUS_IMPACT_CAP
            break
        if woke:
            na, n_pairs = _awake_sets(asleep, nk, pr.awake, pr.pair_i, pr.pair_k)
            near_stale = True
        near_stale = _project_contacts(P, S, m.Snew, nc, asleep, near_stale, pr, cl, diag)
        slept, all_asleep, nan = _rest(S, m.Snew, cfg.v_rest, cfg.sleeping, asleep, na, pr)
        if slept:
            na, n_pairs = _awake_sets(asleep, nk, pr.awake, pr.pair_i, pr.pair_k)
            near_stale = True
        if nan:
            status = STATUS_NAN
            break
        if all_asleep and cfg.stop_at_rest:
            break
    if rec_dt > 0.0 and n_rec < traj.shape[0]:
        n_rec = _record_state(traj, n_rec, t, S)
    rest[:, :] = S[:, 0:3]
    final[:, :] = S[:, 3:6]
    diag[D_STEPS], diag[D_IMPACTS], diag[D_NREC], diag[D_T_END] = steps, n_imp, n_rec, t
    diag[D_STATUS] = status


@njit(cache=True, parallel=True)
def simulate_many(P, S0, B, cfg, A, NA, ZC, ZS, ZMU, ZBOX, rest, final, contact, imp, diag):
    """A batch of scenes of the same composition (vehicles, barriers, action rows, zone corners), in
    parallel, without trajectories."""
    no_traj = np.empty((0, P.shape[1], 7))
    for s in prange(P.shape[0]):
        simulate_one(P[s], S0[s], B[s], cfg[s], A[s], NA[s], (ZC[s], ZS[s], ZMU[s], ZBOX[s]), rest[s], final[s],
                     contact[s], imp[s], no_traj, diag[s])
