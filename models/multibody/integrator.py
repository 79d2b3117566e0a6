"""The time loop: Dormand-Prince 5(4) with FSAL and PI step-size control (PI_BETA), hand-rolled in numba, over all
vehicles of a scene at once (one step size, error norm over the awake vehicles).

Scene awareness: step sizes grow up to h_max while nothing happens; a vehicle whose chassis has been
still (speed < v_rest, angular speed < w_rest) for t_sleep goes to sleep (velocities zeroed, no more
force evaluations; a vehicle the scene starts at rest starts asleep, ASLEEP0); the run ends when every vehicle
sleeps (stop_at_rest) or at t_end. Vehicle pairs of two sleeping vehicles are not evaluated.
Vehicle contact (common/chassis_contact.py) is evaluated in every stage. First-contact control (Flores & Ambrosio 2010,
docs/physics.md §15): a trial step that passes the error test but ends with a pair not yet in contact
penetrating deeper than onset_tol is bisected (re-integrated from its start) until the new penetration
is in (0, onset_tol]; the pair is then active and its approach velocity delta_dot0 is stored until its contact
ends (penetration <= 0 at the end of a step; a re-touch stores its own); the contact episode (impulse, peak
force, work, max penetration, delta-V, recorded in IMP: common/contact_episodes.py) closes once the pair is
SEPARATION apart. Euler parameters are renormalised after every accepted step.
"""
import math

import numpy as np
from numba import njit

from crashlab.models.common.chassis_contact import G_DDOT, G_DEL, G_GAP, IN_CONTACT, NONE, P_I, P_J, S_ACT, S_PUSH
from crashlab.models.common.contact_episodes import (
    accumulate,
    episode_step,
    finish_episode,
    open_episode,
    reset_sums,
    track_peak,
)
from crashlab.models.common.road_contact import R_DEL

from .dormand_prince import DP_A, dp_step, error_norm, normalise
from .driver_control import apply_modes, next_break, steer_jump
from .equations import (
    AUX_DRIFT_ANG,
    AUX_DRIFT_POS,
    AUX_FZ,
    C_ATOL,
    C_G,
    C_H0,
    C_HMAX,
    C_ONSET_TOL,
    C_PI_BETA,
    C_REC_DT,
    C_RTOL,
    C_STOP_AT_REST,
    C_T_SLEEP,
    C_TEND,
    C_V_REST,
    C_VMIN,
    C_W_REST,
    N_AUX,
)
from .recording import (
    D_CONTACT_T,
    D_H_MAX,
    D_H_MIN,
    D_MAX_DRIFT_ANG,
    D_MAX_DRIFT_POS,
    D_MAX_NORM_ERR,
    D_MAX_ONSET,
    D_NFEV,
    D_NIMP,
    D_NREC,
    D_ONSET_BISECT,
    D_PAIR_I,
    D_PAIR_J,
    D_REJECTED,
    D_STATUS,
    D_STEPS,
    D_T_END,
    R_T,
    headings,
    pose,
    record,
    velocity,
)
from .stage_forces import eval_all, make_work

STATUS_OK, STATUS_NAN, STATUS_STEP = 0, 2, 3


@njit(cache=True)
def _new_penetration(PST, PSG6):
    """Largest penetration at the end of a trial step among pairs not in contact (none yet, or an episode whose
    contact has ended: its re-touch is located as a first touch)."""
    best = -1e300
    for p in range(PST.shape[0]):
        if PST[p, S_ACT] != IN_CONTACT and PSG6[p, G_DEL] > best:
            best = PSG6[p, G_DEL]
    return best


@njit(cache=True)
def _episode(IMP, diag, p, PP, PST, PSG6, Y, BODY, t, finish):
    """The contact episode of an active pair p at the end of an accepted step at t, or at the run's end (finish)
    (common/contact_episodes.py: episode_step, finish_episode), its records counted in diag[D_NIMP]."""
    vi, vj = velocity(Y, BODY, int(PP[p, P_I])), velocity(Y, BODY, int(PP[p, P_J]))
    if finish:
        diag[D_NIMP] = finish_episode(IMP, int(diag[D_NIMP]), PP, PST, p, t, PSG6[p, G_DDOT], vi, vj)
    else:
        diag[D_NIMP] = episode_step(IMP, int(diag[D_NIMP]), PP, PST, p, t, t, t, PSG6[p, G_DEL], PSG6[p, G_GAP],
                                    PSG6[p, G_DDOT], vi, vj)


