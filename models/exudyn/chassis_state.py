"""The chassis states the shared contact code needs (common/chassis_contact.py, road_contact.py), read from
exudyn's coordinate vectors in one compiled pass (issue 25): two exudyn calls per evaluation instead of four
node outputs per vehicle and a Python Shepperd conversion.

exudyn's Euler-parameter node (RigidBodyEP) has the ODE2 coordinates [r (3), p (4)] (reference + displacement;
`GetODE2CoordinatesTotal` aborted inside a pre-step function with exudyn 1.13.6, so the reference is read
once) and their rates [r_dot, p_dot]; the body-fixed angular velocity is
w' = 2 L(p) p_dot (docs/physics.md §6; Nikravesh 1988), p normalised with e0 >= 0 (as rotations.from_matrix).
"""
import math

from numba import njit

from crashlab.models.common.rotations import rotation_matrix_into


@njit(cache=True)
def chassis_states(qref, q, qt, idx, Y, A):
    """Y[v] = (r, p, r_dot, w') of each chassis (the multibody layout with nq = 7) and A[v] its rotation
    matrix, from the reference coordinates qref, the displacements q, their rates qt and each chassis node's
    first ODE2 index idx[v]."""
    for v in range(idx.shape[0]):
        o = idx[v]
        e0, e1 = qref[o + 3] + q[o + 3], qref[o + 4] + q[o + 4]
        e2, e3 = qref[o + 5] + q[o + 5], qref[o + 6] + q[o + 6]
        n = math.sqrt(e0 * e0 + e1 * e1 + e2 * e2 + e3 * e3)
        if e0 < 0.0:
            n = -n
        e0, e1, e2, e3 = e0 / n, e1 / n, e2 / n, e3 / n
        d0, d1, d2, d3 = qt[o + 3], qt[o + 4], qt[o + 5], qt[o + 6]
        if n < 0.0:
            d0, d1, d2, d3 = -d0, -d1, -d2, -d3
        for k in range(3):
            Y[v, k] = qref[o + k] + q[o + k]
            Y[v, 7 + k] = qt[o + k]
        Y[v, 3], Y[v, 4], Y[v, 5], Y[v, 6] = e0, e1, e2, e3
        Y[v, 10] = 2.0 * (-e1 * d0 + e0 * d1 + e3 * d2 - e2 * d3)
        Y[v, 11] = 2.0 * (-e2 * d0 - e3 * d1 + e0 * d2 + e1 * d3)
        Y[v, 12] = 2.0 * (-e3 * d0 + e2 * d1 - e1 * d2 + e0 * d3)
        rotation_matrix_into(e0, e1, e2, e3, A[v])
