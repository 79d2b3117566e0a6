"""Tyre/ground forces for the pymunk model: a compiled loop over the vehicles that calls the one
implementation of the planar wheel forces (crashlab.models.common.planar_vehicle.vehicle_derivative)
and turns its accelerations into the force [N, global] and yaw moment [N m] applied to each body.
"""
import numpy as np
from numba import njit

from crashlab.models.common.planar_vehicle import P_IZ, P_MASS, vehicle_derivative


@njit(cache=True)
def ground_forces(P, S, modes, awake, mu, acc, F):
    """F[i] = (Fx, Fy, Mz) of the road on vehicle i in state S[i] = (x, y, psi, vx, vy, r); zero for a
    vehicle at rest. acc (nv, 2) carries the body-frame CG acceleration for load transfer (in place)."""
    out = np.empty(6)
    for i in range(S.shape[0]):
        if not awake[i]:
            F[i, 0], F[i, 1], F[i, 2] = 0.0, 0.0, 0.0
            continue
        vehicle_derivative(P[i], S[i], mu, modes[i], acc[i], out)
        # Newton-Euler: F = m a, Mz = Iz r' (vehicle_derivative returns a = F / m, r' = Mz / Iz)
        F[i, 0] = P[i, P_MASS] * out[3]
        F[i, 1] = P[i, P_MASS] * out[4]
        F[i, 2] = P[i, P_IZ] * out[5]
