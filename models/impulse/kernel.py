"""The compiled time loop of the impulse model: vehicle motion, contact onset, impulses, rest.

Everything per scene runs inside one numba function (no Python loop over time steps); a batch of
scenes runs in parallel with `prange`. Step-size policy:
  * fine steps (Heun, 2nd order) of at most `dt`, and below 1 / (fastest decay rate of the regularised
    tyre forces at the wheels' slip speeds) (planar_vehicle.rate_of_slips), whenever a tyre force can change
    or vehicles are close;
  * while every moving vehicle runs straight or slides on locked wheels, far from stopping, and no pair
    can touch within the step, the step grows up to `coarse_dt` (straight running has constant forces,
    Heun is exact for it; a locked wheel's force turns smoothly with its slip velocity: motion._long_step,
    _gap_step; docs/physics.md §2);
  * a vehicle at rest sleeps (no force evaluation) until an impulse wakes it; the loops of a step run
    over the awake vehicles and the pairs with an awake member only (lists rebuilt when a vehicle sleeps or
    wakes, pairs in the order of the full i < k loop, so results do not depend on the skipping), and the
    bounding circles reject distant pairs before the outline test; a pair of an awake vehicle and a static
    partner (sleeping vehicle, barrier) more than 2 REACH apart is left out until a vehicle has moved REACH
    (_near_pairs): a parked or distant vehicle costs (nearly) nothing;
  * the run ends when every vehicle sleeps (stop_at_rest) or at `duration`.
Contact onset is located by bisection of the step until the outlines overlap by at most `onset_tol`.

Contact episodes (episode.py; the model docstring argues the choice): a pair's touch after being apart by more than
SEPARATION is an impact (restitution e, a row of the impact table); until the pair is that far apart
again, every step in which the outlines overlap and approach gets plastic (e = 0) Coulomb-limited
contact impulses, booked into that impact's row, and a position projection keeps the overlap below
CONTACT_SLOP. Reaching max_impacts or MAX_STEPS stops and fails the run.

The time loop and its step policy live here: simulate_one is a loop over named stages (step size, free motion, the
pairs tested, onset, contacts, impulses, projection, rest, recording), each a function inlined at numba's IR level
(inline="always": the same compiled code as the loop in one piece, no call; numba's "Notes on Inlining"), compiled
by compiler.py (which drops the array copies inlining leaves, and with them their reference counts). A stage takes
at most 30 arguments: CPython compiles a call with more as a call with *args, which numba's inliner refuses. The
stages and what they call, one module per reason to change: episode.py (onset, the step's contacts, their impulses,
the projection), contact.py (outlines, contact geometry, the engagement point, the position projection), impacts.py
(the impulse at a point and the impact record), motion.py (the Heun step and the wheels' road friction), pairs.py
(which vehicles and pairs a step visits), layout.py (the arrays' layouts).
"""
import math

import numpy as np
from numba import njit, prange

from crashlab.geometry import penetration
from crashlab.models.common.driver_inputs import (
    PATCH,
    ahead,
    driver_inputs,
    effective_mode,
    next_change,
    ramping,
    steady_next,
)
from crashlab.models.common.planar_vehicle import P_A, P_B, P_TRACK, rate_of_slips, wheel_slips
from crashlab.models.common.wheel_states import LOCKED
from crashlab.units import G

from .compiler import StagesCompiler
from .contact import _circles_apart, _outline, _radius
from .episode import _bisect, _gather_contacts, _given_impact, _impulses, _onset_test, _project
from .impacts import _kinetic, _settle_reimpacts
from .layout import (
    D_COARSE,
    D_CONTACT_T,
    D_IMPACTS,
    D_KE0,
    D_NREC,
    D_STATUS,
    D_STEPS,
    D_T_END,
    D_VEHICLE_STEPS,
    IN_BRAKE,
    IN_COS_HEADING,
    IN_COS_STEER,
    IN_MODE,
    IN_SIN_HEADING,
    IN_SIN_STEER,
    IN_STEER,
    N_IN,
    STATUS_IMPACT_CAP,
    STATUS_NAN,
    STATUS_OK,
    STATUS_STEP_LIMIT,
)
from .motion import _gap_step, _heun, _long_step, _near_zone, _straight
from .pairs import _awake_sets, _moved, _near_pairs

