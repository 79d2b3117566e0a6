"""Planar 3-DOF vehicle motion with four wheel contacts (docs/physics.md §2).

One implementation of the tyre/ground forces, compiled with numba, used by every planar model.
State per vehicle (global): x, y, heading psi, vx, vy, yaw rate r.
Parameters per vehicle: the P_* indices below (SI).
"""
import math

import numpy as np
from numba.extending import register_jitable

from crashlab.structure import STRUCTURE_SIDES, crush_zone
from crashlab.units import G

from .crush_structure import series_stiffness, side_code, structure_slot
from .driver_inputs import wheel_frictions
from .wheel_states import BRAKED, LOCKED, WHEEL_CODES

# vehicle parameter vector layout
P_MASS, P_IZ, P_A, P_B, P_TRACK, P_H, P_FRR, P_CALPHA, P_FRONT, P_REAR, P_HALFW, P_WHEELS, P_STEER = range(13)
# the crush structures' B [N/m^2] (P_STR_B) and crush zones [m] (P_STR_D) of the front, rear and side
# (crashlab.structure: STRUCTURE_SIDES, crush_zone), for an impact's crush capacity (engaged_capacity)
P_STR_B, P_STR_D = 13, 16
N_PARAMS = 19

V_REG = 0.05  # m/s: regularisation of Coulomb friction and rolling resistance near zero slip speed
V_LOW = 2.0  # m/s: floor of the longitudinal speed in the slip angle, keeps it defined near standstill


@register_jitable
def struck_side(p, x, y, heading, px, py):
    """The face of the vehicle (parameters p, CG at x, y, heading) a contact point (px, py) strikes: 0 front, 1
    rear, 2 left, 3 right (crush_structure.side_code on its outline rectangle; docs/physics.md §21)."""
    c, sn = math.cos(heading), math.sin(heading)
    dx, dy = px - x, py - y
    half = 0.5 * (p[P_FRONT] + p[P_REAR])
    return side_code(c * dx + sn * dy - (p[P_FRONT] - half), -sn * dx + c * dy, half, p[P_HALFW])


@register_jitable(inline="always")
def _derivative(s, c, sn, ax, ay, mz, iz, acc_body, out):
    """The state's time derivative into out from the CG acceleration (ax, ay) in body axes and the yaw moment mz
    (heading cos, sin c, sn); acc_body keeps (ax, ay) for the next evaluation's load transfer."""
    acc_body[0], acc_body[1] = ax, ay
    out[0], out[1], out[2] = s[3], s[4], s[5]
    out[3] = c * ax - sn * ay
    out[4] = sn * ax + c * ay
    out[5] = mz / iz


@register_jitable
def wheel_force(vwx, vwy, normal, mu, mode, brake, f_rr, c_alpha):
    """Force (Fx, Fy) of the road on one wheel, in the wheel frame, from its contact velocity.

    rolling: lateral force -mu N tanh(C_alpha alpha / (mu N)) (slip angle alpha, saturating at mu N) and the
    longitudinal force of the brake fraction `brake` of the friction left beside it, at least the rolling
    resistance f_rr N (docs/physics.md §2a); locked: Coulomb against the sliding velocity; braked (ABS-like):
    the lateral force of a rolling wheel and the friction left in the friction circle as braking force.
    """
    fmax = mu * normal
    if fmax <= 0.0:  # wheel off the ground, or a frictionless road (ice): no force
        return 0.0, 0.0
    if mode == LOCKED:
        s = math.sqrt(vwx * vwx + vwy * vwy + V_REG * V_REG)
        return -fmax * vwx / s, -fmax * vwy / s
    alpha = math.atan2(vwy, max(abs(vwx), V_LOW))
    x = c_alpha * alpha / fmax
    fy = -fmax * math.tanh(x)
    # the friction left beside fy, sqrt(fmax^2 - fy^2), as fmax / cosh(x): the difference of squares loses every
    # digit where fy saturates (docs/physics.md §2a); cosh's argument capped below its overflow
    left = fmax / math.cosh(min(abs(x), 700.0))
    if mode == BRAKED:
        return -left * math.tanh(vwx / V_REG), fy
    retard = f_rr * normal
    if brake > 0.0:
        retard = max(retard, brake * left)
    fx = -retard * math.tanh(vwx / V_REG)
    if abs(fx) + abs(fy) < fmax * (1.0 - 1e-12):  # inside the friction circle: hypot(fx, fy) <= |fx| + |fy|
        return fx, fy
    f = math.hypot(fx, fy)
    if f > fmax:
        return fx * fmax / f, fy * fmax / f
    return fx, fy


