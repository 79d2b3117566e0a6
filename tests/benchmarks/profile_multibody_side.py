"""Where the multibody side collision's time goes (issue 25 item 4):
`python tests/benchmarks/profile_multibody_side.py`.

Prints (1) the run's counts (steps and rejected steps per phase, right-hand-side and narrow-phase evaluations),
(2) the per-call cost of the parts of one evaluation in compiled loops (min of 7 repeats, process CPU) on the
run's own states before, in and after contact, and (3) the stiffest eigenvalues of the sliding V2 (Jacobian of
the right-hand side by central differences at 0.75 s) with the state they live in: the explicit Dormand-Prince
step is stable for h |lambda| <~ 3.3 (models/multibody/README.md "Speed"). Not a test (pytest does not collect it).
"""
import dataclasses
import time
from pathlib import Path

import numpy as np
from numba import njit

import crashlab
from crashlab.models.common.chassis_contact import contact_arrays, contacts_awake
from crashlab.models.common.contact_episodes import N_IMP, episode_capacity
from crashlab.models.common.road_contact import ROAD_FRICTION_LAW, road_contacts
from crashlab.models.multibody import MultibodyModel
from crashlab.models.multibody import dormand_prince as DP
from crashlab.models.multibody import equations as E
from crashlab.models.multibody import integrator as I
from crashlab.models.multibody import recording as REC
from crashlab.models.multibody.model import NB, NW, _road_arrays
from crashlab.models.multibody.stage_forces import eval_all, make_work

SIDE = Path(__file__).resolve().parents[2] / "studies" / "pc_crash" / "side.toml"
NQ, NVQ = 7 * NB, 13 * NB


def state_at(sc, t_end):
    """The scene's packed arrays integrated to t_end (the integrator's own step sequence)."""
    prep = MultibodyModel().prepare(sc)
    nv = len(sc.vehicles)
    Y, JNT, TYR = prep["Y"].copy(), prep["JNT"].copy(), prep["TYR"].copy()
    cfg = prep["cfg"].copy()
    cfg[E.C_TEND] = t_end
    CT = contact_arrays(prep["CSH"], prep["PP"], prep["BAR"], nv)
    RD = _road_arrays([v.mass for v in prep["vehicles"]])
    I.simulate(Y, prep["BODY"], JNT, prep["SPR"], TYR, CT, prep["DV"], cfg, 2 * NW,
               np.zeros((int(t_end / 0.01) + 5, nv, REC.N_REC)), np.zeros(REC.N_DIAG),
               np.array([vs.heading for vs in sc.vehicles]), np.zeros((nv, 4)), np.zeros((nv, 4)), True,
               np.zeros((episode_capacity(nv, len(sc.barriers)), N_IMP)), np.full((nv, 4), np.nan), RD, prep["ASLEEP"])
    return Y, (prep["BODY"], JNT, prep["SPR"], TYR, cfg, make_work(nv, NB), np.zeros((nv, E.N_AUX)), CT, RD, prep["DV"])


@njit(cache=True)
def _eval(n, Y, K, awake, BODY, JNT, SPR, TYR, cfg, wk, aux, CT, RD, DV):
    for _ in range(n):
        eval_all(Y, K, 1, 0.5, awake, BODY, JNT, SPR, TYR, cfg, wk, aux, CT, RD, DV)


@njit(cache=True)
def _one_vehicle(n, Y, K, BODY, JNT, SPR, TYR, cfg, wk, aux, CT, RD, DV):
    A, R, V, W, Q, D, phi, gam, rowb, ispos, S, lam, phit, MD, jst, JB, NZ, IM = wk
    ZC, ZS, ZM, ZB = DV[3], DV[4], DV[5], DV[6]
    for _ in range(n):
        E.rhs(Y[0], K[1, 0], BODY[0], JNT[0], SPR[0], TYR[0], cfg, A[0], R[0], V[0], W[0], Q[0], D[0], phi[0],
              gam[0], rowb[0], ispos[0], S[0], lam[0], aux[0], CT[7][0], phit[0], 0.0, ZC, ZS, ZM, ZB, MD[0], jst[0],
              JB[0], NZ[0], IM[0])


@njit(cache=True)
def _contact(n, Y, CT, cfg, awake):
    CSH, BOXR, BOXA, BOXE, PP, PST, PSG, FX, BPC, OUT = CT
    for _ in range(n):
        contacts_awake(Y, NQ, CSH, BOXR, BOXA, BOXE, PP, PST, PSG[1], FX, BPC, OUT, cfg[E.C_NEXP], cfg[E.C_CHI],
                       cfg[E.C_MU_C], cfg[E.C_FCODE], cfg[E.C_FV0], cfg[E.C_FV1], cfg[E.C_FVS], cfg[E.C_VMIN],
                       cfg[E.C_LAW], cfg[E.C_REST], awake)


