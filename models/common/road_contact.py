"""Chassis-road contact: each chassis superellipsoid (the chassis-chassis contact geometry) against the road
plane z = 0 (issue 10: a rolled-over car used to sink through the road and keep sliding). numba, plain
arrays, no state: the multibody integrator and the exudyn model call the same function.

    road_contacts(Y, nq, CSH, KR, n, chi_, mu, fcode, v0, v1, vs, FX, RSG, awake)

Y (nv, >= nq + 6): per vehicle the chassis state in the multibody layout (r at [0:3], Euler parameters at
[3:7], r_dot at [nq:nq+3], body-fixed w' at [nq+3:nq+6]; nq = 7 * bodies, 7 for a chassis-only array);
CSH (nv, 7) the chassis superellipsoids [a, b, c, eps1, eps2, x_off, z_off] (vehicle_3d.chassis_shape);
KR (nv,) stiffness [N/m^n] (`stiffness`); n exponent; chi_ hysteresis factor (`road_chi`); mu the road's
friction; fcode the friction law code (contact_force: 0 coulomb, 1 threlfall, 2 ambrosio) with its
tolerances v0, v1, vs [m/s]. ADDS the road's load to FX[v] (global force [0:3], global moment about the
chassis CG [3:6], power [6]) and writes RSG[v] = (z of the lowest point, penetration, penetration rate,
F_N, power) (R_* columns).

Lowest point P of the chassis: the support point in the direction -z (closed form). Penetration
delta = -P_z > 0, normal +z, delta_dot = -(velocity of P)_z.
Normal force (Hunt & Crossley 1975, "Coefficient of restitution interpreted as damping in vibroimpact",
J. Appl. Mech. 42:440-445, damping a material constant):
    F_N = K_v delta^n (1 + chi delta_dot / V_REF),  F_N >= 0
K_v = m_v g / DELTA_STATIC^n: a vehicle resting on its roof or side sinks DELTA_STATIC = 5 mm into the road.
Why not the vehicle-barrier stiffness (1.35e6 N/m^1.5, a crush-zone value): a 3,000 kg car would rest 8 cm
deep in the road and land from a roll 10-15 cm deep; the road contact is a support, not a crush model (the
physics guard fails a body 5 cm below the road on average over 0.1 s, or 10 cm at any moment: docs/physics.md
§19). Landing
after a roll (a third of the mass at the touching corner, vertical speed v): delta_max = (1.25 v^2
DELTA_STATIC^1.5 / (3 g))^0.4, 5 cm at 6 m/s, 10 cm at 15 m/s (1 cm static would allow 4 m/s only for 5 cm:
the rollovers of the tests touched down at 3-4 m/s and reached 4.6-4.9 cm).
chi = contact_force.exact_chi(E_ROAD): a body hitting the road at
V_REF = 3 m/s (a typical roof-to-ground speed in a rollover) rebounds with E_ROAD = 0.3; the damping does not
scale with the speed at onset (a law scaled with the onset speed, as the car-to-car law, would turn a
1 mm/s touch of a resting body into a stiff damper).
Friction: the road friction mu against the sliding velocity of P, F_T = -mu c(|u_T|) F_N u_T/|u_T|
(the multibody model: regularised Coulomb, v_s = 0.01 m/s, as its vehicle contacts).
Patch moment: a roof or side lying on the road touches it over a patch, not a point: turning the body on it
(spin about the normal, or rocking) slides or crushes the patch. M = -mu F_N RHO_PATCH c(|w| RHO_PATCH)
w/|w| (w the chassis' angular velocity), always dissipative. RHO_PATCH = 0.1 m, a conservative patch radius
(the superellipsoid's flat top cut 1 cm deep is ~1.7 m x 0.7 m). Without it a point contact has no spin
friction and the quartic (flat) pole no rocking stiffness: an upside-down car wobbled at 1-3 cm/s for
seconds instead of coming to rest.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from crashlab.units import G

from .chassis_contact import chassis_pose
from .contact_force import exact_chi, friction_ratio_code
from .superellipsoid import support_global

N_ROAD = 1.5          # Hertz exponent, as the chassis contact
DELTA_STATIC = 0.005  # m: static penetration under the vehicle's own weight
E_ROAD = 0.3          # restitution of a body hitting the road at V_REF
V_REF = 3.0           # m/s
RHO_PATCH = 0.1       # m, radius of the patch moment
ROAD_FRICTION_LAW = 0  # contact_force.friction_ratio_code: regularised Coulomb
# per-vehicle outputs RSG[v]
R_ZMIN, R_DEL, R_DDOT, R_FN, R_POW = range(5)
N_RSG = 5


def stiffness(mass, n=N_ROAD):
    """K_v [N/m^n] of vehicles of total mass `mass` (array)."""
    return np.asarray(mass, dtype=float) * G / DELTA_STATIC ** n


def road_chi():
    return exact_chi(E_ROAD)


@njit(cache=True)
def road_contacts(Y, nq, CSH, KR, n, chi_, mu, fcode, v0, v1, vs, FX, RSG, awake):
    """Add the road contact of every chassis to FX[v]; RSG[v] = (z_min, delta, delta_dot, F_N, power). awake (nv,)
    bool: a sleeping vehicle is skipped, its RSG[v] kept (multibody: its state does not change; 30 parked cars
    cost 2.8 x the run of two without it); an empty array: every vehicle."""
    nv = Y.shape[0]
    use_awake = awake.shape[0] > 0
    A = np.empty((3, 3))
    rc = np.empty(3)
    for v in range(nv):
        if use_awake and not awake[v]:
            continue
        r, vel, om = chassis_pose(Y[v], nq, A)
        sh = CSH[v]
        for k in range(3):
            rc[k] = r[k] + A[k, 0] * sh[5] + A[k, 2] * sh[6]
        P = support_global(0.0, 0.0, -1.0, sh, rc, A)
        RSG[v, :] = 0.0
        RSG[v, R_ZMIN] = P[2]
        a = (P[0] - r[0], P[1] - r[1], P[2] - r[2])
        u = (vel[0] + om[1] * a[2] - om[2] * a[1], vel[1] + om[2] * a[0] - om[0] * a[2],
             vel[2] + om[0] * a[1] - om[1] * a[0])
        d = -P[2]
        dd = -u[2]
        RSG[v, R_DEL] = d
        RSG[v, R_DDOT] = dd
        if d <= 0.0:
            continue
        fn = KR[v] * d ** n * (1.0 + chi_ * dd / V_REF)
        if fn <= 0.0:
            continue
        st = math.sqrt(u[0] * u[0] + u[1] * u[1])
        c = 0.0
        if st > 0.0 and mu > 0.0:
            c = mu * friction_ratio_code(fcode, st, v0, v1, vs) * fn / st
        F = (-c * u[0], -c * u[1], fn)
        # patch moment against the chassis' rotation
        wn = math.sqrt(om[0] * om[0] + om[1] * om[1] + om[2] * om[2])
        cm = 0.0
        if wn > 0.0 and mu > 0.0:
            cm = mu * friction_ratio_code(fcode, wn * RHO_PATCH, v0, v1, vs) * fn * RHO_PATCH / wn
        FX[v, 0] += F[0]
        FX[v, 1] += F[1]
        FX[v, 2] += F[2]
        FX[v, 3] += a[1] * F[2] - a[2] * F[1] - cm * om[0]
        FX[v, 4] += a[2] * F[0] - a[0] * F[2] - cm * om[1]
        FX[v, 5] += a[0] * F[1] - a[1] * F[0] - cm * om[2]
        p = F[0] * u[0] + F[1] * u[1] + F[2] * u[2] - cm * wn * wn
        FX[v, 6] += p
        RSG[v, R_FN] = fn
        RSG[v, R_POW] = p
