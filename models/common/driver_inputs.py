"""What a wheel gets at time t at a point of the road (docs/physics.md §2a), one implementation for every model.

* Driver actions: each vehicle's wheel state, brake fraction and front-wheel steer angle over time, from the
  scene's start state and its `actions` (each holds until the next; brake and steer move linearly over the
  action's ramp). `pack_actions` turns them into a table once; `driver_inputs(A, n, t)` reads it (compiled or
  pure Python: register_jitable).
* Friction zones: the road friction at a point from the scene's friction polygons (later zones win).
  `pack_zones` packs them once; `road_friction(x, y, ...)` reads them.

A zone boundary is blended over a tyre contact patch: the friction at a wheel is the friction of the zone
weighted by the share of a patch of length PATCH centred on the wheel that lies inside it (linear in the
signed distance to the boundary). The friction force then has no jump as a wheel crosses a boundary within a
step (fixed-step models see at most a change of (mu_in - mu_out) / PATCH per metre travelled; adaptive ones no
discontinuity to reject steps over), and the work of friction across a boundary equals that of the sharp
boundary, because the blend is symmetric about it: a stopping distance across a zone keeps its analytic value.
"""
from __future__ import annotations

import functools
import math

import numpy as np
from numba.extending import register_jitable

from .wheel_states import BRAKED, LOCKED, LOCKED_AFTER_IMPACT, ROLLING, WHEEL_CODES

# one row per action of one vehicle, row 0 the start state:
# t at which the action starts, t at which its ramp ends, wheel-state code, brake and steer before and after
A_T, A_T_END, A_MODE, A_BRAKE_FROM, A_BRAKE_TO, A_STEER_FROM, A_STEER_TO = range(7)
N_ACTION_COLUMNS = 7

PATCH = 0.2  # m: length of a passenger-car tyre's contact patch (about 0.15-0.2 m), the zone-boundary blend


def _rows(vs) -> list[tuple]:
    mode, brake, steer = WHEEL_CODES[vs.wheels], 0.0, vs.steer
    rows = [(-math.inf, -math.inf, mode, brake, brake, steer, steer)]
    for a in vs.actions:
        mode = WHEEL_CODES[a.wheels] if a.wheels is not None else mode
        brake_to = brake if a.brake is None else a.brake
        steer_to = steer if a.steer is None else a.steer
        rows.append((a.t, a.t + a.ramp, mode, brake, brake_to, steer, steer_to))
        brake, steer = brake_to, steer_to
    return rows


def pack_actions(vs) -> np.ndarray:
    """The action table (rows x N_ACTION_COLUMNS) of one VehicleState: row 0 holds the start state (wheels,
    steer, brake 0) from t = -inf; each action a row from its t."""
    return np.array(_rows(vs), dtype=np.float64)


def pack_action_tables(vehicles) -> tuple[np.ndarray, np.ndarray]:
    """All vehicles' tables in one array (vehicles x rows x columns, padded with the last row) and the
    number of rows of each: fresh arrays on every call (a few microseconds; nothing remembered)."""
    tables = [_rows(v) for v in vehicles]
    k = max(len(t) for t in tables)
    A = np.array([t + t[-1:] * (k - len(t)) for t in tables], dtype=np.float64)
    NA = np.array([len(t) for t in tables], dtype=np.int64)
    return A, NA


@register_jitable
def ahead(t, time):
    """Whether `time` lies after t by more than round-off (1e-12 relative): a change there is still to come."""
    return time > t + 1e-12 * (1.0 + abs(t))


@register_jitable
def next_change(A, n, t):
    """The first time after t at which the vehicle's inputs change their law: an action's start (a jump of
    wheel state, brake or steer, or a ramp's start) or a ramp's end (a kink); inf if none. A step that ends
    there does not straddle a change."""
    for k in range(1, n):
        if ahead(t, A[k, A_T]):
            return A[k, A_T]
        if ahead(t, A[k, A_T_END]):
            return A[k, A_T_END]
    return math.inf


