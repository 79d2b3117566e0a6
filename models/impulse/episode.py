"""The contact stages of the impulse kernel's time step (kernel.simulate_one): an impact at a given point at t = 0,
the onset of a contact located by bisection, the step's contacts gathered, the impact and contact impulses exchanged
at them, and the position projection that keeps sustained contact from sinking in (contact episodes: the kernel's
docstring and docs/physics.md §5).

The stages are inlined into the time loop at numba's IR level (inline="always"; with compiler.py no call and no
reference counting at run time: the same compiled code as the loop written in one piece). They take the loop's
arrays and scalars as plain arguments (at most 30: kernel.py), write into the arrays and return the scalars they
change.
"""
import math

from numba import njit

from crashlab.geometry import clip_convex, contact_zone_centroid, overlap_centroid, penetration
from crashlab.outcome import PUSH_TIME, REIMPACT_SPEED, SEPARATION

from .contact import _centre, _circles_apart, _engagement, _outline, _point_velocity, _project_apart
from .impacts import _apply_impulse, _merge_impact, _record_impact, _struck
from .layout import (
    D_BISECT,
    D_CONTACT_T,
    D_E_IMPACT,
    D_FOLLOW,
    D_MAX_DEPTH,
    D_NARROW,
    D_PROJECTED,
    I_CLOSING,
    I_ENGAGE,
    I_ENGAGE_RATIO,
    I_KIND,
    I_N_FOLLOW,
    I_REIMPACT,
    I_REVERSED,
    I_T,
    PUSH,
    STATUS_NOT_APPROACHING,
    STATUS_OK,
)
from .motion import _heun

V_EPS = 1e-6  # m/s: an overlapping pair approaching slower needs no contact impulse (round-off level)
# m/s: overlap vertices approaching within this of the fastest tie (_fastest_point): 1000x the round-off of a
# point velocity of ~30 m/s, a physically negligible difference
V_TIE = 1e-12
CONTACT_SLOP = 0.002  # m: overlap tolerated in sustained contact (no bisection, no projection below it)
DEEPEN = 2.0 * CONTACT_SLOP  # m: a touching pair's overlap deepening past this within a step is bisected
MAX_SWEEPS = 50  # sequential-impulse sweeps over simultaneous contacts per step


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


@njit(inline="always")
def _onset_test(P, Snew, B, radius, broad, i, k, p, in_contact, episode, allowed, tol, pen, oa, ob, diag):
    """The onset test of a tested pair (i, k), the p-th: its overlap at the step's end Snew (into pen[p]: depth,
    normal). A pair not in contact that overlaps by more than tol is a new contact, whose step is bisected to an
    overlap within (0, tol]; a touching pair whose overlap deepens past DEEPEN within the step (another part of it
    approaching, e.g. a rotating car's far corner) is bisected likewise, to an overlap within (CONTACT_SLOP,
    DEEPEN]. Returns (bisect, the overlap window's low and high end)."""
    nv = P.shape[0]
    if broad and _circles_apart(Snew, B, radius, i, k, nv):
        return False, 0.0, 0.0
    diag[D_NARROW] += 1
    depth, nx, ny, _ = penetration(_outline(P, Snew, B, i, nv, oa), _outline(P, Snew, B, k, nv, ob))
    pen[p, 0], pen[p, 1], pen[p, 2] = depth, nx, ny
    if in_contact[i, k]:
        if allowed[i, k] > 0.0 or depth <= DEEPEN:
            return False, 0.0, 0.0
        return True, CONTACT_SLOP, DEEPEN
    if depth <= tol or (episode[i, k] >= 0 and depth <= CONTACT_SLOP):
        return False, 0.0, 0.0
    return True, 0.0, tol


