"""The contact loads of one exudyn step (docs/physics.md §17): every chassis contact (car-car, car-barrier,
chassis-road) evaluated at the state exudyn holds, applied as a global force and torque on each chassis; the
pre-step predictor and the post-Newton iteration to the loads of the step end, and the step's shortening at a
contact onset."""
from __future__ import annotations

import numpy as np

from crashlab.models.common import chassis_contact as C
from crashlab.models.common import driver_inputs as DI
from crashlab.models.common import road_contact as R
from crashlab.models.common.contact_force import FRICTION_V0, FRICTION_V1, FRICTION_VS

from .chassis_state import chassis_states

BIG_ERROR = 1e6        # N: a post-Newton error that always repeats the step (exudyn's tolerance is 1 N)
LOAD_ABS_TOL = 10.0    # N: absolute part of the load-iteration tolerance
MAX_LOAD_ITER = 4      # load passes per step before the step is halved
# passes at the shortest step (exudyn's discontinuous maxIterations, its default; after the last it accepts the step
# unsettled): from MAX_LOAD_ITER on relaxed by Aitken's factor (postnewton)
MAX_SHORTEST_ITER = 5
OMEGA_MIN, OMEGA_MAX = 0.05, 1.5  # the relaxation factor's range
ALL = np.zeros(0, np.bool_)  # road_contacts: every vehicle (exudyn does not put vehicles to sleep)