@register_jitable
def vehicle_motion(p, s, mu_road, mode, brake, steer, C, start, zmu, box, acc_body, out):
    """Time derivative of one vehicle's state s = (x, y, psi, vx, vy, r) into out[0:6], with the driver's
    wheel state `mode`, brake fraction and steer angle of this instant (common/driver_inputs.driver_inputs)
    and each wheel's road friction from the zones (C, start, zmu, box: driver_inputs.pack_zones; no zones:
    `mu_road` everywhere): driver_inputs.wheel_frictions, then vehicle_forces.

    acc_body = (ax, ay) of the previous evaluation, for quasi-static load transfer from the CG height;
    it is updated in place.
    """
    if zmu.shape[0] > 0:  # the friction where each wheel stands (§2a)
        f0, f1, f2, f3 = wheel_frictions(s[0], s[1], math.cos(s[2]), math.sin(s[2]), p[P_A], p[P_B],
                                         0.5 * p[P_TRACK], mu_road, C, start, zmu, box)
        vehicle_forces(p, s, f0, f1, f2, f3, mode, brake, steer, acc_body, out)
    else:
        vehicle_forces(p, s, mu_road, mu_road, mu_road, mu_road, mode, brake, steer, acc_body, out)


@register_jitable
def vehicle_forces(p, s, mu_fl, mu_fr, mu_rl, mu_rr, mode, brake, steer, acc_body, out):
    """vehicle_motion with the road friction at each wheel given (front left, front right, rear left, rear
    right). Scalars only beside the vehicle's rows: a compiled caller's hot loop passes no zone arrays
    (measured: the impulse kernel's Heun stage ~45 ns faster with it)."""
    cs, ss = (math.cos(steer), math.sin(steer)) if steer != 0.0 else (1.0, 0.0)
    vehicle_forces_trig(p, s, math.cos(s[2]), math.sin(s[2]), mu_fl, mu_fr, mu_rl, mu_rr, mode, brake, cs, ss,
                        acc_body, out)


@register_jitable
def vehicle_forces_trig(p, s, c, sn, mu_fl, mu_fr, mu_rl, mu_rr, mode, brake, cs, ss, acc_body, out):
    """vehicle_forces with the cosine and sine of the heading s[2] (c, sn) and of the steer angle (cs, ss;
    (1, 0) without steer) given: a caller that holds them saves the trigonometry (the impulse kernel)."""
    m, iz, a, b = p[P_MASS], p[P_IZ], p[P_A], p[P_B]
    track, h = p[P_TRACK], p[P_H]
    wb = a + b
    u = c * s[3] + sn * s[4]  # body-frame velocity
    v = -sn * s[3] + c * s[4]
    r = s[5]
    # axle loads with longitudinal transfer m a_x h / L, then lateral transfer m a_y h / track per side,
    # shared between the axles as the static loads (§2, pycrash style)
    nf = m * (G * b - acc_body[0] * h) / wb
    nr = m * (G * a + acc_body[0] * h) / wb
    dlat = m * acc_body[1] * h / track
    fx_t, fy_t, mz = 0.0, 0.0, 0.0
    for w in range(4):
        front = w < 2
        left = w % 2 == 0
        xw = a if front else -b
        yw = 0.5 * track if left else -0.5 * track
        nax = nf if front else nr
        share = b / wb if front else a / wb
        normal = 0.5 * nax + (-1.0 if left else 1.0) * dlat * share  # side transfer m a_y h / track
        mu = mu_fl if w == 0 else (mu_fr if w == 1 else (mu_rl if w == 2 else mu_rr))
        vx_w = u - r * yw
        vy_w = v + r * xw
        if front and ss != 0.0:  # a steer (sin of a nonzero angle is nonzero)
            wx = cs * vx_w + ss * vy_w
            wy = -ss * vx_w + cs * vy_w
            fx, fy = wheel_force(wx, wy, normal, mu, mode, brake, p[P_FRR], p[P_CALPHA])
            fx, fy = cs * fx - ss * fy, ss * fx + cs * fy
        else:
            fx, fy = wheel_force(vx_w, vy_w, normal, mu, mode, brake, p[P_FRR], p[P_CALPHA])
        fx_t += fx
        fy_t += fy
        mz += xw * fy - yw * fx
    _derivative(s, c, sn, fx_t / m, fy_t / m, mz, iz, acc_body, out)  # CG acceleration in body axes


