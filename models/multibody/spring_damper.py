"""Translational spring-damper with a bump stop (docs/physics.md §8).

d = r_j^Q - r_i^P, l = |d|, u = d/l, l_dot = u . d_dot
f = k (l - l0) + c l_dot - k_b max(0, l_b - l)     (tension positive; the bump stop is a linear stop
                                                    that engages when the spring is shorter than l_b)
F_i = f u at P, F_j = -f u at Q.
Strut (axis u'_i given, a unit vector of body i from P towards Q): the element acts along the strut axis
u = A_i u'_i with the SIGNED length l = d . u (a suspension strut on the vehicle's translational joint).
With |d| the length would turn positive again once a violent compression pushed Q through P, the force
would flip and the spring would pull the wheel up through the chassis (issue 10: chassis below the road);
signed, the bump stop's force keeps growing. The force on j acts at the point of the axis line at Q's
height (P + l u), so the pair is collinear (no spurious couple; the joint carries Q's small offset).
Row layout (common/vehicle_3d.py S_* indices): i, j, s'_P, s'_Q, k, c, l0, l_b, k_b, u'_i (zero: along d,
unsigned).
"""
import math

from numba import njit

from crashlab.models.common.rotations import add, cross, dot, mtv, mv, scale, sub
from crashlab.models.common.vehicle_3d import S_C, S_I, S_J, S_K, S_KB, S_L0, S_LB, S_P, S_Q, S_U


@njit(cache=True, inline="always")
def apply_force(A, Q, b, s_, F):
    """A global force F at body-fixed point s' of body b: adds to f and to the body moment n'."""
    Q[b, 0] += F[0]
    Q[b, 1] += F[1]
    Q[b, 2] += F[2]
    n = cross(s_, mtv(A, b, F))
    Q[b, 3] += n[0]
    Q[b, 4] += n[1]
    Q[b, 5] += n[2]


@njit(cache=True)
def spring_damper(S, A, R, V, W, Q, damping_on):
    """Adds the element's forces to Q; returns (power dissipated by the damper, length)."""
    i, j = int(S[S_I]), int(S[S_J])
    sp, sq = (S[S_P], S[S_P + 1], S[S_P + 2]), (S[S_Q], S[S_Q + 1], S[S_Q + 2])
    P = add((R[i, 0], R[i, 1], R[i, 2]), mv(A, i, sp))
    Qp = add((R[j, 0], R[j, 1], R[j, 2]), mv(A, j, sq))
    d = sub(Qp, P)
    vP = add((V[i, 0], V[i, 1], V[i, 2]), mv(A, i, cross((W[i, 0], W[i, 1], W[i, 2]), sp)))
    ua = (S[S_U], S[S_U + 1], S[S_U + 2])
    strut = ua[0] != 0.0 or ua[1] != 0.0 or ua[2] != 0.0
    if strut:
        u = mv(A, i, ua)
        l = dot(d, u)
        # force on j at the axis point X = P + l u (body j's material point there)
        sx = mtv(A, j, sub(add(P, scale(l, u)), (R[j, 0], R[j, 1], R[j, 2])))
    else:
        l = math.sqrt(dot(d, d))
        u = scale(1.0 / l, d)
        sx = sq
    vX = add((V[j, 0], V[j, 1], V[j, 2]), mv(A, j, cross((W[j, 0], W[j, 1], W[j, 2]), sx)))
    ldot = dot(u, sub(vX, vP))
    c = S[S_C] * damping_on
    f = S[S_K] * (l - S[S_L0]) + c * ldot
    if l < S[S_LB]:
        f -= S[S_KB] * (S[S_LB] - l)
    apply_force(A, Q, i, sp, scale(f, u))
    apply_force(A, Q, j, sx, scale(-f, u))
    return c * ldot * ldot, l


@njit(cache=True)
def spring_energy(S, l):
    e = 0.5 * S[S_K] * (l - S[S_L0]) ** 2
    if l < S[S_LB]:
        e += 0.5 * S[S_KB] * (S[S_LB] - l) ** 2
    return e