@njit(inline="always")
def _bisect(P, S, t, A, NA, hit, zones, wheel_reach, zcache, awake, na, mu, acc, Snew, k1, k2, tmp, inp, held, B,
            i, k, h, lo_d, hi_d, oa, ob, diag):
    """The step from t shortened by bisection (at most 60 halvings) until the overlap of the pair (i, k) at its end
    lies within (lo_d, hi_d]. Snew holds the shortened step's end (_heun). Returns the step."""
    nv = P.shape[0]
    lo, hi = 0.0, h
    for _ in range(60):
        hm = 0.5 * (lo + hi)
        _heun(P, S, t, A, NA, hit, zones, wheel_reach, zcache, awake, na, mu, acc, hm, Snew, k1, k2, tmp, inp, held)
        diag[D_BISECT] += 1
        depth = penetration(_outline(P, Snew, B, i, nv, oa), _outline(P, Snew, B, k, nv, ob))[0]
        if depth > hi_d:
            hi = hm
        elif depth <= lo_d:
            lo = hm
        else:
            break
    return hm


@njit(inline="always")
def _gather_contacts(P, S, B, radius, broad, bisected, li, lk, nl, pen, in_contact, episode, allowed, oa, ob,
                     cl_i, cl_k, cl_d, cl_n, cl_p, cl_v, cl_m, diag):
    """The step's contacts: each tested pair's overlap at the step's end (pen, or tested again after a bisection)
    updates its contact state (a pair further apart than SEPARATION ends its episode); an overlap deeper than a
    collision position's start overlap is listed (cl_*: pair, depth, normal, overlap centroid, overlap polygon).
    Returns the number listed."""
    nv = P.shape[0]
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


@njit(inline="always")
def _contact_state(contact, X, diag, t):
    """The vehicles' state at the first impact (X: just before it): position, heading, speed; and its time."""
    diag[D_CONTACT_T] = t
    for q in range(X.shape[0]):
        contact[q, 0], contact[q, 1] = X[q, 0], X[q, 1]
        contact[q, 2] = X[q, 2]
        contact[q, 3] = math.hypot(X[q, 3], X[q, 4])


@njit(inline="always")
def _given_impact(P, S, B, cfg, e, mu_imp, law, S_before, contact, imp, hit, asleep, in_contact, diag):
    """The impact at t = 0 at a given point of impact and contact plane (PC-Crash style), in the impact table's
    first row. Returns (impacts recorded, status)."""
    nv = P.shape[0]
    i0, j = cfg.given_i, cfg.given_j  # the pair touching at the point
    px, py, th = cfg.given_x, cfg.given_y, cfg.given_plane
    nx, ny = math.sin(th), -math.cos(th)
    cjx, cjy = _centre(S, B, j, nv)
    if nx * (cjx - S[i0, 0]) + ny * (cjy - S[i0, 1]) < 0.0:
        nx, ny = -nx, -ny
    _contact_state(contact, S, diag, 0.0)
    S_before[:] = S
    pn, pt, kind, energy, gn = _apply_impulse(P, S, i0, j, nv, px, py, nx, ny, e, mu_imp, law, imp[0])
    if kind < 0:
        return 0, STATUS_NOT_APPROACHING
    _record_impact(imp, 0, 0.0, i0, j, nv, P, B, S_before, S, pn, pt, kind, energy, px, py, nx, ny)
    # the given impulse keeps its own row (the collision position's impulse as given); contact after it, where
    # the pair's overlap deepens, opens an episode of its own
    diag[D_E_IMPACT] += energy
    _struck(i0, j, nv, hit, asleep)
    in_contact[i0, j] = True
    return 1, STATUS_OK


