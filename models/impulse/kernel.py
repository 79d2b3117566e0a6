"""The compiled time loop of the impulse model: vehicle motion, contact onset, impulses, rest.

Everything per scene runs inside one numba function (no Python loop over time steps); a batch of
scenes runs in parallel with `prange`. Step-size policy:
  * fine steps (Heun, 2nd order) of at most `dt`, and below 1 / (fastest decay rate of the regularised
    tyre forces at the wheels' slip speeds) (planar_vehicle.slip_rate), whenever a tyre force can change
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

Contact episodes (the model docstring argues the choice): a pair's touch after being apart by more than
SEPARATION is an impact (restitution e, a row of the impact table); until the pair is that far apart
again, every step in which the outlines overlap and approach gets plastic (e = 0) Coulomb-limited
contact impulses, booked into that impact's row, and a position projection keeps the overlap below
CONTACT_SLOP. Reaching max_impacts or MAX_STEPS stops and fails the run.

The time loop and its step policy live here; the stages it calls, one module per reason to change:
contact.py (outlines, contact geometry, the engagement point, the position projection), impacts.py (the impulse
at a point and the impact record), motion.py (the Heun step and the wheels' road friction), pairs.py (which
vehicles and pairs a step visits), layout.py (the arrays' layouts).
"""
import math

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
from crashlab.models.common.planar_vehicle import P_A, P_B, P_TRACK, rate_of_slips, wheel_slips
from crashlab.models.common.wheel_states import LOCKED
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
    STATUS_IMPACT_CAP,
    STATUS_NAN,
    STATUS_NOT_APPROACHING,
    STATUS_OK,
    STATUS_STEP_LIMIT,
)
from .motion import _gap_step, _heun, _long_step, _near_zone, _straight
from .pairs import _awake_sets, _moved, _near_pairs

MAX_STEPS = 200_000  # a guard: no scene needs more (duration <= 120 s at dt >= 1 ms)
V_EPS = 1e-6  # m/s: an overlapping pair approaching slower needs no contact impulse (round-off level)
# m/s: overlap vertices approaching within this of the fastest tie (_fastest_point): 1000x the round-off of a
# point velocity of ~30 m/s, a physically negligible difference
V_TIE = 1e-12
CONTACT_SLOP = 0.002  # m: overlap tolerated in sustained contact (no bisection, no projection below it)
SEPARATION = 0.05  # m: a pair further apart than this has ended its contact episode
DEEPEN = 2.0 * CONTACT_SLOP  # m: a touching pair's overlap deepening past this within a step is bisected
MAX_SWEEPS = 50  # sequential-impulse sweeps over simultaneous contacts per step
REACH = 1.0  # m: a pair with a static member further apart than 2 REACH is left out until a vehicle moved REACH


@njit(cache=True)
def _normal_approach(S, i, k, nv, px, py, nx, ny):
    """The speed at which k's point (px, py) approaches i's along the normal n."""
    v1x, v1y = _point_velocity(S, i, nv, px, py)
    v2x, v2y = _point_velocity(S, k, nv, px, py)
    return -((v2x - v1x) * nx + (v2y - v1y) * ny)


@njit(cache=True)
def _fastest_point(S, i, k, nv, poly, n_poly, nx, ny, approach, px, py, speeds):
    """Sustained contact (docs/physics.md §5): the point of the overlap that approaches fastest, from the overlap's
    centroid (px, py) approaching at `approach` (rigid bodies: the normal velocity is linear over the overlap, so
    its extremes are at vertices). Vertices within V_TIE of the fastest tie: the point is their mean (the centroid
    where they tie with it: a pure translation), not the first in the polygon's order, which a reflected scene
    reverses. Each vertex's approach is evaluated once, into the scratch `speeds` (>= n_poly). Returns (approach,
    px, py)."""
    fastest = approach
    for q in range(n_poly):
        speeds[q] = _normal_approach(S, i, k, nv, poly[q, 0], poly[q, 1], nx, ny)
        fastest = max(fastest, speeds[q])
    if fastest - approach <= V_TIE:
        return approach, px, py
    sx, sy, n = 0.0, 0.0, 0
    for q in range(n_poly):
        if speeds[q] >= fastest - V_TIE:
            sx, sy, n = sx + poly[q, 0], sy + poly[q, 1], n + 1
    if n == 1:
        return fastest, sx, sy
    return _normal_approach(S, i, k, nv, sx / n, sy / n, nx, ny), sx / n, sy / n