MAX_STEPS = 200_000  # a guard: no scene needs more (duration <= 120 s at dt >= 1 ms)
REACH = 1.0  # m: a pair with a static member further apart than 2 REACH is left out until a vehicle moved REACH


@njit(inline="always")
def _start_contacts(P, S, B, radius, broad, in_contact, allowed, oa, ob):
    """Outlines that overlap at the start are in contact (a collision position): their overlap is allowed."""
    nv, nk = P.shape[0], radius.shape[0]
    for i in range(nv):
        for k in range(i + 1, nk):
            if broad and _circles_apart(S, B, radius, i, k, nv):
                continue
            d0 = penetration(_outline(P, S, B, i, nv, oa), _outline(P, S, B, k, nv, ob))[0]
            if d0 > 0.0:
                in_contact[i, k] = True
                allowed[i, k] = d0


@njit(inline="always")
def _fine_step(P, S, A, NA, t, awake, na, hit, held, law_mode, law_brake, law_change, law_ramp, inp, radius, zone_box,
               zoned, mu_max, dt, coarse_dt):
    """The step size of the tyre forces: at most dt and below each awake vehicle's stability limit 1 / (the fastest
    decay rate of its regularised tyre forces at its wheels' slip speeds) (planar_vehicle.rate_of_slips). Reads
    each vehicle's driver inputs where their law changed (held: until when they hold) into inp, with its heading's
    cosine and sine. Returns (h, the time the next law starts: a step ends there, the longest step every awake
    vehicle allows: motion._long_step, running straight or sliding on locked wheels, far from a friction zone and
    from stopping, with constant inputs; 0 where one does not)."""
    h = dt
    t_change = math.inf
    long_ok = coarse_dt > dt
    h_long = coarse_dt
    for a in range(na):
        i = awake[a]
        if not ahead(t, held[i]):  # the inputs' law changed (or changes continuously): read it again
            law_mode[i], law_brake[i], steer = driver_inputs(A[i], NA[i], t)
            law_change[i] = next_change(A[i], NA[i], t)
            law_ramp[i] = ramping(A[i], NA[i], t)
            held[i] = steady_next(A[i], NA[i], t)
            if steer != inp[i, IN_STEER]:
                inp[i, IN_STEER] = steer
                inp[i, IN_COS_STEER], inp[i, IN_SIN_STEER] = ((math.cos(steer), math.sin(steer)) if steer != 0.0
                                                              else (1.0, 0.0))
        t_change = min(t_change, law_change[i])
        mode, brake, steer = effective_mode(law_mode[i], hit[i]), law_brake[i], inp[i, IN_STEER]
        inp[i, IN_MODE], inp[i, IN_BRAKE] = mode, brake
        c, sn = math.cos(S[i, 2]), math.sin(S[i, 2])
        inp[i, IN_COS_HEADING], inp[i, IN_SIN_HEADING] = c, sn
        slips = wheel_slips(P[i], S[i], c, sn, inp[i, IN_COS_STEER], inp[i, IN_SIN_STEER], mu_max)
        if mode != LOCKED and not _straight(S[i], c, sn, steer):  # its load transfer lags a stage (first
            slips = (0.0, 0.0, slips[2], slips[3])  # order): the worst case's step (docs/physics.md §2)
        rate = rate_of_slips(P[i], mu_max, mode, brake, slips, dt)  # 0: locked on ice, no force
        if rate * h > 1.0:
            h = 1.0 / rate
        if long_ok:  # (not within a ramp, nor where a wheel's friction may change: near a zone)
            if law_ramp[i] or (zoned and _near_zone(S, i, radius[i] + math.hypot(S[i, 3], S[i, 4]) * coarse_dt
                                                    + PATCH, zone_box)):
                h_long = 0.0
            else:
                h_long = min(h_long, _long_step(P[i], S[i], c, sn, steer, mode, brake, mu_max, coarse_dt, slips))
            long_ok = h_long > h
    return h, t_change, h_long if long_ok else 0.0


