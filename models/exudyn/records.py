"""What one exudyn run keeps and reports (models/exudyn/run.py): the vehicles' poses, energy and headings read
from exudyn's nodes, the contact episodes' bookkeeping of each accepted step (common/contact_episodes.py, as
multibody's integrator), the trajectory records, the rest test, and the Outcome at the end of the run."""
from __future__ import annotations

import math
import time

import numpy as np

from crashlab.models.common import chassis_contact as C
from crashlab.models.common import contact_episodes as EP
from crashlab.models.common import contact_report
from crashlab.models.common import road_contact as R
from crashlab.models.common.impact_rows import struck_compliance
from crashlab.models.common.vehicle_3d import CORNERS
from crashlab.outcome import Outcome
from crashlab.units import G


class Records:
    """The state access, bookkeeping and results of ExudynRun (a mixin: it uses the run's attributes)."""

    def _chassis(self, v):
        out = self.exu.OutputVariableType
        nd = self.items[v]["chassis"]["nodeNumber"]
        g = self.mbs.GetNodeOutput
        A = np.asarray(g(nd, out.RotationMatrix)).reshape(3, 3)
        r, vel, om = g(nd, out.Position), g(nd, out.Velocity), g(nd, out.AngularVelocity)
        return np.asarray(r), A, np.asarray(vel), np.asarray(om)

    def _pose(self, v):
        """(x, y, z, heading (continuous), roll, pitch, vx, vy, yaw_rate, vz): vehicle CG of all nine bodies,
        chassis angles (ZYX), CG velocity, chassis yaw rate (as multibody.integrator.pose)."""
        out = self.exu.OutputVariableType
        it = self.items[v]
        m = it["mass"]
        c = np.zeros(6)
        for b, nd in enumerate(it["nodes"]):
            c[:3] += m[b] * np.asarray(self.mbs.GetNodeOutput(nd, out.Position))
            c[3:] += m[b] * np.asarray(self.mbs.GetNodeOutput(nd, out.Velocity))
        c /= m.sum()
        r, A, vel, om = self._chassis(v)
        pitch = math.asin(max(-1.0, min(1.0, -A[2, 0])))
        roll = math.atan2(A[2, 1], A[2, 2])
        return (c[0], c[1], c[2], self.head[v], roll, pitch, c[3], c[4], om[2], c[5])

    def _energy(self, v):
        """Mechanical energy of vehicle v [J]: kinetic energy of its nine bodies (translation and rotation
        about their principal axes) and their height in gravity; the guard's measure for a tumbling car,
        whose planar energy alone trades with roll and pitch in free flight (docs/physics.md §19)."""
        out = self.exu.OutputVariableType
        g = self.mbs.GetNodeOutput
        e = 0.0
        for b, nd in enumerate(self.items[v]["nodes"]):
            m, inertia = self.vehs[v].BODY[b, 0], self.vehs[v].BODY[b, 1:4]
            A = np.asarray(g(nd, out.RotationMatrix)).reshape(3, 3)
            vel, om = np.asarray(g(nd, out.Velocity)), A.T @ np.asarray(g(nd, out.AngularVelocity))
            e += 0.5 * m * float(vel @ vel) + 0.5 * float(inertia @ (om * om)) \
                + m * G * float(np.asarray(g(nd, out.Position))[2])
        return e

    def _update_headings(self):
        for v in range(self.nv):
            A = self.chassisA[v]
            h = math.atan2(A[1, 0], A[0, 0])
            d = h - self.head[v]
            self.head[v] += math.atan2(math.sin(d), math.cos(d))

    def _accept(self, s, t, F1, psg1, rsg1):
        """Bookkeeping of the accepted step [s, t] (common/contact_episodes.py, as multibody's integrator):
        episodes open at the first penetration (delta_dot0 stored, onset time interpolated in the step), close at
        separation; impulse of the applied (trapezoidal) load, work by the trapezoidal rule of the contact power,
        peak force and penetration at both ends. Road contacts: their intervals only (contact_intervals)."""
        h = t - s
        self.nsteps += 1
        self.h_min_used = min(self.h_min_used, h)
        CSH, BOXR, BOXA, BOXE, PP, PST, PSG, FX, BPC, OUT, FM = self.CT
        psg0 = self.psg0
        for p in range(PP.shape[0]):
            i, j = int(PP[p, C.P_I]), int(PP[p, C.P_J])
            d0, d1 = psg0[p, C.G_DEL], psg1[p, C.G_DEL]
            if PST[p, C.S_ACT] == C.NONE:
                if d1 <= 0.0:
                    continue
                EP.reset_sums(PST, p)
                EP.open_episode(PST, p, s + h * min(max(-d0 / (d1 - d0), 0.0), 1.0),
                                max(psg1[p, C.G_DDOT], self.o["v_min"]), self._velocity(i), self._velocity(j))
                self.max_onset = max(self.max_onset, d1)
                if math.isnan(self.contact_time):
                    self.contact_time = PST[p, C.S_T0]
                    for v in range(self.nv):
                        pv = self._pose(v)
                        self.contact[v] = [pv[0], pv[1], pv[3], math.hypot(pv[6], pv[7])]
                for v in (i, j):
                    if v < self.nv:
                        self.struck[v] = True   # locked_after_impact locks in the next pre-step (_driver)
            for q in (psg0, psg1):
                EP.accumulate(PST, p, 0.5 * h, q[p])
                EP.track_peak(PST, p, q[p], PP, FM)
            # where within the step the contact ended / began (interpolated; only where it did: d0 == d1 divided
            # by zero)
            t_part = s + h * min(max(d0 / (d0 - d1), 0.0), 1.0) if d0 > 0.0 >= d1 else s
            t_touch = s + h * min(max(-d0 / (d1 - d0), 0.0), 1.0) if d1 > 0.0 >= d0 else t
            self._episode(p, t, t_part, t_touch, psg1)
        for v in range(self.nv):
            on = rsg1[v, R.R_DEL] > 0.0
            if on and not self.road_on[v]:
                d0, d1 = self.rsg0[v, R.R_DEL], rsg1[v, R.R_DEL]
                self.road_t0[v] = s + h * min(max(-d0 / (d1 - d0), 0.0), 1.0)
                self.road_contacts += 1
            elif self.road_on[v] and not on:
                self.intervals.append((self.road_t0[v], t))
            self.road_on[v] = on
            self.road_pen = max(self.road_pen, rsg1[v, R.R_DEL])

    def _velocity(self, v):
        """(vx, vy, yaw rate) of vehicle v's CG; zeros for a barrier (v >= number of vehicles)."""
        if v >= self.nv:
            return (0.0, 0.0, 0.0)
        p = self._pose(v)
        return (float(p[6]), float(p[7]), float(p[8]))

    def _episode(self, p, t, t_part, t_touch, psg, finish=False):
        """The contact episode of an active pair p at the end of an accepted step at t (contact ended at t_part,
        began again at t_touch within it), or at the run's end (finish): common/contact_episodes.py's
        episode_step, finish_episode; each record written adds its contact interval."""
        PP, PST = self.CT[4], self.CT[5]
        vi, vj = self._velocity(int(PP[p, C.P_I])), self._velocity(int(PP[p, C.P_J]))
        n = self.n_episodes
        if finish:
            self.n_episodes = EP.finish_episode(self.IMP, n, PP, PST, p, t, psg[p, C.G_DDOT], vi, vj)
        else:
            self.n_episodes = EP.episode_step(self.IMP, n, PP, PST, p, t, t_part, t_touch, psg[p, C.G_DEL],
                                              psg[p, C.G_GAP], psg[p, C.G_DDOT], vi, vj)
        for k in range(n, min(self.n_episodes, len(self.IMP))):
            self.intervals.append((self.IMP[k, EP.I_T0], self.IMP[k, EP.I_T1]))

    def _record(self, s):
        for v in range(self.nv):
            self.traj[v].append((s,) + tuple(self._pose(v)) + (self.RSG[v, R.R_ZMIN], self._energy(v)))

    def _awake(self, s):
        """False (stop after this step) once every chassis has been still for t_sleep and no contact is open."""
        if not self.scene.stop_at_rest:
            return True
        PST = self.CT[5]
        active = bool(PST.shape[0]) and bool((PST[:, C.S_ACT] == C.IN_CONTACT).any())
        still = not active and all(math.hypot(self.Y[v, 7], self.Y[v, 8]) < self.o["v_rest"]
                                   and abs((self.chassisA[v] @ self.Y[v, 10:13])[2]) < self.o["w_rest"]
                                   for v in range(self.nv))
        if not still:
            self.t_still = None
            return True
        if self.t_still is None:
            self.t_still = s
        return s - self.t_still < self.o["t_sleep"]


    def _outcome(self, t0, t_end, warnings, ok, overlap):
        """The Outcome of the run ended at t_end: rest poses, trajectories, impact rows, diagnostics."""
        exu, mbs, o = self.exu, self.mbs, self.o
        nv = self.nv
        self._record(t_end)
        rest, final = np.zeros((nv, 3)), np.zeros((nv, 3))
        trajectories = {}
        keys = ("t", "x", "y", "z", "heading", "roll", "pitch", "vx", "vy", "yaw_rate", "vz", "z_min", "energy")
        for v, n in enumerate(self.names):
            p = self._pose(v)
            rest[v] = [p[0], p[1], p[3]]
            final[v] = [p[6], p[7], p[8]]
            arr = np.array(self.traj[v], dtype=float)
            trajectories[n] = {k: arr[:, c].copy() for c, k in enumerate(keys)}
        if not np.all(np.isfinite(rest)):
            ok = False
            warnings.append("the state became NaN")
        mass = np.array([it["mass"].sum() for it in self.items])
        heads = [(trajectories[n]["t"], trajectories[n]["heading"]) for n in self.names]
        rows = EP.impact_rows(self.names, mass, self.IMP[:min(self.n_episodes, len(self.IMP))].copy(),
                              struck_compliance(vs.spec for vs in self.scene.vehicles), heads)
        if any(r["open"] for r in rows):
            warnings.append("a contact was still active at the end of the run")
        warnings += contact_report.row_warnings(self.scene, rows, dict(zip(self.names, mass)))
        if self.n_unsettled:
            ok = False
            warnings.append(f"the contact loads did not settle at the shortest step ({o['min_step']:g} s) in "
                            f"{self.n_unsettled} step(s)")
        if self.n_episodes > len(self.IMP):  # later episodes would be missing from the table and the guard
            ok = False
            warnings.append(f"more than {len(self.IMP)} contact episodes: the run cannot report them all")
        try:
            it = mbs.sys["dynamicSolver"].it
            newton, disc = int(it.newtonStepsCount), int(it.discontinuousIterationsCount)
        except Exception:  # the solver's statistics are a convenience; their layout is not a stable API
            newton = disc = -1
        fz = exu.OutputVariableType.ForceLocal
        loads = {n: [float(mbs.GetObjectOutput(d, fz)[2]) for d in self.items[v]["discs"]]
                 for v, n in enumerate(self.names)}
        diagnostics = {"steps": self.nsteps, "wheel_loads_final": loads, "wheel_order": list(CORNERS),
                       "step_size": self.o["step"], "min_step_used": self.h_min_used,
                       "newton_iterations": newton, "discontinuous_iterations": disc,
                       "load_iterations": self.n_load_iter, "rejected_steps": self.n_shortened,
                       "t_end": t_end, "episodes": self.n_episodes,
                       "road_contacts": self.road_contacts, "max_road_penetration": self.road_pen,
                       "max_onset_penetration": self.max_onset,
                       # the largest overlap of the undeformed shapes in contact, the dynamic crush under the
                       # structure law (S_MAXPEN of the episodes, as multibody), not G_DEL: that is the crush
                       # beyond the permanent set, only the elastic part (0.02 m of NHTSA 10146's 0.56 m)
                       "max_penetration": float(self.IMP[:min(self.n_episodes, len(self.IMP)), EP.I_MAXPEN].max(
                           initial=0.0)),
                       "vehicle_notes": {n: self.vehs[v].notes for v, n in enumerate(self.names)},
                       "solver": "exudyn generalized-alpha (index 3), adaptive step, trapezoidal contact loads"}
        wall = time.perf_counter() - t0
        out = Outcome(self.names, rest, final, self.contact, self.contact_time, trajectories, rows, diagnostics,
                      warnings, ok, "exudyn", wall, contact_intervals=sorted(self.intervals))
        if ok and overlap is not None:
            out.fail("interpenetration", overlap)
        return out

