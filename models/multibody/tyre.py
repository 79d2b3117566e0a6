"""University of Arizona (UA) tyre, Gim & Nikravesh (1990/91), as docs/physics.md §9, with the smoothing
and the transient-slip states described in README.md.

Per wheel: torus geometry (r1 = radius of the carcass-centre circle, r2 = carcass radius), flat road
z = 0 with normal k. State per wheel: the transient slips (s, a) = (longitudinal slip ratio, tangent of
the lateral slip angle), relaxing towards the UA slips with relaxation lengths sigma_s, sigma_a:

    sigma_s ds/dt = V_sx - V_ref s        sigma_a da/dt = V_y - V_ref a,   V_ref = max(|V_x|, |V_c|)

whose steady states are exactly the UA definitions in braking (V_sx/V_x, V_y/V_x) and traction
(V_sx/V_c, (1-S) tan(alpha) = V_y/V_c) (§9). With V_ref in the relaxation rate instead of a divisor there
is no singularity at standstill (§9): there the states are tread deflections (springs K/sigma).

Camber: an equivalent lateral slip in the same state, fed by the rolling speed,
    sigma_a da/dt = V_y + (K_g/K_a) sin(gamma) |V_c| - V_ref a,
so a free-rolling wheel's steady state is tan(alpha) + (K_g/K_a) sin(gamma) (the usual equivalent slip) and a
wheel at standstill or locked gets no camber thrust (before issue 10 the camber slip was added statically:
a tilted car at rest was pushed sideways by mu F_z and accelerated without any contact).
Forces (§9, comprehensive slip, brush form): X = K_s s, Y = K_a a_eq (a_eq = a, camber included),
S_c = |(X, Y)|, l_n = max(0, 1 - S_c/(3 mu F_z)),
    F = (X, Y) l_n^2 + mu F_z e_slide (1 - 3 l_n^2 + 2 l_n^3),  e_slide = (s, a_eq)/|(s, a_eq)|
i.e. the adhesion part follows the stiffness-weighted slip and the sliding part the sliding-velocity
direction (for a locked wheel F = mu F_z against the sliding velocity). The law is C1 across the
adhesion/sliding boundary, so the UA case switches (I/II/III, adhesion/sliding) never jump.
Tread damping C_s sigma_s ds/dt, C_a sigma_a da/dt (zero in steady state) is added to the adhesion part
of a state within full sliding (S_c <= 3 mu F_z) and fades out beyond it (over SAT_BAND): a fully sliding
tread is Coulomb friction against the sliding direction (issue 10).
Self-aligning torque T_z = (l/6) Y l_n^3, contact length l = sqrt(8 R delta).
Rolling resistance and the braked wheel's (ABS-like) brake torque eta mu F_z R_e: common/tyre_moments.py.
Parameter rows: common/vehicle_3d.py (T_*), built there from the vehicle file.
"""
import math

from numba import njit

from crashlab.models.common.rotations import add, cross, dot, mtv, mv, scale, sub
from crashlab.models.common.tyre_moments import brake_moment, rolling_resistance_moment
from crashlab.models.common.vehicle_3d import (
    T_CA,
    T_CS,
    T_CZ,
    T_ETA,
    T_FRR,
    T_KA,
    T_KG,
    T_KNUCKLE,
    T_KS,
    T_KZ,
    T_MODE,
    T_R1,
    T_R2,
    T_SIG_A,
    T_SIG_S,
    T_WHEEL,
)
from crashlab.models.common.wheel_states import BRAKED, ROLLING

V_EPS = 0.01        # m/s: smooths V_ref = max(|V_x|, |V_c|) at standstill
DELTA_RAMP = 1e-3   # m: radial damping fades in over the first mm of deflection (no jump at touchdown)
TAU_AIR = 0.01      # s: relaxation of the slip states (tread deflection) of a wheel off the road
V_BRAKE = 0.05      # m/s: the brake-fraction force reaches its full value above this speed (tanh)
SAT_BAND = 0.05     # the tread damping fades out over this fraction beyond full sliding (S_c > 3 mu F_z)
SAT_GROW = 0.25     # the slip states stop growing once S_c exceeds 3 mu F_z by this fraction (issue 25)


@njit(cache=True)
def deflection(Tw, A, R):
    """(delta, C, w): tyre deflection, carcass-circle centre below the hub, spin axis (global)."""
    bw = int(Tw[T_WHEEL])
    w = mv(A, bw, (0.0, 1.0, 0.0))
    kz = w[2]
    t = (-kz * w[0], -kz * w[1], 1.0 - kz * w[2])
    nt = math.sqrt(dot(t, t))
    if nt < 1e-9:
        return -1.0, (R[bw, 0], R[bw, 1], R[bw, 2]), w
    C = add((R[bw, 0], R[bw, 1], R[bw, 2]), scale(-Tw[T_R1] / nt, t))
    return Tw[T_R2] - C[2], C, w