@njit(inline="always")
def _coarse_step(P, S, B, radius, pair_i, pair_k, n_pairs, h, h_long, mu_max, oa, ob, diag):
    """A step grows up to h_long (_fine_step) while no listed pair can touch within it (motion._gap_step; a
    sleeping vehicle and a barrier are not listed, closing 0). Returns h."""
    nv = S.shape[0]
    for p in range(n_pairs):
        h_long = min(h_long, _gap_step(P, S, B, radius, pair_i[p], pair_k[p], nv, mu_max * G * h_long, oa, ob))
    if h_long > h:
        h = h_long
        diag[D_COARSE] += 1
    return h


@njit(inline="always")
def _near_list(S, Snew, B, radius, asleep, awake, na, pair_i, pair_k, n_pairs, ref, near_i, near_k, n_near,
               near_stale, in_contact, episode, allowed):
    """The broad phase's pairs tested this step: pairs with a static partner far away are left out (_near_pairs,
    rebuilt once an awake vehicle has moved REACH from ref); a step longer than REACH leaves the list stale (every
    listed pair is tested). Returns (n_near, near_stale)."""
    if near_stale or _moved(S, Snew, awake, na, ref, REACH):
        near_stale = _moved(S, Snew, awake, na, S[:, 0:2], REACH)  # the step itself longer
        if not near_stale:
            n_near = _near_pairs(S, B, radius, asleep, awake, na, pair_i, pair_k, n_pairs, ref, REACH, near_i,
                                 near_k, in_contact, episode, allowed)
    return n_near, near_stale


@njit(inline="always")
def _accept(S, Snew, awake, na):
    """The step's end becomes the awake vehicles' state."""
    for a in range(na):
        i = awake[a]
        for q in range(6):
            S[i, q] = Snew[i, q]


@njit(inline="always")
def _come_to_rest(S, Snew, asleep, awake, na, v_rest, sleeping):
    """A vehicle that has (almost) stopped goes to sleep (with sleeping: no force evaluation) until an impulse wakes
    it. Returns (all asleep, one fell asleep, a state is NaN: a sleeping vehicle's state is only moved by the
    projection, finite; NaN can arise in awake ones)."""
    all_asleep, slept, nan = True, False, False
    for a in range(na):
        i = awake[a]
        if math.hypot(S[i, 3], S[i, 4]) < v_rest and abs(S[i, 5]) < v_rest:
            S[i, 3:6] = 0.0
            asleep[i] = sleeping
            if sleeping:
                Snew[i] = S[i]
                slept = True
        if not asleep[i]:
            all_asleep = False
        if math.isnan(S[i, 0]) or math.isnan(S[i, 3]):
            nan = True
    return all_asleep, slept, nan


@njit(inline="always")
def _record(traj, n_rec, t, S):
    """The vehicles' state at t into the trajectory's next row. Returns the rows filled."""
    traj[n_rec, :, 0] = t
    traj[n_rec, :, 1:7] = S
    return n_rec + 1