@register_jitable
def vehicle_derivative(p, s, mu, mode, acc_body, out):
    """vehicle_motion with the start state's wheels and steer held and one road friction (scenes without
    actions or zones)."""
    vehicle_forces(p, s, mu, mu, mu, mu, mode, 1.0 if mode == BRAKED else 0.0, p[P_STEER], acc_body, out)


@register_jitable
def locked_forces(p, s, c, sn, mu_fl, mu_fr, mu_rl, mu_rr, acc_body, out):
    """vehicle_forces_trig for locked wheels with the quasi-static load transfer solved, not lagged
    (docs/physics.md §2): each wheel's Coulomb force is its load N times -mu v / sqrt(|v|^2 + V_REG^2)
    (wheel_force, any steer) and the loads are linear in the body acceleration (ax, ay), so m (ax, ay) =
    sum of N (ux, uy) is a 2 x 2 linear system. The previous evaluation's acceleration (vehicle_forces_trig)
    lags one Heun stage behind: an error first order in the step (the side collision's rest heading moved
    0.09 deg per ms of step). acc_body gets the solved acceleration; where a solved load would lift a wheel
    (|a| beyond about g track / 2h) this is vehicle_forces_trig with the lagged loads."""
    m, iz, a, b, track, h = p[P_MASS], p[P_IZ], p[P_A], p[P_B], p[P_TRACK], p[P_H]
    wb = a + b
    u = c * s[3] + sn * s[4]
    v = -sn * s[3] + c * s[4]
    r = s[5]
    # the load of wheel w: n0 + kx ax + ky ay (vehicle_forces_trig's transfer), its force that times (ux, uy):
    # m (ax, ay) = (bx, by) + S (ax, ay), and the yaw moment mz = z0 + zx ax + zy ay. Each axle's left and
    # right wheel are added first: a reflected scene (left and right swapped) gives the same bits, mirrored.
    bx, by, sxx, sxy, syx, syy, z0, zx, zy = 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    yw = 0.5 * track
    for axle in range(2):
        front = axle == 0
        xw = a if front else -b
        share = b / wb if front else a / wb
        n0 = 0.5 * m * G * share
        kx = (-0.5 if front else 0.5) * m * h / wb
        ky = m * h / track * share  # (the left wheel's: -ky)
        mu_l, mu_r = (mu_fl, mu_fr) if front else (mu_rl, mu_rr)
        vx_l, vx_r, vy_w = u - r * yw, u + r * yw, v + r * xw
        q_l = -mu_l / math.sqrt(vx_l * vx_l + vy_w * vy_w + V_REG * V_REG)
        q_r = -mu_r / math.sqrt(vx_r * vx_r + vy_w * vy_w + V_REG * V_REG)
        ux_l, uy_l, ux_r, uy_r = q_l * vx_l, q_l * vy_w, q_r * vx_r, q_r * vy_w
        m_l, m_r = xw * uy_l - yw * ux_l, xw * uy_r + yw * ux_r
        bx, by, z0 = bx + n0 * (ux_l + ux_r), by + n0 * (uy_l + uy_r), z0 + n0 * (m_l + m_r)
        sxx, syx, zx = sxx + kx * (ux_l + ux_r), syx + kx * (uy_l + uy_r), zx + kx * (m_l + m_r)
        sxy, syy, zy = sxy + ky * (ux_r - ux_l), syy + ky * (uy_r - uy_l), zy + ky * (m_r - m_l)
    det = (m - sxx) * (m - syy) - sxy * syx
    ax = (bx * (m - syy) + sxy * by) / det
    ay = ((m - sxx) * by + syx * bx) / det
    dlat = abs(ay) * h / track  # the side transfer per unit mass; a wheel lifts where its load would be <= 0
    if G * b - ax * h <= 2.0 * dlat * b or G * a + ax * h <= 2.0 * dlat * a:
        vehicle_forces_trig(p, s, c, sn, mu_fl, mu_fr, mu_rl, mu_rr, LOCKED, 0.0, 1.0, 0.0, acc_body, out)
        return
    _derivative(s, c, sn, ax, ay, z0 + zx * ax + zy * ay, iz, acc_body, out)