@njit(cache=True)
def tyre(Tw, A, R, V, W, Q, s, a, mu, friction_on, damping_on, dslip, brake=0.0):
    """Adds the road's force on one wheel (and a brake's torque on wheel and knuckle) to Q; writes the
    slip-state derivatives into dslip[0:2]; returns (F_z, power of the non-conservative parts).
    brake: the driver's brake fraction b of a rolling wheel (docs/physics.md §2a; README "Driver actions")."""
    bw, bk = int(Tw[T_WHEEL]), int(Tw[T_KNUCKLE])
    delta, C, w = deflection(Tw, A, R)
    c = (R[bw, 0], R[bw, 1], R[bw, 2])
    vw = (V[bw, 0], V[bw, 1], V[bw, 2])
    om = mv(A, bw, (W[bw, 0], W[bw, 1], W[bw, 2]))
    spin = dot(om, w)
    hx = math.sqrt(w[0] * w[0] + w[1] * w[1])
    xc = (w[1] / hx, -w[0] / hx, 0.0)        # heading: w x k
    yc = (-xc[1], xc[0], 0.0)                # k x heading
    vx, vy = dot(vw, xc), dot(vw, yc)
    Rfree = Tw[T_R1] + Tw[T_R2]
    Re = Rfree - max(delta, 0.0) / 3.0       # effective rolling radius [U]
    vc = spin * Re
    vsx = vx - vc
    vref = math.sqrt(max(vx * vx, vc * vc) + V_EPS * V_EPS)
    ds = (vsx - vref * s) / Tw[T_SIG_S]
    # camber thrust as an equivalent lateral slip fed by the rolling speed |V_c| (the tread is carried
    # through the tilted contact patch only while the wheel rolls): steady state a = tan(alpha) +
    # (K_g/K_a) sin(gamma) for a free-rolling wheel (V_c = V_x), nothing at standstill or when locked
    da = (vy + Tw[T_KG] / Tw[T_KA] * w[2] * abs(vc) - vref * a) / Tw[T_SIG_A]
    if delta <= 0.0:
        # off the road the tread deflection springs back (time TAU_AIR): before issue 10 the states kept
        # integrating V/V_ref in the air, unsaturated, and a tumbling car landed on a wheel whose state
        # pointed against its sliding velocity (mu F_z driving it: +1.7 MW, +100 kJ in stress scene 1:5)
        dslip[0], dslip[1] = -s / TAU_AIR, -a / TAU_AIR
        return 0.0, 0.0
    # normal force (§9): elastic + radial damping faded in over DELTA_RAMP
    arm = sub(C, c)
    vC = add(vw, cross(om, arm))
    ddelta = -vC[2]
    fz = Tw[T_KZ] * delta + damping_on * Tw[T_CZ] * ddelta * min(1.0, delta / DELTA_RAMP)
    fz = max(fz, 0.0)
    ks, ka = Tw[T_KS], Tw[T_KA]
    fmax = mu * fz * friction_on
    # saturation: the tread deflection cannot grow beyond full sliding (keeps the direction); the band SAT_GROW
    # sets how stiff this stop is (1.5 / SAT_GROW x the direction's relaxation; README "Tyre", issue 25)
    X, Y = ks * s, ka * a
    sc = math.sqrt(X * X + Y * Y)
    lim = 3.0 * fmax
    if sc > lim and sc > 0.0:
        z = 1.0 if lim <= 0.0 else min(1.0, (sc / lim - 1.0) / SAT_GROW)
        f = z * z * (3.0 - 2.0 * z)
        rd = (X * ks * ds + Y * ka * da) / sc
        if rd > 0.0:
            ds -= f * rd * (X / sc) / ks
            da -= f * rd * (Y / sc) / ka
    if friction_on == 0.0 or mu <= 0.0:
        # no in-plane tyre forces (also on ice, road friction 0): the slip states act on nothing and are
        # frozen (their saturated dynamics at fmax = 0 only chatter and throttle the step size)
        ds, da = 0.0, 0.0
    dslip[0], dslip[1] = ds, da
    # comprehensive-slip brush law (§9)
    aeq = a                                  # camber is already in the state (see da above)
    X, Y = ks * s, ka * aeq
    sc = math.sqrt(X * X + Y * Y)
    fxi, feta, tz = 0.0, 0.0, 0.0
    if sc > 1e-12 and fmax > 0.0:
        ln = max(0.0, 1.0 - sc / (3.0 * fmax))
        m = math.sqrt(s * s + aeq * aeq)
        slide = fmax * (1.0 - 3.0 * ln * ln + 2.0 * ln * ln * ln) / m
        fxi = X * ln * ln + slide * s
        feta = Y * ln * ln + slide * aeq
        tz = math.sqrt(8.0 * Rfree * delta) / 6.0 * Y * ln * ln * ln
    # tread damping damps the elastic tread deflection; a state beyond full sliding (S_c > 3 mu F_z) is no
    # deflection any more (the whole patch slides, the force is Coulomb friction against the sliding
    # direction), so the damping fades out over SAT_BAND there. Before, a locked wheel's state far
    # beyond saturation relaxing at V_ref/sigma gave a damping force far above mu F_z along the sliding
    # velocity (issue 10: a spinning car on locked wheels gained +70 kJ without contact, +120 kW per wheel)
    cd = damping_on * friction_on
    if sc > 3.0 * fmax:
        z = 1.0 if fmax <= 0.0 else min(1.0, (sc / (3.0 * fmax) - 1.0) / SAT_BAND)
        cd *= 1.0 - z * z * (3.0 - 2.0 * z)
    fx = -fxi - cd * Tw[T_CS] * Tw[T_SIG_S] * ds
    fy = -feta - cd * Tw[T_CA] * Tw[T_SIG_A] * da
    # brake fraction b of a rolling wheel (§2a): the brake regulates the tyre's longitudinal force to
    # b sqrt((mu F_z)^2 - F_y^2) (rolling resistance its floor): the part the slip law does not already give
    # (fxi, the force of the wheel's own longitudinal slip, which decelerates the wheel's spin) is applied at
    # the contact point with the brake torque that keeps the wheel's spin free of it (below); both fade out
    # below V_BRAKE, where the tread's own force holds the stopped car
    fb = 0.0
    if brake > 0.0 and int(Tw[T_MODE]) == ROLLING and fmax > 0.0:
        left = math.sqrt(max(fmax * fmax - feta * feta, 0.0))
        th = math.tanh(vx / V_BRAKE)
        fb = max(brake * left - Tw[T_FRR] * fz * friction_on, 0.0) * th - fxi * abs(th)
        fx -= fb
    fh = math.sqrt(fx * fx + fy * fy)
    if fh > fmax:
        r = fmax / fh if fh > 0.0 else 0.0
        fx *= r
        fy *= r
        fb *= r
    F = (fx * xc[0] + fy * yc[0], fx * xc[1] + fy * yc[1], fz)
    P = (C[0], C[1], 0.0)
    sP = sub(P, c)
    # forces and moments on the wheel body
    Q[bw, 0] += F[0]
    Q[bw, 1] += F[1]
    Q[bw, 2] += F[2]
    # rolling resistance: moment f_r F_z h (h = hub-to-contact distance), i.e. a resistance force f_r F_z
    myr = friction_on * rolling_resistance_moment(Tw[T_FRR], fz, math.sqrt(dot(sP, sP)), spin)
    Tg = add(cross(sP, F), add((0.0, 0.0, tz), scale(myr, w)))
    n = mtv(A, bw, Tg)
    Q[bw, 3] += n[0]
    Q[bw, 4] += n[1]
    Q[bw, 5] += n[2]
    vP = add(vw, cross(om, sP))
    power = dot(F, vP) + tz * om[2] + myr * spin - Tw[T_KZ] * delta * vP[2]
    if fb != 0.0:
        # the brake torque between wheel and knuckle that cancels the brake force's moment about the spin axis
        Fb = (-fb * xc[0], -fb * xc[1], 0.0)
        power += _wheel_torque(Q, A, W, bw, bk, w, spin, -dot(cross(sP, Fb), w))
    if int(Tw[T_MODE]) == BRAKED:
        rel = spin - dot(mv(A, bk, (W[bk, 0], W[bk, 1], W[bk, 2])), w)
        power += _wheel_torque(Q, A, W, bw, bk, w, spin, friction_on * brake_moment(Tw[T_ETA], mu, fz, Re, rel))
    return fz, power


@njit(cache=True)
def _wheel_torque(Q, A, W, bw, bk, w, spin, tb):
    """A torque tb about the spin axis w between wheel bw and knuckle bk (body frames into Q); returns its
    power on the wheel's spin relative to the knuckle."""
    rel = spin - dot(mv(A, bk, (W[bk, 0], W[bk, 1], W[bk, 2])), w)
    nb = mtv(A, bw, scale(tb, w))
    nk = mtv(A, bk, scale(-tb, w))
    for k in range(3):
        Q[bw, 3 + k] += nb[k]
        Q[bk, 3 + k] += nk[k]
    return tb * rel


def tyres_for(veh, modes):
    """The vehicle's tyre rows with the wheel modes (per wheel, wheel_states.WHEEL_CODES codes) set."""
    T = veh.TYR.copy()
    T[:, T_MODE] = modes
    return T