@njit(inline="always")
def _impulses(P, S, B, cfg, t, nc, cl_i, cl_k, cl_n, cl_p, cl_v, cl_m, speeds, episode, imp, n_imp, S_before,
              no_alt, contact, hit, asleep, oa, ob, diag):
    """The impulses at the step's contacts: a pair's first touch of an episode is an impact with its own row of the
    impact table (its point: the middle of the contact zone the approach will crush, or with [impact] point =
    "engagement" the overlap's centroid at engagement with its contact plane); a pair in an open episode that
    approaches gets a plastic contact impulse at the overlap's fastest approaching point, booked into the episode's
    row; later than PUSH_TIME after the impact, into a push row of its own (layout.PUSH, §5), or where it closes at
    crashlab.outcome.REIMPACT_SPEED or faster there or in a push, into a re-impact's row (I_REIMPACT, §15
    "Re-impacts"; impacts._settle_reimpacts after the run). Several contacts at
    once (a car squeezed between a car and a wall) are resolved together by sweeps of sequential impulses
    (projected Gauss-Seidel): after the first sweep a pair is approaching again only through its neighbours'
    impulses of this instant, so its further impulses are plastic and booked into its row. Returns
    (n_imp, capped: the impact table is full, woke: a sleeping vehicle was struck)."""
    nv = P.shape[0]
    e, mu_imp, law, max_imp = cfg.restitution, cfg.impact_friction, cfg.law, min(cfg.max_impacts, imp.shape[0])
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
                approach, px, py = _fastest_point(S, i, k, nv, cl_v[c], cl_m[c], nx, ny, approach, px, py, speeds)
            if approach <= V_EPS:
                continue
            is_impact = row < 0
            # the contact outlasts a collision's pulse: from here on the episode is a push, in its own row (§5)
            # (a full table keeps the push in its impact's row: a push never fails a run)
            late = not is_impact and imp[row, I_T] != t and (imp[row, I_KIND] == PUSH or t - imp[row, I_T] > PUSH_TIME)
            # closing as fast as a collision there: a re-impact, a row of its own (as in the 3D models, §15)
            reimpact = late and approach >= REIMPACT_SPEED and n_imp < max_imp
            push = late and not reimpact and imp[row, I_KIND] != PUSH and n_imp < max_imp
            if is_impact and n_imp >= max_imp:
                stop = True
                break
            if is_impact:
                zx, e_flag, e_ratio = math.nan, 0, math.nan
                if cfg.engagement:
                    zx, zy, nx, ny, e_flag, e_ratio = _engagement(P, S, B, i, k, nv, cfg.engagement_depth, nx, ny,
                                                                  oa, ob)
                if math.isnan(zx):
                    zx, zy, _ = contact_zone_centroid(_outline(P, S, B, i, nv, oa), _outline(P, S, B, k, nv, ob),
                                                      nx, ny, cfg.crush_time * approach)
                if not math.isnan(zx):
                    px, py = zx, zy
            e_k = e if is_impact else 0.0  # follow-ups are plastic (no bounce chatter)
            S_before[:] = S
            alt = imp[n_imp] if is_impact or reimpact else no_alt  # (the impact's row: its slip-reversal check)
            pn, pt, kind, energy, gn = _apply_impulse(P, S, i, k, nv, px, py, nx, ny, e_k, mu_imp, law, alt)
            if kind < 0:
                continue
            active = True
            if is_impact:
                if n_imp == 0:
                    _contact_state(contact, S_before, diag, t)
                _record_impact(imp, n_imp, t, i, k, nv, P, B, S_before, S, pn, pt, kind, energy, px, py, nx, ny)
                imp[n_imp, I_ENGAGE], imp[n_imp, I_ENGAGE_RATIO] = e_flag, e_ratio
                episode[i, k] = n_imp
                n_imp += 1
            elif push or reimpact:
                _record_impact(imp, n_imp, t, i, k, nv, P, B, S_before, S, pn, pt, kind if reimpact else PUSH, energy,
                               px, py, nx, ny)
                if push:
                    imp[n_imp, I_REVERSED] = 0.0
                imp[n_imp, I_CLOSING], imp[n_imp, I_N_FOLLOW] = math.nan, 1.0
                imp[n_imp, I_REIMPACT] = 1.0 if reimpact else 0.0
                episode[i, k] = n_imp
                n_imp += 1
                diag[D_FOLLOW] += 1
            else:
                _merge_impact(imp, row, t, i, k, nv, S_before, S, pn, pt, energy, nx, ny)
                diag[D_FOLLOW] += 1
            diag[D_E_IMPACT] += energy
            woke = woke or asleep[i] or (k < nv and asleep[k])
            _struck(i, k, nv, hit, asleep)
        if stop or not active:
            break
    return n_imp, stop, woke


@njit(inline="always")
def _project(P, S, Snew, nc, cl_i, cl_k, cl_d, cl_n, allowed, asleep, near_stale, diag):
    """Non-penetration at the position level: the velocity-level contact impulse stops the approach at the end of a
    step but not the overlap gained within it (~ a h^2 / 2); each listed contact's overlap is pushed back to
    CONTACT_SLOP (or a collision position's start overlap). Returns near_stale: a static partner moved."""
    nv = P.shape[0]
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
    return near_stale