@register_jitable
def wheel_slips(p, s, c, sn, cs, ss, mu):
    """The slowest wheel of a vehicle in state s (heading cos, sin c, sn; steer cos, sin cs, ss; the road's
    largest friction mu): (its slip speed [m/s], the least |longitudinal speed| of a wheel in its own frame,
    a bound of how fast a wheel's slip speed changes [m/s^2], the same for the longitudinal speed). The road's
    forces total at most mu m g and their moment mu m g rho (rho the farthest wheel's distance from the CG),
    so a wheel's velocity changes at most at mu g (1 + m rho^2 / Iz) + r^2 rho; its components in the turning
    vehicle's frame also by |r| |v_w|."""
    m, iz, a, b, track = p[P_MASS], p[P_IZ], p[P_A], p[P_B], p[P_TRACK]
    u = c * s[3] + sn * s[4]  # body-frame velocity
    v = -sn * s[3] + c * s[4]
    r = s[5]
    rho2 = max(a, b) ** 2 + 0.25 * track * track
    change = mu * G * (1.0 + m * rho2 / iz) + r * r * math.sqrt(rho2)
    slip, along, fastest = math.inf, math.inf, 0.0
    for w in range(4):
        xw = a if w < 2 else -b
        yw = 0.5 * track if w % 2 == 0 else -0.5 * track
        vx_w, vy_w = u - r * yw, v + r * xw
        speed = math.sqrt(vx_w * vx_w + vy_w * vy_w)
        if w < 2 and ss != 0.0:
            vx_w = cs * vx_w + ss * vy_w
        slip, along, fastest = min(slip, speed), min(along, abs(vx_w)), max(fastest, speed)
    return slip, along, change, change + abs(r) * fastest


@register_jitable
def rate_of_slips(p, mu, mode, brake, slips, dt):
    """Largest decay rate [1/s] of the regularised tyre forces (lateral and yaw modes) of one vehicle with the
    wheel_slips `slips` (wheel state `mode`, brake fraction `brake`, the road's largest friction mu) over a step
    of at most dt: an explicit step must stay below about 1 / rate (Heun is stable up to 2 / rate). Each
    regularised force's stiffness at the slowest wheel's own slip speed, the speed it can lose within dt taken
    off first (docs/physics.md §2): a locked wheel's Coulomb force is stiff (mu N / sqrt(|v|^2 + V_REG^2)) only
    near standstill, a braked wheel's (mu N / V_REG / cosh^2(v_x / V_REG)) only near v_x = 0, a rolling tyre's
    (C_alpha / max(|v_x|, V_LOW)) only slower than a few m/s. At zero slip speed: the worst case, e.g. 1 / 3.6
    ms for the Clio locked."""
    m, iz, a, b, track = p[P_MASS], p[P_IZ], p[P_A], p[P_B], p[P_TRACK]
    slip, along, change, change_along = slips
    slip, along = max(slip - change * dt, 0.0), max(along - change_along * dt, 0.0)
    if mode == LOCKED:
        rho2 = 0.5 * (a * a + b * b) + 0.25 * track * track
        return mu * G / math.sqrt(slip * slip + V_REG * V_REG) * max(1.0, m * rho2 / iz)
    c_alpha = p[P_CALPHA]
    x = max(along, V_LOW)
    rate = max(4.0 * c_alpha / (m * x), 2.0 * c_alpha * (a * a + b * b) / (iz * x))
    if mode == BRAKED or brake > 0.0:
        rate = max(rate, mu * G / V_REG / math.cosh(min(along / V_REG, 300.0)) ** 2)
    return rate


