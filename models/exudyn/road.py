"""Chassis-road contact: each chassis superellipsoid against the road plane z = 0 (numba, plain arrays).

Lowest point P of the chassis: the support point in the direction -z (superellipsoid.support_global, closed
form). Penetration delta = -P_z > 0; normal +z; delta_dot = -(velocity of P)_z.
Normal force (Hunt & Crossley 1975, "Coefficient of restitution interpreted as damping in vibroimpact",
J. Appl. Mech. 42:440-445, with its damping a material constant):
    F_N = K_v delta^n (1 + chi delta_dot / V_REF),  F_N >= 0
K_v = m_v g / DELTA_STATIC^n per vehicle: a vehicle resting on its roof or side sinks DELTA_STATIC = 1 cm into
the road (a roof holds 3x the vehicle's weight with <= 127 mm crush by FMVSS 216a; the road contact is a
support, not a crush model). chi = contact_force.exact_chi(E_ROAD) at V_REF: a body that hits the road at
V_REF = 3 m/s (a typical roof-to-ground speed in a rollover) rebounds with E_ROAD = 0.3; the damping does not
depend on the speed at onset, so a body at rest on the road is damped like any other (a law scaled with
the onset speed, as the car-to-car law, would turn a 1 mm/s touch into a stiff damper).
Friction: the road friction mu (the scene's) against the sliding velocity of P, regularised with the scene's
friction law (contact_force.friction_ratio_code), F_T = -mu c(|u_T|) F_N u_T / |u_T|.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from crashlab.models.multibody.contact import chassis_pose
from crashlab.models.multibody.contact_force import exact_chi, friction_ratio_code
from crashlab.models.multibody.superellipsoid import support_global

N_ROAD = 1.5  # Hertz exponent, as the chassis contact
DELTA_STATIC = 0.002  # m: static penetration under the vehicle's own weight
E_ROAD = 0.3  # restitution of a body hitting the road at V_REF
V_REF = 3.0  # m/s
G = 9.81
# per-vehicle outputs RSG[v]
R_ZMIN, R_DEL, R_DDOT, R_FN, R_POW = range(5)
N_RSG = 5


def stiffness(mass, n):
    """K_v [N/m^n] of vehicles of total mass `mass` (array)."""
    return np.asarray(mass, dtype=float) * G / DELTA_STATIC ** n


def road_chi():
    return exact_chi(E_ROAD)


@njit(cache=True)
def road_contacts(Y, nq, CSH, KR, n, chi_, mu, fcode, v0, v1, vs, FX, RSG):
    """Add the road contact of every chassis to FX[v] (global force, moment about the chassis CG, power),
    RSG[v] = (z of the lowest point, penetration, its rate, F_N, power of the contact force)."""
    nv = Y.shape[0]
    A = np.empty((3, 3))
    rc = np.empty(3)
    for v in range(nv):
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
        FX[v, 0] += F[0]
        FX[v, 1] += F[1]
        FX[v, 2] += F[2]
        FX[v, 3] += a[1] * F[2] - a[2] * F[1]
        FX[v, 4] += a[2] * F[0] - a[0] * F[2]
        FX[v, 5] += a[0] * F[1] - a[1] * F[0]
        p = F[0] * u[0] + F[1] * u[1] + F[2] * u[2]
        FX[v, 6] += p
        RSG[v, R_FN] = fn
        RSG[v, R_POW] = p