@register_jitable
def steer_rate(A, n, t):
    """d(steer)/dt at t [rad/s]: nonzero within a steer ramp."""
    k = n - 1
    while k > 0 and t < A[k, A_T]:
        k -= 1
    if t >= A[k, A_T_END]:
        return 0.0
    return (A[k, A_STEER_TO] - A[k, A_STEER_FROM]) / (A[k, A_T_END] - A[k, A_T])


@register_jitable
def ramping(A, n, t):
    """True within a ramp that moves the brake or the steer (the inputs change continuously)."""
    k = n - 1
    while k > 0 and t < A[k, A_T]:
        k -= 1
    return t < A[k, A_T_END] and (A[k, A_BRAKE_TO] != A[k, A_BRAKE_FROM] or A[k, A_STEER_TO] != A[k, A_STEER_FROM])


@register_jitable
def steady_next(A, n, t):
    """How long the vehicle's inputs at t hold: when its current action's ramp is over, the next action's
    start (inf if none): driver_inputs and next_change keep their values of t at every later t' while that
    start is ahead(t', start) (each ramp ends before the next action starts); -inf within a ramp."""
    k = n - 1
    while k > 0 and t < A[k, A_T]:
        k -= 1
    if t < A[k, A_T_END]:
        return -math.inf
    return A[k + 1, A_T] if k + 1 < n else math.inf


@register_jitable
def driver_inputs(A, n, t, before=False):
    """(wheel-state code, brake fraction, steer angle [rad]) of one vehicle at time t from its action table
    A (n rows). A `braked` wheel state brakes fully without locking: its brake fraction is 1.
    before=True gives the left limit at t (an action starting exactly at t not yet applied): the end of a
    step that ends at an action's time belongs to the law of the step (next_change)."""
    k = n - 1
    while k > 0 and (t < A[k, A_T] or (before and t <= A[k, A_T])):
        k -= 1
    mode = int(A[k, A_MODE])
    if t >= A[k, A_T_END]:
        brake, steer = A[k, A_BRAKE_TO], A[k, A_STEER_TO]
    else:
        f = (t - A[k, A_T]) / (A[k, A_T_END] - A[k, A_T])
        brake = A[k, A_BRAKE_FROM] + f * (A[k, A_BRAKE_TO] - A[k, A_BRAKE_FROM])
        steer = A[k, A_STEER_FROM] + f * (A[k, A_STEER_TO] - A[k, A_STEER_FROM])
    if mode == BRAKED:
        brake = 1.0
    return mode, brake, steer


@register_jitable
def effective_mode(mode, struck):
    """The wheel state the tyre law uses: `locked_after_impact` rolls until the vehicle is struck, then locks
    (until an action sets another wheel state)."""
    if mode == LOCKED_AFTER_IMPACT:
        return LOCKED if struck else ROLLING
    return mode