def pack_vehicle(spec, wheels: str, steer: float) -> np.ndarray:
    """The parameter vector of one vehicle (SI)."""
    p = np.empty(N_PARAMS)
    p[P_MASS], p[P_IZ] = spec.mass, spec.yaw_inertia
    p[P_A], p[P_B], p[P_TRACK], p[P_H] = spec.cg_to_front_axle, spec.cg_to_rear_axle, spec.track, spec.cg_height
    p[P_FRR], p[P_CALPHA] = spec.rolling_resistance, spec.cornering_stiffness
    p[P_FRONT], p[P_REAR], p[P_HALFW] = spec.cg_to_front, spec.cg_to_rear, spec.width / 2
    p[P_WHEELS], p[P_STEER] = WHEEL_CODES[wheels], steer
    for k, side in enumerate(STRUCTURE_SIDES):
        p[P_STR_B + k] = spec.structure[side].B
        p[P_STR_D + k] = crush_zone(spec, "left" if side == "side" else side)[0]
    return p


@register_jitable
def _extent(x, y, heading, front, rear, halfw, tx, ty):
    """The interval a rectangle (centre x, y, heading; reaching `front` ahead, `rear` behind, `halfw` to either side
    of it) covers along (tx, ty)."""
    c, sn = math.cos(heading), math.sin(heading)
    lo, hi = math.inf, -math.inf
    for u in (front, -rear):
        for v in (halfw, -halfw):
            a = (x + u * c - v * sn) * tx + (y + u * sn + v * c) * ty
            lo, hi = min(lo, a), max(hi, a)
    return lo, hi


@register_jitable
def engaged_capacity(pi, si, fi, pj, sj, fj, bar, tx, ty):
    """The engaged width [m] of an impact, the overlap of the two outline rectangles (parameters p, states s: x,
    y, heading; for a barrier, bar its row x, y, heading, half length, half width, else empty) along the contact
    plane's tangent (tx, ty), and the energy [J]
    the struck structures (faces fi, fj: struck_side's codes) absorb over it before the first is crushed through
    its crush zone D: in series they carry the same force per width f (CRASH3's line through zero force, f = B C,
    docs/physics.md §13a), so f reaches min(B D) and each absorbs f^2 / 2B per width (a rigid barrier nothing;
    docs/physics.md §4 "Engaged width")."""
    barrier = bar.shape[0] > 0
    lo_i, hi_i = _extent(si[0], si[1], si[2], pi[P_FRONT], pi[P_REAR], pi[P_HALFW], tx, ty)
    if barrier:
        lo_j, hi_j = _extent(bar[0], bar[1], bar[2], bar[3], bar[3], bar[4], tx, ty)
    else:
        lo_j, hi_j = _extent(sj[0], sj[1], sj[2], pj[P_FRONT], pj[P_REAR], pj[P_HALFW], tx, ty)
    width = max(0.0, min(hi_i, hi_j) - max(lo_i, lo_j))
    ki, kj = structure_slot(int(fi)), structure_slot(int(fj))
    bi, bj = pi[P_STR_B + ki], 0.0 if barrier else pj[P_STR_B + kj]
    f = bi * pi[P_STR_D + ki] if barrier else min(bi * pi[P_STR_D + ki], bj * pj[P_STR_D + kj])
    return width, width * f * f / (2.0 * series_stiffness(bi, bj))  # f^2/2B1 + f^2/2B2 (a rigid barrier B2 <= 0)