@njit(cache=True)
def simulate(Y, BODY, JNT, SPR, TYR, CT, DV, cfg, nslip, traj, diag, head, fz_start, fz_end, check_events,
             IMP, CONT, RD, ASLEEP0):
    """Integrate all vehicles from Y (modified in place) until rest or t_end, with vehicle contact
    (common/chassis_contact.py): first-contact control (no step ends with a new contact deeper than onset_tol),
    per-pair contact episodes recorded in IMP, state at first contact in CONT; chassis-road contact
    (common/road_contact.py, RD = (KR, RSG[7, nv, N_RSG])). ASLEEP0[v]: vehicle v starts asleep in its
    start state (velocities zeroed) unless it penetrates another body at the start; it wakes on contact like
    any sleeping vehicle. DV (model.driver_arrays): the drivers' action tables and the road's friction zones
    (docs/physics.md §2a): no step straddles a change of a driver's law (next_break); at one, the wheel
    states are set anew (apply_modes) and the accelerations re-evaluated. JNT and TYR are changed in place."""
    nv, ny = Y.shape
    nb = BODY.shape[1]
    nq, nvq = 7 * nb, 13 * nb
    CSH, BOXR, BOXA, BOXE, PP, PST, PSG, FX, BPC, OUT, FM = CT
    RSG = RD[1]
    road = np.zeros(nv)
    npair = PP.shape[0]
    wk = make_work(nv, nb)
    K = np.zeros((7, nv, ny))
    Ytmp, Ynew, Y0 = np.empty_like(Y), np.empty_like(Y), np.empty_like(Y)
    aux = np.zeros((nv, N_AUX))
    awake = np.ones(nv, np.bool_)
    struck = np.zeros(nv, np.bool_)
    ACT, NACT = DV[0], DV[1]
    t_lim = next_break(ACT, NACT, 0.0)
    still = np.zeros(nv)
    woken = np.zeros(nv, np.bool_)  # vehicles an accepted step's contact wakes (after its bookkeeping)
    hnew = np.empty(nv)
    rtol, atol, hmax = cfg[C_RTOL], cfg[C_ATOL], cfg[C_HMAX]
    t_end, rec_dt, tol = cfg[C_TEND], cfg[C_REC_DT], cfg[C_ONSET_TOL]
    diag[:] = 0.0
    diag[D_CONTACT_T] = math.nan
    diag[D_H_MIN] = 1e300
    diag[D_MAX_NORM_ERR] = normalise(Y, nb)
    headings(Y, BODY, head, head)
    eval_all(Y, K, 0, 0.0, awake, BODY, JNT, SPR, TYR, cfg, wk, aux, CT, RD, DV)
    fz_start[:, :] = aux[:, AUX_FZ:AUX_FZ + 4]
    # vehicles starting asleep (the first evaluation above had every vehicle awake: all pairs measured)
    for v in range(nv):
        if not ASLEEP0[v]:
            continue
        touching = False
        for p in range(npair):
            if (int(PP[p, P_I]) == v or int(PP[p, P_J]) == v) and PSG[0, p, G_DEL] > 0.0:
                touching = True
        if not touching:
            awake[v] = False
            fz_end[v, :] = aux[v, AUX_FZ:AUX_FZ + 4]
            Y[v, nq:nvq] = 0.0
            K[0, v, :] = 0.0
    Ytmp[:, :] = Y    # a sleeping vehicle's stage state (dp_step writes only the awake ones)
    nfev = 1
    nrec = record(traj, 0, 0.0, Y, BODY, head, aux, RSG[0], road, SPR, TYR, cfg[C_G])
    t_rec = rec_dt
    t, h = 0.0, cfg[C_H0]
    status = STATUS_OK
    bw = DP_A[6]
    expo = 0.2 - 0.75 * cfg[C_PI_BETA]
    errold, rejected = 1e-4, False
    while t < t_end * (1 - 1e-12):
        h = min(h, hmax, t_end - t)
        h_free = h
        at_break = t + h >= t_lim - 1e-10
        if at_break:
            h = t_lim - t
        dp_step(Y, t, h, t_lim, K, Ytmp, Ynew, awake, BODY, JNT, SPR, TYR, cfg, wk, aux, CT, RD, DV)
        nfev += 6
        err = error_norm(Y, Ynew, K, h, awake, nq, nvq, nslip, rtol, atol)
        if not (err == err):
            if h < 1e-9:
                status = STATUS_NAN
                break
            h *= 0.1
            h_free = h
            diag[D_REJECTED] += 1
            continue
        if err > 1.0:
            diag[D_REJECTED] += 1
            h *= max(0.2, 0.9 * err ** -expo)
            h_free = h
            rejected = True
            if h < 1e-10:
                status = STATUS_STEP
                break
            continue
        # first-contact control (docs/physics.md §15): a step may not end with a new contact deeper than tol
        if check_events and npair > 0 and _new_penetration(PST, PSG[6]) > tol:
            lo, hi = 0.0, h
            found = False
            for _ in range(60):
                mid = 0.5 * (lo + hi)
                dp_step(Y, t, mid, t_lim, K, Ytmp, Ynew, awake, BODY, JNT, SPR, TYR, cfg, wk, aux, CT, RD, DV)
                nfev += 6
                dm = _new_penetration(PST, PSG[6])
                if dm > tol:
                    hi = mid
                elif dm > 0.0:
                    h = mid
                    found = True
                    break
                else:
                    lo = mid
                if hi - lo < 1e-12:
                    break
            if not found:
                h = hi
                dp_step(Y, t, h, t_lim, K, Ytmp, Ynew, awake, BODY, JNT, SPR, TYR, cfg, wk, aux, CT, RD, DV)
                nfev += 6
            diag[D_ONSET_BISECT] += 1
            at_break = False
        # accepted
        Y0[:, :] = Y
        Y[:, :] = Ynew
        t = t_lim if at_break else t + h
        diag[D_STEPS] += 1
        diag[D_H_MIN] = min(diag[D_H_MIN], h)
        diag[D_H_MAX] = max(diag[D_H_MAX], h)
        diag[D_MAX_NORM_ERR] = max(diag[D_MAX_NORM_ERR], normalise(Y, nb))
        for v in range(nv):
            if awake[v]:
                diag[D_MAX_DRIFT_POS] = max(diag[D_MAX_DRIFT_POS], aux[v, AUX_DRIFT_POS])
                diag[D_MAX_DRIFT_ANG] = max(diag[D_MAX_DRIFT_ANG], aux[v, AUX_DRIFT_ANG])
        K[0] = K[6]
        headings(Y, BODY, head, hnew)
        head[:] = hnew
        # contact episodes: accumulate (DP weights), then open / close
        need_k0 = False
        for p in range(npair):
            i, j = int(PP[p, P_I]), int(PP[p, P_J])
            if PST[p, S_ACT] != IN_CONTACT and not awake[i] and (j >= nv or not awake[j]):
                continue  # two sleepers (or a sleeper and a barrier) not in contact, their episode ended or none:
                # contacts left their rows empty, nothing changes until one wakes (an ended one is written then,
                # or at the run's end)
            for s in range(7):
                if s < 6:
                    accumulate(PST, p, h * bw[s], PSG[s, p])
                track_peak(PST, p, PSG[s, p], PP, FM)
            d6 = PSG[6, p, G_DEL]
            if PST[p, S_ACT] == NONE:
                if d6 > 0.0:
                    open_episode(PST, p, t, max(PSG[6, p, G_DDOT], cfg[C_VMIN]), velocity(Y, BODY, i),
                                 velocity(Y, BODY, j))
                    diag[D_MAX_ONSET] = max(diag[D_MAX_ONSET], d6)
                    if not (diag[D_CONTACT_T] == diag[D_CONTACT_T]):
                        diag[D_CONTACT_T] = t
                        diag[D_PAIR_I], diag[D_PAIR_J] = i, j
                        for v in range(nv):
                            pv = pose(Y[v], BODY[v], nb)
                            CONT[v, 0], CONT[v, 1], CONT[v, 2] = pv[0], pv[1], head[v]
                            CONT[v, 3] = math.sqrt(pv[6] ** 2 + pv[7] ** 2)
                    for v in (i, j):
                        if v >= nv:
                            continue
                        if not struck[v]:
                            struck[v] = True
                            if apply_modes(Y[v], JNT[v], TYR[v], ACT[v], NACT[v], t, True, nb):
                                need_k0 = True
                        if not awake[v]:
                            woken[v] = True
                else:
                    reset_sums(PST, p)
            else:
                push = PST[p, S_PUSH]
                _episode(IMP, diag, p, PP, PST, PSG[6], Y, BODY, t, False)
                if (PST[p, S_PUSH] > 0.0) != (push > 0.0):
                    need_k0 = True  # a damped record (a push or re-impact) opened or ended: its damping (§13a) from
                    # the next step's first stage on
            if PST[p, S_ACT] == IN_CONTACT:
                for v in (i, j):
                    if v < nv and not awake[v]:
                        woken[v] = True
        # woken only now: the pairs above are booked with the awake flags their contacts were evaluated with (a
        # pair of two sleepers was skipped there, its outputs empty: booked, an ended episode would close)
        for v in range(nv):
            if woken[v]:
                awake[v], still[v], woken[v] = True, 0.0, False
                need_k0 = True
        for p in range(npair):
            for k in range(PSG.shape[2]):
                PSG[0, p, k] = PSG[6, p, k]
        for v in range(nv):
            for s in range(7):
                if RSG[s, v, R_DEL] > 0.0:
                    road[v] = 1.0
            if awake[v]:  # (a sleeping vehicle's stage outputs are not computed: RSG[0] keeps its last)
                for k in range(RSG.shape[2]):
                    RSG[0, v, k] = RSG[6, v, k]
        if at_break:
            # a driver's law changes at t (next_break): new wheel states, new brake / steer law from t on
            for v in range(nv):
                if awake[v] and DV[2][v, 3] > 0.0:
                    steer_jump(Y[v], ACT[v], NACT[v], DV[2][v], t, nb)
                apply_modes(Y[v], JNT[v], TYR[v], ACT[v], NACT[v], t, struck[v], nb)
            t_lim = next_break(ACT, NACT, t)
            need_k0 = True
        if need_k0:
            eval_all(Y, K, 0, t, awake, BODY, JNT, SPR, TYR, cfg, wk, aux, CT, RD, DV)
            nfev += 1
        # rest: a vehicle still for t_sleep goes to sleep (not while it is in contact)
        for v in range(nv):
            if not awake[v]:
                continue
            sp = math.sqrt(Y[v, nq] ** 2 + Y[v, nq + 1] ** 2 + Y[v, nq + 2] ** 2)
            wn = math.sqrt(Y[v, nq + 3] ** 2 + Y[v, nq + 4] ** 2 + Y[v, nq + 5] ** 2)
            if sp < cfg[C_V_REST] and wn < cfg[C_W_REST]:
                still[v] += h
            else:
                still[v] = 0.0
            if still[v] >= cfg[C_T_SLEEP]:
                awake[v] = False
                fz_end[v, :] = aux[v, AUX_FZ:AUX_FZ + 4]
                Y[v, nq:nvq] = 0.0
                K[0, v, :] = 0.0
        if t >= t_rec - 1e-12:
            nrec = record(traj, nrec, t, Y, BODY, head, aux, RSG[0], road, SPR, TYR, cfg[C_G])
            t_rec = t + rec_dt
        if cfg[C_STOP_AT_REST] > 0 and not awake.any():
            break
        # PI step-size control (Hairer, Norsett & Wanner, Solving ODE I, section II.4, DOPRI5's beta): the error
        # of the previous accepted step damps the oscillation of the step size at the stability limit;
        # no growth right after a rejection
        fac = 0.9 * err ** -expo * errold ** cfg[C_PI_BETA] if err > 0 else 5.0
        fac = min(5.0, max(0.2, fac))
        if rejected:
            fac = min(fac, 1.0)
        h *= fac
        errold = max(err, 1e-4)
        rejected = False
        if at_break:
            h = max(h, h_free)    # the step was shortened to end at the change, not for accuracy
    for p in range(npair):
        if PST[p, S_ACT] != NONE:
            _episode(IMP, diag, p, PP, PST, PSG[6], Y, BODY, t, True)
    for v in range(nv):
        if awake[v]:
            fz_end[v, :] = aux[v, AUX_FZ:AUX_FZ + 4]
    if traj.shape[0] > 0 and (nrec == 0 or traj[nrec - 1, 0, R_T] < t):
        nrec = record(traj, nrec, t, Y, BODY, head, aux, RSG[0], road, SPR, TYR, cfg[C_G])
    diag[D_T_END] = t
    diag[D_STATUS] = status
    diag[D_NFEV] = nfev
    diag[D_NREC] = nrec
    return t