def pack_zones(road) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The road's zones as arrays: edges of all zones (a_x, a_y, e_x, e_y, 1/|e|^2, n_x, n_y: start corner,
    edge vector to the next corner, its inverse squared length, unit normal into the zone), start index of
    each zone's edges (zones + 1), friction per zone, and per zone its bounding box widened by PATCH / 2 and
    whether it is convex (x_min, x_max, y_min, y_max, convex 1/0). Fresh copies of _zone_arrays(road)."""
    return tuple(a.copy() for a in _zone_arrays(road))


@functools.lru_cache(maxsize=64)
def _zone_arrays(road) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """pack_zones' arrays, remembered by the road's value (Road is a frozen dataclass: equal roads, equal
    arrays; a batch's scenes share theirs), read-only: pack_zones hands out copies."""
    zones = road.zones
    edges = np.zeros((sum(len(z.polygon) for z in zones), 7))
    start = np.zeros(len(zones) + 1, dtype=np.int64)
    box = np.empty((len(zones), 5))
    for k, z in enumerate(zones):
        pts = np.asarray(z.polygon, dtype=np.float64)
        e = np.roll(pts, -1, axis=0) - pts
        length = np.hypot(e[:, 0], e[:, 1])
        turn = e[:, 0] * np.roll(e[:, 1], -1) - e[:, 1] * np.roll(e[:, 0], -1)  # cross of consecutive edges
        ccw = np.sum(pts[:, 0] * np.roll(pts[:, 1], -1) - np.roll(pts[:, 0], -1) * pts[:, 1]) > 0
        inward = np.column_stack((-e[:, 1], e[:, 0])) / length[:, None] * (1.0 if ccw else -1.0)
        start[k + 1] = start[k] + len(pts)
        edges[start[k]:start[k + 1]] = np.column_stack((pts, e, 1.0 / length ** 2, inward))
        convex = bool(np.all(turn >= 0) or np.all(turn <= 0))
        box[k] = (pts[:, 0].min() - PATCH / 2, pts[:, 0].max() + PATCH / 2,
                  pts[:, 1].min() - PATCH / 2, pts[:, 1].max() + PATCH / 2, float(convex))
    arrays = (edges, start, np.array([z.friction for z in zones], dtype=np.float64), box)
    for a in arrays:
        a.flags.writeable = False
    return arrays


@register_jitable
def _boundary_distance(x, y, E, i0, i1):
    """(inside, distance to the boundary) of (x, y) and the polygon with edges E[i0:i1] (crossing number)."""
    inside = False
    d2 = math.inf
    for k in range(i0, i1):
        ax, ay, ex, ey = E[k, 0], E[k, 1], E[k, 2], E[k, 3]
        if (ay > y) != (ay + ey > y) and x < ax + (y - ay) * ex / ey:
            inside = not inside
        s = min(max(((x - ax) * ex + (y - ay) * ey) * E[k, 4], 0.0), 1.0)
        dx, dy = x - ax - s * ex, y - ay - s * ey
        d2 = min(d2, dx * dx + dy * dy)
    return inside, math.sqrt(d2)


@register_jitable
def _zone_weight(x, y, E, i0, i1, convex):
    """(share, margin): the share of a contact patch centred on (x, y) that lies inside the polygon with edges
    E[i0:i1], 0.5 + signed distance to the boundary / PATCH clipped to [0, 1], and how far (x, y) may move
    before the share can change (0 within the blend). A convex zone takes the distances to its edges' lines
    (inside: the smallest is the distance to the boundary; outside: the largest negative one bounds it from
    below), the exact distance only within PATCH / 2 outside."""
    half = 0.5 * PATCH
    if convex:
        d_min = math.inf
        for k in range(i0, i1):
            d_min = min(d_min, E[k, 5] * (x - E[k, 0]) + E[k, 6] * (y - E[k, 1]))
        if d_min >= half:
            return 1.0, d_min - half
        if d_min >= 0.0:
            return 0.5 + d_min / PATCH, 0.0
        if d_min <= -half:
            return 0.0, -d_min - half
    inside, d = _boundary_distance(x, y, E, i0, i1)
    if d >= half:
        return (1.0 if inside else 0.0), d - half
    return 0.5 + (d if inside else -d) / PATCH, 0.0


@register_jitable
def _box_gap(x, y, box, z):
    """How far (x, y) lies outside zone z's box (widened by PATCH / 2) along x or y; <= 0 within it."""
    return max(box[z, 0] - x, x - box[z, 1], box[z, 2] - y, y - box[z, 3])


@register_jitable
def _patch_weight(x, y, E, start, box, z):
    """_zone_weight of zone z, 0 outside its box (widened by PATCH / 2), with the box distance as margin."""
    gap = _box_gap(x, y, box, z)
    if gap > 0.0:
        return 0.0, gap
    return _zone_weight(x, y, E, start[z], start[z + 1], box[z, 4] > 0.5)


@register_jitable
def _blend(f, w, mu_zone):
    """The friction f overlaid by a zone covering the share w of the patch."""
    if w >= 1.0:
        return mu_zone
    return f + w * (mu_zone - f)


@register_jitable
def point_friction(x, y, mu_road, E, start, mu, box):
    """(friction, margin): the road friction at (x, y), `mu_road` overlaid by each zone in order (later zones
    win), each blended over the contact patch across its boundary (module docstring), and how far (x, y) may
    move before it can change (0 within a boundary's blend)."""
    f = mu_road
    margin = math.inf
    for z in range(mu.shape[0]):
        gap = _box_gap(x, y, box, z)  # (tested here, not in _patch_weight: 3-4x faster, measured)
        if gap > 0.0:
            margin = min(margin, gap)
            continue
        w, m = _zone_weight(x, y, E, start[z], start[z + 1], box[z, 4] > 0.5)
        f = _blend(f, w, mu[z])
        margin = min(margin, m)
    return f, margin


@register_jitable
def road_friction(x, y, mu_road, E, start, mu, box):
    """The road friction at (x, y) (point_friction)."""
    return point_friction(x, y, mu_road, E, start, mu, box)[0]


@register_jitable
def wheel_point(x, y, c, s, front, rear, half_track, w):
    """(x, y) of wheel w (0 front left, 1 front right, 2 rear left, 3 rear right) of a vehicle at (x, y) heading
    (c, s) = (cos, sin), axles `front` ahead of and `rear` behind the CG."""
    along = front if w < 2 else -rear
    left = half_track if w % 2 == 0 else -half_track
    return x + c * along - s * left, y + s * along + c * left


@register_jitable
def wheel_frictions_clearance(x, y, c, s, front, rear, half_track, mu_road, E, start, mu, box):
    """(f_fl, f_fr, f_rl, f_rr, margin): the road friction at the four wheels (front left, front right, rear
    left, rear right) of a vehicle at (x, y) heading (c, s) = (cos, sin), axles `front` ahead of and `rear`
    behind the CG, and how far any wheel may move before a friction can change (0 while a wheel stands in a
    boundary's blend): point_friction at each wheel, with each zone first tested against the circle about
    the CG that holds every wheel (a zone whose box it misses is skipped, a convex zone that holds it whole
    gives every wheel its friction), so a vehicle away from zone boundaries costs one test per zone."""
    x0, y0 = wheel_point(x, y, c, s, front, rear, half_track, 0)
    x1, y1 = wheel_point(x, y, c, s, front, rear, half_track, 1)
    x2, y2 = wheel_point(x, y, c, s, front, rear, half_track, 2)
    x3, y3 = wheel_point(x, y, c, s, front, rear, half_track, 3)
    f0 = f1 = f2 = f3 = mu_road
    margin = math.inf
    reach = math.sqrt(max(front, rear) ** 2 + half_track ** 2)
    for z in range(mu.shape[0]):
        gap = _box_gap(x, y, box, z) - reach
        if gap > 0.0:  # no wheel within the box
            margin = min(margin, gap)
            continue
        if box[z, 4] > 0.5:
            d_min = math.inf
            for k in range(start[z], start[z + 1]):
                d_min = min(d_min, E[k, 5] * (x - E[k, 0]) + E[k, 6] * (y - E[k, 1]))
            if d_min >= reach + 0.5 * PATCH:  # every wheel's patch wholly inside
                f0 = f1 = f2 = f3 = mu[z]
                margin = min(margin, d_min - reach - 0.5 * PATCH)
                continue
        w, m0 = _patch_weight(x0, y0, E, start, box, z)
        f0 = _blend(f0, w, mu[z])
        w, m1 = _patch_weight(x1, y1, E, start, box, z)
        f1 = _blend(f1, w, mu[z])
        w, m2 = _patch_weight(x2, y2, E, start, box, z)
        f2 = _blend(f2, w, mu[z])
        w, m3 = _patch_weight(x3, y3, E, start, box, z)
        f3 = _blend(f3, w, mu[z])
        margin = min(margin, m0, m1, m2, m3)
    return f0, f1, f2, f3, margin


@register_jitable
def wheel_frictions(x, y, c, s, front, rear, half_track, mu_road, E, start, mu, box):
    """The road friction at the four wheels (wheel_frictions_clearance without the margin)."""
    f0, f1, f2, f3, _ = wheel_frictions_clearance(x, y, c, s, front, rear, half_track, mu_road, E, start, mu, box)
    return f0, f1, f2, f3


def largest_friction(road) -> float:
    """The largest friction anywhere on the road (for step-size bounds)."""
    return max([road.friction] + [z.friction for z in road.zones])


def action_modes(vs) -> set[int]:
    """Every wheel-state code the vehicle's wheels take during the run (for step-size bounds)."""
    return {int(m) for m in pack_actions(vs)[:, A_MODE]}