@njit(cache=True, pipeline_class=StagesCompiler)  # (compiler.py: the stages inlined without reference counts)
def simulate_one(P, S0, B, cfg, A, NA, zones, rest, final, contact, imp, traj, diag):
    """Simulate one scene. P (nv, N_PARAMS), S0 (nv, 6) start states, B (nb, 5) barriers
    (x, y, heading, half length, half width), cfg the run's settings (a layout.SETTINGS record), A, NA the
    driver's action tables, zones the friction zones (common/driver_inputs.pack_action_tables, pack_zones).
    Outputs are written into the arrays passed in."""
    nv, nb = P.shape[0], B.shape[0]
    nk = nv + nb
    mu, e, mu_imp, law = cfg.road_friction, cfg.restitution, cfg.impact_friction, cfg.law
    duration, dt, coarse_dt, rec_dt = cfg.duration, cfg.dt, cfg.coarse_dt, cfg.record_dt
    tol, v_rest = cfg.onset_tol, cfg.v_rest
    broad, sleeping = cfg.broad_phase, cfg.sleeping  # study switches (comparison scaling)
    # ---- the state and the scratch arrays of the stages
    S = S0.copy()
    no_alt = np.empty(0)
    Snew = np.empty_like(S)
    S_before = np.empty_like(S)
    k1 = np.empty_like(S)
    k2 = np.empty_like(S)
    tmp = np.empty_like(S)
    acc = np.zeros((nv, 2))
    asleep = np.zeros(nv, np.bool_)
    hit = np.zeros(nv, np.bool_)
    radius = np.empty(nk)
    for k in range(nk):
        radius[k] = _radius(P, B, k, nv)
    in_contact = np.zeros((nv, nk), np.bool_)
    episode = np.full((nv, nk), -1, np.int64)  # impact row of the pair's open contact episode
    allowed = np.zeros((nv, nk))  # overlap the projection leaves (a collision position's start overlap)
    cl_i = np.empty(nv * nk, np.int64)  # the contacts of a step: pair, depth, normal, overlap centroid
    cl_k = np.empty(nv * nk, np.int64)
    cl_d = np.empty(nv * nk)
    cl_n = np.empty((nv * nk, 2))
    cl_p = np.empty((nv * nk, 2))
    cl_v = np.empty((nv * nk, 8, 2))  # and the overlap polygon's vertices
    cl_m = np.zeros(nv * nk, np.int64)
    speeds = np.empty(cl_v.shape[1])  # the approach of each overlap vertex (_fastest_point)
    oa, ob = np.empty((4, 2)), np.empty((4, 2))  # the outlines of the pair under test (_outline)
    pen = np.empty((nv * nk, 3))  # each listed pair's overlap test at the step's end: depth, normal
    awake = np.empty(nv, np.int64)  # the awake vehicles and the pairs with an awake member (_awake_sets)
    pair_i = np.empty(nv * nk, np.int64)
    pair_k = np.empty(nv * nk, np.int64)
    near_i = np.empty(nv * nk, np.int64)  # the listed pairs that can touch soon (_near_pairs)
    near_k = np.empty(nv * nk, np.int64)
    ref = np.zeros((nv, 2))
    n_near, near_stale = 0, True
    _start_contacts(P, S, B, radius, broad, in_contact, allowed, oa, ob)
    mu_max = mu  # the largest road friction anywhere (zones): bounds the step and the stopping speed
    for z in range(zones[2].shape[0]):
        mu_max = max(mu_max, zones[2][z])
    zoned = zones[2].shape[0] > 0
    wheel_reach = np.empty(nv)  # the CG-centred circle holding every wheel (_wheel_frictions)
    zcache = np.zeros((nv, 12))  # each vehicle's last wheel frictions and their margins (_wheel_frictions): none
    zcache[:, 3:8] = -1.0
    inp = np.zeros((nv, N_IN))  # each vehicle's driver inputs at the step's start (_heun): steer 0 so far
    inp[:, IN_COS_STEER] = 1.0
    held = np.full(nv, -math.inf)  # until when the inputs of the law read last hold (steady_next): none yet
    law_mode = np.zeros(nv, np.int64)  # the law read last: driver_inputs, next_change, ramping
    law_brake = np.zeros(nv)
    law_change = np.zeros(nv)
    law_ramp = np.zeros(nv, np.bool_)
    for i in range(nv):
        wheel_reach[i] = math.sqrt(max(P[i, P_A], P[i, P_B]) ** 2 + (0.5 * P[i, P_TRACK]) ** 2)
    for i in range(nv):
        if math.hypot(S[i, 3], S[i, 4]) < v_rest and abs(S[i, 5]) < v_rest:
            S[i, 3:6] = 0.0
            asleep[i] = sleeping
    diag[:] = 0.0
    diag[D_CONTACT_T] = math.nan
    contact[:] = math.nan
    ke0 = 0.0
    for i in range(nv):
        ke0 += _kinetic(P, S, i, nv)
    diag[D_KE0] = ke0
    n_imp, n_rec, t = 0, 0, 0.0
    next_rec = 0.0
    status = STATUS_OK
    if cfg.given and nk >= 2:
        n_imp, status = _given_impact(P, S, B, cfg, e, mu_imp, law, S_before, contact, imp, hit, asleep, in_contact,
                                      diag)
    na, n_pairs = _awake_sets(asleep, nk, awake, pair_i, pair_k)
    Snew[:] = S  # a sleeping vehicle's row of Snew stays equal to its row of S (_heun leaves it)
    steps = 0
    # ---- the time loop
    while t < duration - 1e-12:
        if rec_dt > 0.0 and t >= next_rec - 1e-12 and n_rec < traj.shape[0] - 1:
            n_rec = _record(traj, n_rec, t, S)
            next_rec += rec_dt
        # step size: fine within the tyre forces' stability limit, coarse while every moving vehicle runs
        # straight and nothing can touch; a step ends where a driver's input changes its law
        h, t_change, h_long = _fine_step(P, S, A, NA, t, awake, na, hit, held, law_mode, law_brake, law_change,
                                         law_ramp, inp, radius, zones[3], zoned, mu_max, dt, coarse_dt)
        if h_long > h:
            h = _coarse_step(P, S, B, radius, pair_i, pair_k, n_pairs, h, h_long, mu_max, oa, ob, diag)
        h = min(h, duration - t, t_change - t)
        # free motion
        _heun(P, S, t, A, NA, hit, zones, wheel_reach, zcache, awake, na, mu, acc, h, Snew, k1, k2, tmp, inp, held)
        steps += 1
        diag[D_VEHICLE_STEPS] += na
        if steps > MAX_STEPS:
            status = STATUS_STEP_LIMIT
            break
        # the pairs tested this step
        li, lk, nl = pair_i, pair_k, n_pairs
        if broad and (na < nv or nb > 0):
            n_near, near_stale = _near_list(S, Snew, B, radius, asleep, awake, na, pair_i, pair_k, n_pairs, ref,
                                            near_i, near_k, n_near, near_stale, in_contact, episode, allowed)
            if not near_stale:
                li, lk, nl = near_i, near_k, n_near
        # onset: the step shortened to a new contact's touch (or a contact's deepening)
        bisected = False  # (else the contacts reuse each pair's test of the step's end: pen)
        for p in range(nl):
            bisect, lo_d, hi_d = _onset_test(P, Snew, B, radius, broad, li[p], lk[p], p, in_contact, episode, allowed,
                                             tol, pen, oa, ob, diag)
            if bisect:
                h = _bisect(P, S, t, A, NA, hit, zones, wheel_reach, zcache, awake, na, mu, acc, Snew, k1, k2, tmp,
                            inp, held, B, li[p], lk[p], h, lo_d, hi_d, oa, ob, diag)
                bisected = True
        t += h
        _accept(S, Snew, awake, na)
        # contacts, their impact and contact impulses, the projection
        nc = _gather_contacts(P, S, B, radius, broad, bisected, li, lk, nl, pen, in_contact, episode, allowed, oa,
                              ob, cl_i, cl_k, cl_d, cl_n, cl_p, cl_v, cl_m, diag)
        n_imp, capped, woke = _impulses(P, S, B, cfg, t, nc, cl_i, cl_k, cl_n, cl_p, cl_v, cl_m, speeds, episode, imp,
                                        n_imp, S_before, no_alt, contact, hit, asleep, oa, ob, diag)
        if capped:
            status = STATUS_IMPACT_CAP
            break
        if woke:
            na, n_pairs = _awake_sets(asleep, nk, awake, pair_i, pair_k)
            near_stale = True
        near_stale = _project(P, S, Snew, nc, cl_i, cl_k, cl_d, cl_n, allowed, asleep, near_stale, diag)
        # rest and sleep
        all_asleep, slept, nan = _come_to_rest(S, Snew, asleep, awake, na, v_rest, sleeping)
        if nan:
            status = STATUS_NAN
        if slept:
            na, n_pairs = _awake_sets(asleep, nk, awake, pair_i, pair_k)
            near_stale = True
        if status == STATUS_NAN or (all_asleep and cfg.stop_at_rest):
            break
    # ---- the results
    if rec_dt > 0.0 and n_rec < traj.shape[0]:
        n_rec = _record(traj, n_rec, t, S)
    rest[:, :] = S[:, 0:3]
    final[:, :] = S[:, 3:6]
    _settle_reimpacts(P, imp, n_imp, nv)
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