class StepLoads:
    """The contact loads of ExudynRun's steps (a mixin: it uses the run's attributes)."""

    def _contact_loads(self):
        """Read the chassis states exudyn holds now and evaluate every contact there: returns (FX (nv, 7):
        global force, moment about the chassis CG, power per chassis; the pairs' outputs psg; the road outputs
        RSG), all copies."""
        sd = self.mbs.systemData
        chassis_states(self.q_ref, sd.GetODE2Coordinates(), sd.GetODE2Coordinates_t(), self.chassis_idx, self.Y,
                       self.chassisA)
        CSH, BOXR, BOXA, BOXE, PP, PST, PSG, FX, BPC, OUT, FM = self.CT
        psg = PSG[0]
        if PP.shape[0]:
            C.contacts(self.Y, 7, CSH, BOXR, BOXA, BOXE, PP, PST, psg, FX, BPC, OUT, FM, self.o["contact_exponent"],
                       self.cchi, self.mu_c, self.fcode, FRICTION_V0, FRICTION_V1, FRICTION_VS, self.o["v_min"],
                       self.claw, self.rest)
        else:
            FX[:, :] = 0.0
        mu = self.scene.road.friction
        if self.zones is None:
            R.road_contacts(self.Y, 7, self.CSH, self.KR, R.N_ROAD, self.road_chi, mu,
                            R.ROAD_FRICTION_LAW, FRICTION_V0, FRICTION_V1, FRICTION_VS, FX, self.RSG, ALL)
        else:  # each chassis on the friction of the zone under its CG (§2a)
            for v in range(self.nv):
                mv = DI.road_friction(self.Y[v, 0], self.Y[v, 1], mu, *self.zones)
                w = slice(v, v + 1)
                R.road_contacts(self.Y[w], 7, self.CSH[w], self.KR[w], R.N_ROAD, self.road_chi, mv,
                                R.ROAD_FRICTION_LAW, FRICTION_V0, FRICTION_V1, FRICTION_VS, FX[w], self.RSG[w], ALL)
        return FX.copy(), psg.copy(), self.RSG.copy()

    def _apply(self, L):
        mbs = self.mbs
        for v in range(self.nv):
            it = self.items[v]
            mbs.SetLoadParameter(it["force"], "loadVector", L[v, 0:3].tolist())
            mbs.SetLoadParameter(it["torque"], "loadVector", L[v, 3:6].tolist())
        self.L = L

    # ------------------------------------------------------------------ one step: pre-step and post-Newton
    def prestep(self, mbs, t):
        """Start of an attempt of the step [s, t] (the state exudyn holds now is the one at s). A new s means the
        previous step was accepted: its contact bookkeeping is done here, with the loads at this state as its
        end values. The contact loads start at their value at s (the predictor of the step's iteration)."""
        s = mbs.systemData.GetTime(self.exu.ConfigurationType.StartOfStep)
        self.iter, self.omega, self.r_prev = 0, 1.0, None
        if s != self.s_cur:
            F, psg, rsg = self._contact_loads()
            self._update_headings()
            if self.s_cur is not None:
                self._accept(self.s_cur, s, F, psg, rsg)
            # slope of the loads over the last step: the predictor extrapolates it (at most one last step on)
            self.dF, self.h_last = ((F - self.F0) / (s - self.s_cur), s - self.s_cur) if self.s_cur is not None \
                else (np.zeros_like(F), 0.0)
            self.s_cur, self.F0, self.psg0, self.rsg0 = s, F, psg, rsg
            self._driver(s, t)
            self._wheel_torques(mbs)
            if s >= self.t_rec - 1e-12:
                self._record(s)
                self.t_rec = s + self.o["record_dt"]
            self.awake = self._awake(s)
        self._apply((self.F0 + self.dF * min(t - s, self.h_last))[:, :6])
        return self.awake

    def postnewton(self, mbs, t):
        """After exudyn's Newton converged for [s, t]: the contact loads at t. The step is repeated with the
        trapezoidal load (F(s) + F(t)) / 2 until it changes by less than load_tolerance; it is repeated with a
        shorter step (exudyn's adaptive step) when a contact opens deeper than onset_tolerance or the load
        iteration does not settle in MAX_LOAD_ITER passes. Returns [error, recommended step] (exudyn's
        PostNewtonUserFunction; error > its discontinuous iterationTolerance repeats the step)."""
        o = self.o
        h = t - self.s_cur
        F1, psg1, rsg1 = self._contact_loads()
        can_shorten = h > 1.5 * o["min_step"]
        if can_shorten:
            d = self._onset_depth(psg1, rsg1)
            if d > o["onset_tolerance"]:
                self.n_shortened += 1
                return [BIG_ERROR, h * max(0.1, min(0.5, o["onset_tolerance"] / d))]
        L = F1[:, :6]
        # converged when the forces settle; the moments are not tested: on parallel flat faces the contact
        # point (a support point of the superellipsoid) moves across the face with the last digits of the
        # contact normal, so the moment changes from pass to pass without a trend
        err = float(np.abs(L[:, :3] - self.L[:, :3]).max()) if L.size else 0.0
        if err <= o["load_tolerance"] * max(float(np.abs(L[:, :3]).max()), 1.0) + LOAD_ABS_TOL:
            self.F1, self.psg1, self.rsg1 = F1, psg1, rsg1
            return [0.0, -1.0]
        self.iter += 1
        r = L - self.L
        r_prev, self.r_prev = self.r_prev, r
        if self.iter >= MAX_LOAD_ITER:
            if can_shorten:
                self.n_shortened += 1
                return [BIG_ERROR, 0.5 * h]
            # at the shortest step: the passes relaxed by Aitken's factor (the loads' own iteration can flip
            # between two values at any step, e.g. a regularised friction at a large normal force)
            L = self.L + self._aitken(r, r_prev) * r
            if self.iter >= MAX_SHORTEST_ITER:
                self.n_unsettled += 1      # the last pass did not settle: exudyn accepts the step
        self.n_load_iter += 1
        self._apply(L)
        return [max(err, BIG_ERROR), -1.0]

    def _aitken(self, r, r_prev):
        """Aitken's relaxation factor of a fixed-point iteration from its last two residuals r (new load less the
        applied one): omega = -omega_prev r_prev . (r - r_prev) / |r - r_prev|^2 (Irons & Tuck 1969), kept within
        [OMEGA_MIN, OMEGA_MAX]."""
        if r_prev is not None:
            dr = r - r_prev
            den = float(np.sum(dr * dr))
            if den > 0.0:
                self.omega = min(max(-self.omega * float(np.sum(r_prev * dr)) / den, OMEGA_MIN), OMEGA_MAX)
        return self.omega

    def _onset_depth(self, psg1, rsg1):
        """Deepest penetration of a contact not yet open (pairs: none yet, or an episode whose contact has ended;
        road)."""
        PST = self.CT[5]
        d = 0.0
        for p in range(PST.shape[0]):
            if PST[p, C.S_ACT] != C.IN_CONTACT:
                d = max(d, psg1[p, C.G_DEL])
        for v in range(self.nv):
            if not self.road_on[v]:
                d = max(d, rsg1[v, R.R_DEL])
        return d
