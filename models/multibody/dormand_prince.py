"""One Dormand-Prince 5(4) step over all vehicles of a scene (FSAL: the last stage is the next step's first),
its error norm over the awake vehicles, the Euler parameters' renormalisation after an accepted step, and the beta
of the PI step-size control (integrator.simulate)."""
import math

import numpy as np
from numba import njit

from .stage_forces import eval_all

# Dormand-Prince 5(4) tableau
DP_A = np.array([
    [0, 0, 0, 0, 0, 0],
    [1 / 5, 0, 0, 0, 0, 0],
    [3 / 40, 9 / 40, 0, 0, 0, 0],
    [44 / 45, -56 / 15, 32 / 9, 0, 0, 0],
    [19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729, 0, 0],
    [9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656, 0],
    [35 / 384, 0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84]])
DP_C = np.array([0.0, 1 / 5, 3 / 10, 4 / 5, 8 / 9, 1.0, 1.0])
DP_E = np.array([71 / 57600, 0.0, -71 / 16695, 71 / 1920, -17253 / 339200, 22 / 525, -1 / 40])

# PI step-size control (simulate): beta = 0.08 with exponent 0.2 - 0.75 beta = 0.14 is Soderlind's PI.3.4
# (Gustafsson 1991, ACM TOMS 17:533-554; Hairer & Wanner's DOPRI5 uses 0.04): the step size no longer
# oscillates about the stability limit (side collision: 59 rejected steps instead of 331)
PI_BETA = 0.08


@njit(cache=True)
def dp_step(Y, t, h, t_lim, K, Ytmp, Ynew, awake, BODY, JNT, SPR, TYR, cfg, wk, aux, CT, RD, DV):
    """One Dormand-Prince step from Y at t (K[0] = f(Y) given); fills Ynew and K[1..6] (K[6] = f(Ynew)).
    Stage times are held just below t_lim (the next change of the driver's law; the step ends there)."""
    nv, ny = Y.shape
    for s in range(1, 7):
        for v in range(nv):
            if not awake[v]:
                continue
            for i in range(ny):
                acc = 0.0
                for j in range(s):
                    acc += DP_A[s, j] * K[j, v, i]
                Ytmp[v, i] = Y[v, i] + h * acc
        if s == 6:
            Ynew[:, :] = Ytmp
            for v in range(nv):
                if not awake[v]:
                    Ynew[v] = Y[v]
        eval_all(Ytmp, K, s, min(t + DP_C[s] * h, t_lim - 1e-12), awake, BODY, JNT, SPR, TYR, cfg, wk, aux, CT, RD,
                 DV)


@njit(cache=True)
def error_norm(Y, Ynew, K, h, awake, nq, nvq, nslip, rtol, atol):
    acc, n = 0.0, 0
    for v in range(Y.shape[0]):
        if not awake[v]:
            continue
        for i in range(nvq + nslip):
            e = 0.0
            for j in range(7):
                e += DP_E[j] * K[j, v, i]
            e *= h
            if i < nq:
                sc = atol + rtol          # positions and Euler parameters: absolute scale 1 m / 1
            else:
                sc = atol + rtol * max(abs(Y[v, i]), abs(Ynew[v, i]))
            acc += (e / sc) ** 2
            n += 1
    return math.sqrt(acc / max(n, 1))


@njit(cache=True)
def normalise(Y, nb):
    worst = 0.0
    for v in range(Y.shape[0]):
        for b in range(nb):
            o = 7 * b + 3
            n = math.sqrt(Y[v, o] ** 2 + Y[v, o + 1] ** 2 + Y[v, o + 2] ** 2 + Y[v, o + 3] ** 2)
            worst = max(worst, abs(n - 1.0))
            for k in range(4):
                Y[v, o + k] /= n
    return worst
