"""Tyre/ground forces for the pymunk model: a compiled loop over the vehicles that calls the one
implementation of the planar wheel forces (crashlab.models.common.planar_vehicle.vehicle_motion), with the
driver's inputs of the instant and the zones' friction (crashlab.models.common.driver_inputs), and turns its
accelerations into the force [N, global] and yaw moment [N m] applied to each body.
"""
import numpy as np
from numba import njit

from crashlab.models.common.driver_inputs import driver_inputs, effective_mode
from crashlab.models.common.planar_vehicle import P_IZ, P_MASS, vehicle_motion


@njit(cache=True)
def ground_forces(P, S, t, A, n_actions, struck, awake, mu, C, start, zmu, box, acc, F):
    """F[i] = (Fx, Fy, Mz) of the road on vehicle i in state S[i] = (x, y, psi, vx, vy, r) at time t; zero
    for a vehicle at rest. A, n_actions: the action tables (driver_inputs.pack_action_tables); struck[i]: the
    vehicle has been hit (locked_after_impact); C, start, zmu, box: the zones (driver_inputs.pack_zones).
    acc (nv, 2) carries the body-frame CG acceleration for load transfer (in place)."""
    out = np.empty(6)
    for i in range(S.shape[0]):
        if not awake[i]:
            F[i, 0], F[i, 1], F[i, 2] = 0.0, 0.0, 0.0
            continue
        mode, brake, steer = driver_inputs(A[i], n_actions[i], t)
        vehicle_motion(P[i], S[i], mu, effective_mode(mode, struck[i]), brake, steer, C, start, zmu, box,
                       acc[i], out)
        # Newton-Euler: F = m a, Mz = Iz r' (vehicle_motion returns a = F / m, r' = Mz / Iz)
        F[i, 0] = P[i, P_MASS] * out[3]
        F[i, 1] = P[i, P_MASS] * out[4]
        F[i, 2] = P[i, P_IZ] * out[5]
