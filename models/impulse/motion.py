"""Free motion of the impulse kernel: the Heun step of the awake vehicles (planar_vehicle, docs/physics.md §2)
with the road friction under each wheel (friction zones, §2a) cached between look-ups, and the long steps of the
step policy (_long_step, _gap_step)."""
import math

from numba import njit

from crashlab.geometry import penetration
from crashlab.models.common.driver_inputs import ahead, driver_inputs, effective_mode, point_friction, wheel_point
from crashlab.models.common.planar_vehicle import (
    P_A,
    P_B,
    P_TRACK,
    locked_forces,
    rate_of_slips,
    vehicle_forces_trig,
)
from crashlab.models.common.wheel_states import LOCKED
from crashlab.units import G

from .contact import _centre, _outline
from .layout import IN_BRAKE, IN_COS_HEADING, IN_COS_STEER, IN_MODE, IN_SIN_HEADING, IN_SIN_STEER, IN_STEER


@njit(cache=True, inline="always")  # inlined: a call costs more than the cache hit (measured)
def _wheel_frictions(P, X, i, c, sn, reach, mu, zones, zcache):
    """The road friction under the four wheels of vehicle i in state X[i], heading (c, sn) = (cos, sin)
    (driver_inputs.point_friction at each wheel). zcache[i] = (x, y, heading of the last look-up, the least
    of the four margins, each wheel's margin, each wheel's friction): since that look-up no wheel has moved
    more than d = |dx| + |dy| + reach |dheading|, so while d is below a wheel's margin its friction holds
    (_wheel_lookup)."""
    z = zcache[i]
    d = abs(X[i, 0] - z[0]) + abs(X[i, 1] - z[1]) + reach * abs(X[i, 2] - z[2])
    if d < z[3]:
        return z[8], z[9], z[10], z[11]
    return _wheel_lookup(P, X, i, c, sn, d, mu, zones[0], zones[1], zones[2], zones[3], z)


@njit(cache=True, inline="always")  # (measured: a little faster inlined)
def _wheel_lookup(P, X, i, c, s, d, mu, E, start, zmu, box, z):
    """_wheel_frictions for a vehicle with some wheel's margin spent: that wheel is looked up again, the
    others' margins shrink by d, and the pose of X[i] becomes the reference."""
    least = math.inf
    for w in range(4):
        if d >= z[4 + w]:
            xw, yw = wheel_point(X[i, 0], X[i, 1], c, s, P[i, P_A], P[i, P_B], 0.5 * P[i, P_TRACK], w)
            z[8 + w], z[4 + w] = point_friction(xw, yw, mu, E, start, zmu, box)
        else:
            z[4 + w] -= d
        least = min(least, z[4 + w])
    z[0], z[1], z[2], z[3] = X[i, 0], X[i, 1], X[i, 2], least
    return z[8], z[9], z[10], z[11]


@njit(cache=True)
def _heun(P, S, t, A, NA, hit, zones, wheel_reach, zcache, awake, na, mu, acc, h, out, k1, k2, tmp, inp, held):
    """Heun step from t of the awake vehicles awake[:na] (inputs at t and just before t + h: a step never
    straddles an action's time, and one ending there keeps its own law); a sleeping vehicle's row of
    `out` is left as it is (the caller keeps it equal to its row of S). inp[i]: vehicle i's driver inputs
    at t and the cosines and sines of its steer and heading (IN_*, set by the step policy); held[i]: how
    long they hold (driver_inputs.steady_next). The wheels' frictions: _wheel_frictions, then
    planar_vehicle.vehicle_forces_trig."""
    zoned = zones[2].shape[0] > 0
    # the two stages repeat the frictions and the force law's choice on purpose: a shared helper measured 2.5 %
    # (inline="always") to 18 % (a call) slower on populations, from the arrays' reference counts (2026-11-26)
    for a in range(na):
        i = awake[a]
        mode, brake = int(inp[i, IN_MODE]), inp[i, IN_BRAKE]
        cs, ss = inp[i, IN_COS_STEER], inp[i, IN_SIN_STEER]
        c, sn = inp[i, IN_COS_HEADING], inp[i, IN_SIN_HEADING]
        f0 = f1 = f2 = f3 = mu
        if zoned:
            f0, f1, f2, f3 = _wheel_frictions(P, S, i, c, sn, wheel_reach[i], mu, zones, zcache)
        if mode == LOCKED:  # (the load transfer solved: planar_vehicle.locked_forces)
            locked_forces(P[i], S[i], c, sn, f0, f1, f2, f3, acc[i], k1[i])
        else:
            vehicle_forces_trig(P[i], S[i], c, sn, f0, f1, f2, f3, mode, brake, cs, ss, acc[i], k1[i])
        for q in range(6):
            tmp[i, q] = S[i, q] + h * k1[i, q]
        if not (ahead(t, held[i]) and t + h <= held[i]):  # the step's own law at its end (left limit)
            mode, brake, steer = driver_inputs(A[i], NA[i], t + h, True)
            mode = effective_mode(mode, hit[i])
            if steer != inp[i, IN_STEER]:
                cs, ss = (math.cos(steer), math.sin(steer)) if steer != 0.0 else (1.0, 0.0)
        c, sn = math.cos(tmp[i, 2]), math.sin(tmp[i, 2])
        if zoned:
            f0, f1, f2, f3 = _wheel_frictions(P, tmp, i, c, sn, wheel_reach[i], mu, zones, zcache)
        if mode == LOCKED:
            locked_forces(P[i], tmp[i], c, sn, f0, f1, f2, f3, acc[i], k2[i])
        else:
            vehicle_forces_trig(P[i], tmp[i], c, sn, f0, f1, f2, f3, mode, brake, cs, ss, acc[i], k2[i])
        for q in range(6):
            out[i, q] = S[i, q] + 0.5 * h * (k1[i, q] + k2[i, q])