@njit(cache=True)
def _road(n, Y, CT, RD, cfg):
    for _ in range(n):
        road_contacts(Y, NQ, CT[0], RD[0], cfg[E.C_ROAD_N], cfg[E.C_ROAD_CHI], cfg[E.C_MU], ROAD_FRICTION_LAW,
                      cfg[E.C_FV0], cfg[E.C_FV1], cfg[E.C_FVS], CT[7], RD[1][1], np.zeros(0, np.bool_))


@njit(cache=True)
def _step(n, Y, K, Ytmp, Ynew, awake, BODY, JNT, SPR, TYR, cfg, wk, aux, CT, RD, DV):
    e = 0.0
    for _ in range(n):
        DP.dp_step(Y, 0.5, 1e-3, 1e9, K, Ytmp, Ynew, awake, BODY, JNT, SPR, TYR, cfg, wk, aux, CT, RD, DV)
        e += DP.error_norm(Y, Ynew, K, 1e-3, awake, NQ, NVQ, 2 * NW, cfg[E.C_RTOL], cfg[E.C_ATOL])
    return e


def _best_us(f, n, *args):
    f(1, *args)
    ts = []
    for _ in range(7):
        t0 = time.process_time()
        f(n, *args)
        ts.append(time.process_time() - t0)
    return min(ts) / n * 1e6


def main():
    sc = crashlab.load_scene(SIDE)
    model = MultibodyModel()
    out = model.simulate(sc)
    d = out.diagnostics
    print(f"steps {d['steps']}, rejected {d['rejected_steps']}, rhs evaluations {d['rhs_evaluations']} "
          f"(both vehicles each), broad phase {d['broad_phase']}, rest at {d['t_end']:.3f} s")
    t_contact = out.contact_time
    prev, rows = (0, 0), []
    for t in (t_contact, 0.2, 0.5, 1.0, 1.5, sc.duration):
        di = model.simulate(dataclasses.replace(sc, duration=t)).diagnostics
        rows.append(f"to {min(t, di['t_end']):.3f} s {di['steps'] - prev[0]} + {di['rejected_steps'] - prev[1]}")
        prev = (di["steps"], di["rejected_steps"])
    print("steps + rejected by phase:", "; ".join(rows))
    for t in (0.5 * t_contact, t_contact + 0.02, 0.75):
        Y, a = state_at(sc, t)
        nv, ny = Y.shape
        awake = np.ones(nv, np.bool_)
        K = np.zeros((7, nv, ny))
        eval_all(Y, K, 0, t, awake, *a)
        BODY, JNT, SPR, TYR, cfg, wk, aux, CT, RD, DV = a
        ev = _best_us(_eval, 2000, Y, K, awake, *a)
        one = _best_us(_one_vehicle, 2000, Y, K, *a)
        co = _best_us(_contact, 2000, Y, CT, cfg, awake)
        ro = _best_us(_road, 2000, Y, CT, RD, cfg)
        st = _best_us(_step, 300, Y, K, Y.copy(), Y.copy(), awake, *a)
        print(f"t = {t:.3f} s: one evaluation {ev:.1f} us (one vehicle's equations {one:.1f}, vehicle contact "
              f"{co:.1f}, road contact {ro:.2f}); a DP step with its error norm {st:.0f} us = {st / 6:.1f} per "
              f"evaluation")
    # stiffest modes of V2 sliding after the impact
    Y, a = state_at(sc, 0.75)
    nv, ny = Y.shape
    n = NVQ + 2 * NW
    K = np.zeros((7, nv, ny))
    awake = np.ones(nv, np.bool_)

    def f(y):
        Yp = Y.copy()
        Yp[1, :n] = y
        eval_all(Yp, K, 0, 0.75, awake, *a)
        return K[0, 1, :n].copy()

    y0, J = Y[1, :n].copy(), np.zeros((n, n))
    for i in range(n):
        h = 1e-7 * max(1.0, abs(y0[i]))
        e = np.zeros(n)
        e[i] = h
        J[:, i] = (f(y0 + e) - f(y0 - e)) / (2 * h)
    lam, vec = np.linalg.eig(J)
    names = {NVQ + 2 * k + c: f"wheel {k} slip {'sa'[c]}" for k in range(NW) for c in range(2)}
    for k in np.argsort(-np.abs(lam))[:5]:
        i = int(np.argmax(np.abs(vec[:, k])))
        print(f"V2 at 0.75 s: lambda {lam[k].real:9.1f} {lam[k].imag:+8.1f}i s^-1, mostly {names.get(i, f'state {i}')}"
              f" (DP5 stable for h < {3.3 / abs(lam[k]) * 1e3:.2f} ms)")


if __name__ == "__main__":
    main()