@njit(cache=True)
def simulate_one(P, S0, B, cfg, A, NA, zones, rest, final, contact, imp, traj, diag):
    """Simulate one scene. P (nv, N_PARAMS), S0 (nv, 6) start states, B (nb, 5) barriers
    (x, y, heading, half length, half width), cfg the run's settings (a layout.SETTINGS record), A, NA the
    driver's action tables, zones the friction zones (common/driver_inputs.pack_action_tables, pack_zones).
    Outputs are written into the arrays passed in."""
    nv, nb = P.shape[0], B.shape[0]
    nk = nv + nb
    mu, e, mu_imp, law = cfg.road_friction, cfg.restitution, cfg.impact_friction, cfg.law
    duration, dt, coarse_dt, rec_dt = cfg.duration, cfg.dt, cfg.coarse_dt, cfg.record_dt
    tol, v_rest, max_imp = cfg.onset_tol, cfg.v_rest, min(cfg.max_impacts, imp.shape[0])
    broad, sleeping = cfg.broad_phase, cfg.sleeping  # study switches (comparison scaling)
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
    for i in range(nv):  # outlines that overlap at the start are in contact (a collision position)
        for k in range(i + 1, nk):
            if broad and _circles_apart(S, B, radius, i, k, nv):
                continue
            d0 = penetration(_outline(P, S, B, i, nv, oa), _outline(P, S, B, k, nv, ob))[0]
            if d0 > 0.0:
                in_contact[i, k] = True
                allowed[i, k] = d0
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

    # impact at t = 0 at a given point of impact and contact plane (PC-Crash style)
    if cfg.given and nk >= 2:
        i0, j = cfg.given_i, cfg.given_j  # the pair touching at the point
        px, py, th = cfg.given_x, cfg.given_y, cfg.given_plane
        nx, ny = math.sin(th), -math.cos(th)
        cjx, cjy = _centre(S, B, j, nv)
        if nx * (cjx - S[i0, 0]) + ny * (cjy - S[i0, 1]) < 0.0:
            nx, ny = -nx, -ny
        for i in range(nv):
            contact[i, 0], contact[i, 1], contact[i, 2] = S[i, 0], S[i, 1], S[i, 2]
            contact[i, 3] = math.hypot(S[i, 3], S[i, 4])
        diag[D_CONTACT_T] = 0.0
        S_before[:] = S
        pn, pt, kind, energy, gn = _apply_impulse(P, S, i0, j, nv, px, py, nx, ny, e, mu_imp, law, imp[0])
        if kind < 0:
            status = STATUS_NOT_APPROACHING
        else:
            _record_impact(imp, 0, 0.0, i0, j, nv, S_before, S, pn, pt, kind, energy, px, py, nx, ny)
            n_imp = 1
            # the given impulse keeps its own row (the collision position's impulse as given); contact
            # after it, where the pair's overlap deepens, opens an episode of its own
            diag[D_E_IMPACT] += energy
            _struck(i0, j, nv, hit, asleep)
            in_contact[i0, j] = True

    na, n_pairs = _awake_sets(asleep, nk, awake, pair_i, pair_k)
    Snew[:] = S  # a sleeping vehicle's row of Snew stays equal to its row of S (_heun leaves it)
    steps = 0
    while t < duration - 1e-12:
        if rec_dt > 0.0 and t >= next_rec - 1e-12 and n_rec < traj.shape[0] - 1:
            traj[n_rec, :, 0] = t
            traj[n_rec, :, 1:7] = S
            n_rec += 1
            next_rec += rec_dt
        # ---- step size: the fine step within the tyre forces' stability limit at the wheels' slip speeds
        # (planar_vehicle.slip_rate); a long step, up to coarse_dt, while every moving vehicle runs straight
        # or slides on locked wheels, far from stopping, and nothing can touch (_long_step)
        # (a step ends where a driver's input changes its law: an action's start or its ramp's end; it is
        # fine within a ramp and near a friction zone)
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
            cs, ss = inp[i, IN_COS_STEER], inp[i, IN_SIN_STEER]
            slips = wheel_slips(P[i], S[i], c, sn, cs, ss, mu_max)
            if mode != LOCKED and not _straight(S[i], c, sn, steer):  # its load transfer lags a stage (first
                slips = (0.0, 0.0, slips[2], slips[3])  # order): the worst case's step (docs/physics.md §2)
            rate = rate_of_slips(P[i], mu_max, mode, brake, slips, dt)  # 0: locked on ice, no force
            if rate * h > 1.0:
                h = 1.0 / rate
            if long_ok:  # (not within a ramp, nor where a wheel's friction may change: near a zone)
                if law_ramp[i] or (zoned and _near_zone(S, i, radius[i] + math.hypot(S[i, 3], S[i, 4]) * coarse_dt
                                                        + PATCH, zones[3])):
                    h_long = 0.0
                else:
                    h_long = min(h_long, _long_step(P[i], S[i], c, sn, steer, mode, brake, mu_max, coarse_dt, slips))
                long_ok = h_long > h
        if long_ok:
            for p in range(n_pairs):  # (a sleeping vehicle and a barrier: not listed, closing 0)
                h_long = min(h_long, _gap_step(P, S, B, radius, pair_i[p], pair_k[p], nv, mu_max * G * h_long, oa, ob))
            if h_long > h:
                h = h_long
                diag[D_COARSE] += 1
        h = min(h, duration - t, t_change - t)
        _heun(P, S, t, A, NA, hit, zones, wheel_reach, zcache, awake, na, mu, acc, h, Snew, k1, k2, tmp, inp, held)
        steps += 1
        diag[D_VEHICLE_STEPS] += na
        if steps > MAX_STEPS:
            status = STATUS_STEP_LIMIT
            break
        # ---- the pairs tested this step: with the broad phase, pairs with a static partner far away
        # are left out (_near_pairs, rebuilt once an awake vehicle has moved REACH); a step longer
        # than REACH tests every listed pair
        li, lk, nl = pair_i, pair_k, n_pairs
        if broad and (na < nv or nb > 0):
            if near_stale or _moved(S, Snew, awake, na, ref, REACH):
                near_stale = _moved(S, Snew, awake, na, S[:, 0:2], REACH)  # the step itself longer
                if not near_stale:
                    n_near = _near_pairs(S, B, radius, asleep, awake, na, pair_i, pair_k, n_pairs, ref, REACH,
                                         near_i, near_k, in_contact, episode, allowed)
            if not near_stale:
                li, lk, nl = near_i, near_k, n_near
        # ---- onset of a new contact: bisect the step until the overlap is at most tol; a touching pair
        # whose overlap deepens past DEEPEN within the step (another part of it approaching, e.g. a
        # rotating car's far corner) is bisected likewise, to an overlap between CONTACT_SLOP and DEEPEN
        bisected = False  # (else the contacts below reuse each pair's test of the step's end: pen)
        for p in range(nl):
            i, k = li[p], lk[p]
            if broad and _circles_apart(Snew, B, radius, i, k, nv):
                continue
            diag[D_NARROW] += 1
            depth, nx, ny, _ = penetration(_outline(P, Snew, B, i, nv, oa), _outline(P, Snew, B, k, nv, ob))
            pen[p, 0], pen[p, 1], pen[p, 2] = depth, nx, ny
            if in_contact[i, k]:
                if allowed[i, k] > 0.0 or depth <= DEEPEN:
                    continue
                lo_d, hi_d = CONTACT_SLOP, DEEPEN
            else:
                if depth <= tol or (episode[i, k] >= 0 and depth <= CONTACT_SLOP):
                    continue
                lo_d, hi_d = 0.0, tol
            lo, hi = 0.0, h
            bisected = True
            for _ in range(60):
                hm = 0.5 * (lo + hi)
                _heun(P, S, t, A, NA, hit, zones, wheel_reach, zcache, awake, na, mu, acc, hm, Snew, k1, k2, tmp, inp,
                      held)
                diag[D_BISECT] += 1
                depth = penetration(_outline(P, Snew, B, i, nv, oa), _outline(P, Snew, B, k, nv, ob))[0]
                if depth > hi_d:
                    hi = hm
                elif depth <= lo_d:
                    lo = hm
                else:
                    break
            h = hm
        t += h
        for a in range(na):
            i = awake[a]
            for q in range(6):
                S[i, q] = Snew[i, q]
        # ---- contacts: an impact (the first touch of an episode) gets its own row; a pair in an open
        # episode that overlaps and approaches gets a plastic contact impulse booked into the episode's
        # row. Several contacts at once (a car squeezed between a car and a wall) are
        # resolved together by sweeps of sequential impulses (projected Gauss-Seidel) over the step's
        # contacts: after the first sweep a pair is approaching again only through its neighbours'
        # impulses of this instant, so its further impulses are plastic and booked into its row. Then a
        # projection keeps each overlap below CONTACT_SLOP.
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
        stop = False
        woke = False
        for _ in range(MAX_SWEEPS if nc > 1 else 1):
            active = False
            for c in range(nc):
                i, k = cl_i[c], cl_k[c]
                nx, ny, px, py = cl_n[c, 0], cl_n[c, 1], cl_p[c, 0], cl_p[c, 1]
                approach = _normal_approach(S, i, k, nv, px, py, nx, ny)
                row = episode[i, k]
                if row >= 0 and imp[row, I_T] != t:
                    approach, px, py = _fastest_point(S, i, k, nv, cl_v[c], cl_m[c], nx, ny, approach, px, py,
                                                      speeds)
                if approach <= V_EPS:
                    continue
                is_impact = row < 0
                if is_impact:
                    if n_imp >= max_imp:
                        status = STATUS_IMPACT_CAP
                        stop = True
                        break
                    # the point: the middle of the contact zone the approach will crush, or (point =
                    # "engagement") the overlap's centroid at engagement with its contact plane
                    zx, e_flag, e_ratio = math.nan, 0, math.nan
                    if cfg.engagement:
                        zx, zy, nx, ny, e_flag, e_ratio = _engagement(P, S, B, i, k, nv, cfg.engagement_depth, nx,
                                                                      ny, oa, ob)
                    if math.isnan(zx):
                        zx, zy, _ = contact_zone_centroid(_outline(P, S, B, i, nv, oa),
                                                          _outline(P, S, B, k, nv, ob),
                                                          nx, ny, cfg.crush_time * approach)
                    if not math.isnan(zx):
                        px, py = zx, zy
                e_k = e if is_impact else 0.0  # follow-ups are plastic (no bounce chatter)
                S_before[:] = S
                alt = imp[n_imp] if is_impact else no_alt  # (the impact's row: its slip-reversal check)
                pn, pt, kind, energy, gn = _apply_impulse(P, S, i, k, nv, px, py, nx, ny, e_k, mu_imp, law, alt)
                if kind < 0:
                    continue
                active = True
                if is_impact:
                    if n_imp == 0:
                        diag[D_CONTACT_T] = t
                        for q in range(nv):
                            contact[q, 0], contact[q, 1] = S_before[q, 0], S_before[q, 1]
                            contact[q, 2] = S_before[q, 2]
                            contact[q, 3] = math.hypot(S_before[q, 3], S_before[q, 4])
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
            if stop or not active:
                break
        if stop:
            break
        if woke:
            na, n_pairs = _awake_sets(asleep, nk, awake, pair_i, pair_k)
            near_stale = True
        # non-penetration at the position level: the velocity-level contact impulse stops the approach at
        # the end of a step but not the overlap gained within it (~ a h^2 / 2)
        for c in range(nc):
            i, k, depth = cl_i[c], cl_k[c], cl_d[c]
            target = max(allowed[i, k], CONTACT_SLOP)
            if depth > target:
                _project_apart(P, S, i, k, nv, cl_n[c, 0], cl_n[c, 1], depth - target)
                diag[D_PROJECTED] += depth - target
                Snew[i] = S[i]  # (a sleeping vehicle's row of Snew equals its row of S)
                if k < nv:
                    Snew[k] = S[k]
                    near_stale = near_stale or asleep[k]  # a static partner moved
                near_stale = near_stale or asleep[i]
            allowed[i, k] = min(allowed[i, k], depth)
        # ---- rest: a vehicle that has (almost) stopped goes to sleep; an impulse wakes it
        # (a sleeping vehicle's state is only moved by the projection, finite: NaN can arise in awake ones)
        all_asleep, slept = True, False
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
                status = STATUS_NAN
        if slept:
            na, n_pairs = _awake_sets(asleep, nk, awake, pair_i, pair_k)
            near_stale = True
        if status == STATUS_NAN or (all_asleep and cfg.stop_at_rest):
            break
    if rec_dt > 0.0 and n_rec < traj.shape[0]:
        traj[n_rec, :, 0] = t
        traj[n_rec, :, 1:7] = S
        n_rec += 1
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
