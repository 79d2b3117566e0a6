"""All forces and accelerations of the scene's vehicles at one stage of the time loop: the vehicle contacts
(common/chassis_contact.py), the chassis-road contacts (common/road_contact.py), the driver's steer and brake
(driver_control.py) and each awake vehicle's equations of motion (equations.rhs), with the work arrays they use."""
import numpy as np
from numba import njit

from crashlab.models.common.chassis_contact import contacts_awake
from crashlab.models.common.road_contact import ROAD_FRICTION_LAW, road_contacts

from .driver_control import drive
from .equations import (
    C_CHI,
    C_FCODE,
    C_FV0,
    C_FV1,
    C_FVS,
    C_LAW,
    C_MU,
    C_MU_C,
    C_NEXP,
    C_REST,
    C_ROAD_CHI,
    C_ROAD_N,
    C_VMIN,
    MAX_JOINTS,
    MAX_ROWS,
    rhs,
)


@njit(cache=True)
def make_work(nv, nb):
    return (np.empty((nv, nb, 3, 3)), np.empty((nv, nb, 3)), np.empty((nv, nb, 3)), np.empty((nv, nb, 3)),
            np.empty((nv, nb, 6)), np.empty((nv, MAX_ROWS, 12)), np.empty((nv, MAX_ROWS)),
            np.empty((nv, MAX_ROWS)), np.empty((nv, MAX_ROWS, 2), np.int64), np.empty((nv, MAX_ROWS), np.bool_),
            np.empty((nv, MAX_ROWS, MAX_ROWS)), np.empty((nv, MAX_ROWS)), np.zeros((nv, MAX_ROWS)),
            np.empty((nv, MAX_ROWS, 12)), np.zeros((nv, MAX_JOINTS + 1), np.int64),
            np.zeros((nv, MAX_JOINTS, 2), np.int64), np.zeros((nv, MAX_JOINTS, MAX_JOINTS), np.bool_),
            np.empty((nv, nb, 6)))


@njit(cache=True)
def eval_all(Y, K, s, te, awake, BODY, JNT, SPR, TYR, cfg, wk, aux, CT, RD, DV):
    """All forces and accelerations at stage s, time te (the driver's inputs; DV: driver_arrays)."""
    A, R, V, W, Q, D, phi, gam, rowb, ispos, S, lam, phit, MD, jst, JB, NZ, IM = wk
    ACT, NACT, GEO, ZC, ZS, ZM, ZB = DV
    CSH, BOXR, BOXA, BOXE, PP, PST, PSG, FX, BPC, OUT, FM = CT
    KR, RSG = RD
    if PP.shape[0] > 0:
        contacts_awake(Y, 7 * BODY.shape[1], CSH, BOXR, BOXA, BOXE, PP, PST, PSG[s], FX, BPC, OUT, FM, cfg[C_NEXP],
                       cfg[C_CHI], cfg[C_MU_C], cfg[C_FCODE], cfg[C_FV0], cfg[C_FV1], cfg[C_FVS], cfg[C_VMIN],
                       cfg[C_LAW], cfg[C_REST], awake)
    else:
        FX[:, :] = 0.0
    # chassis-road contact (regularised Coulomb with the road's friction)
    road_contacts(Y, 7 * BODY.shape[1], CSH, KR, cfg[C_ROAD_N], cfg[C_ROAD_CHI], cfg[C_MU], ROAD_FRICTION_LAW,
                  cfg[C_FV0], cfg[C_FV1], cfg[C_FVS], FX, RSG[s], awake)
    for v in range(Y.shape[0]):
        if awake[v]:
            brake = 0.0
            if NACT[v] > 1:
                brake = drive(ACT[v], NACT[v], GEO[v], JNT[v], te)
            rhs(Y[v], K[s, v], BODY[v], JNT[v], SPR[v], TYR[v], cfg, A[v], R[v], V[v], W[v], Q[v], D[v],
                phi[v], gam[v], rowb[v], ispos[v], S[v], lam[v], aux[v], FX[v], phit[v], brake, ZC, ZS, ZM, ZB,
                MD[v], jst[v], JB[v], NZ[v], IM[v])
        else:
            K[s, v, :] = 0.0