@njit(cache=True)
def _near_zone(S, i, reach, box):
    """Whether vehicle i's CG lies within `reach` of a zone's bounding box (its friction may change within
    the step)."""
    for z in range(box.shape[0]):
        if box[z, 0] - reach < S[i, 0] < box[z, 1] + reach and box[z, 2] - reach < S[i, 1] < box[z, 3] + reach:
            return True
    return False


STOP_MARGIN = 0.5  # m/s: long steps end this far above the speed a long step could brake away
SLIDE_TURN = 0.4  # rad: how far a wheel's slip velocity may turn within a sliding step


@njit(cache=True, inline="always")
def _straight(s, c, sn, steer):
    """Whether a vehicle in state s (heading cos, sin c, sn) runs straight: no yaw rate, side slip or steer."""
    return abs(s[5]) <= 1e-9 and abs(-sn * s[3] + c * s[4]) <= 1e-9 and steer == 0.0


@njit(cache=True)
def _long_step(p, s, c, sn, steer, mode, brake, mu, coarse_dt, slips):
    """The longest step (up to coarse_dt; 0: a fine one) of a vehicle in state s (heading cos, sin c, sn; steer
    angle `steer`; its planar_vehicle.wheel_slips `slips`) with the road's largest friction mu (docs/physics.md
    §2):
    * running straight (no yaw rate, side slip or steer): constant forces, which Heun integrates exactly; the step
      stays within the tyre modes' stability limit at the wheels' slip speeds (planar_vehicle.rate_of_slips over the
      step) so that round-off in them decays;
    * sliding on locked wheels: each wheel's force (mu N against its slip velocity) turns with that velocity,
      smoothly while the wheel slides fast: the step within which the slowest wheel's slip velocity can turn by
      SLIDE_TURN at most (wheel_slips: |dv| <= its change bound x the step);
    * else: 0;
    and never so long that the vehicle could stop within it (deceleration <= mu g, STOP_MARGIN kept: a long Heun
    step oscillates about v = 0 at Coulomb friction's discontinuity)."""
    room = math.hypot(s[3], s[4]) - STOP_MARGIN  # (the speed it may lose)
    if room <= 0.0:
        return 0.0
    h = coarse_dt if room >= 2.0 * mu * G * coarse_dt else room / (2.0 * mu * G)
    if _straight(s, c, sn, steer):
        rate = rate_of_slips(p, mu, mode, brake, slips, h)
        return min(h, 1.0 / rate) if rate > 0.0 else h
    if mode != LOCKED:
        return 0.0
    slip, _, change, _ = slips
    return min(h, SLIDE_TURN * slip / change) if change > 0.0 else h


@njit(cache=True)
def _gap_step(P, S, B, radius, i, k, nv, dv, oa, ob):
    """The step within which vehicle i and vehicle or barrier k cannot touch: half their gap over their closing
    speed. The gap between their bounding circles (closing: the centres' relative speed), or where those meet
    the outlines' separation along their separating axis n (geometry.penetration, a lower bound of the
    distance; closing: the centres' approach along n plus the corners' speeds about the centres, |r| radius);
    each vehicle's speed may change by dv within the step; 0 where they touch. oa, ob: scratch (4, 2)."""
    ckx, cky = _centre(S, B, k, nv)
    gap = math.hypot(S[i, 0] - ckx, S[i, 1] - cky) - radius[i] - radius[k]
    if k < nv:
        closing = math.hypot(S[i, 3] - S[k, 3], S[i, 4] - S[k, 4]) + 2.0 * dv
    else:
        closing = math.hypot(S[i, 3], S[i, 4]) + dv
    if gap <= 0.0:
        depth, nx, ny, _ = penetration(_outline(P, S, B, i, nv, oa), _outline(P, S, B, k, nv, ob))
        if depth >= 0.0:
            return 0.0
        gap = -depth  # along the separating axis n (from i to k): points approach at most at the centres'
        # approach along n plus the corners' speeds about the centres
        closing = (S[i, 3] * nx + S[i, 4] * ny) + abs(S[i, 5]) * radius[i] + dv
        if k < nv:
            closing += -(S[k, 3] * nx + S[k, 4] * ny) + abs(S[k, 5]) * radius[k] + dv
    return 0.5 * gap / closing if closing > 0.0 else math.inf
