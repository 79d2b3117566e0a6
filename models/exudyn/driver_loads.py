"""The drivers' inputs and the wheel moments of one exudyn step (docs/physics.md §2a, common/driver_inputs.py,
common/tyre_moments.py): spin locks, steer, brake fraction, the road friction under each wheel, rolling
resistance and brake moments."""
from __future__ import annotations

import math

import numpy as np

from crashlab.models.common import driver_inputs as DI
from crashlab.models.common.tyre_moments import OMEGA_BRAKE, brake_moment, rolling_resistance_moment
from crashlab.models.common.vehicle_3d import NW, steer_angles
from crashlab.models.common.wheel_states import BRAKED, LOCKED

FY_LOCAL = 0           # the lateral component of the rolling disc's ForceLocal (x lateral, y forward, z normal)


class DriverLoads:
    """The driver inputs and wheel torques of ExudynRun's steps (a mixin: it uses the run's attributes)."""

    def _driver(self, s, t):
        """Driver actions and friction zones for the step [s, t] (docs/physics.md §2a), read at its middle
        from common/driver_inputs: the wheel state (locked_after_impact through effective_mode with the
        vehicle's first contact) switches the spin locks, the steer angle turns the knuckles (Ackermann angles
        of vehicle_3d.steer_angles), the brake fraction goes to _wheel_torques; each wheel's road friction
        is that of the zones at its contact point half a step on (the predicted middle of the step), set as
        the rolling disc's dry friction and held over the step."""
        tm = 0.5 * (s + t)
        for v in self.driven:
            it = self.items[v]
            # without actions the wheel state changes at most once, at the first contact
            if not self.timed[v] and self.struck[v] == self.struck_seen[v]:
                continue
            self.struck_seen[v] = self.struck[v]
            mode, b, st = DI.driver_inputs(self.AT[v], self.nAT[v], tm)
            mode = DI.effective_mode(mode, self.struck[v])
            self.mode[v], self.brake[v] = mode, b
            lock = mode == LOCKED
            if it["locks"] and lock != self.locked[v]:
                self.set_locks(self.mbs, it, lock)
                self.locked[v] = lock
            if st != self.steer_now[v]:
                self.steer(self.mbs, it, steer_angles(self.vehs[v], st))
                self.steer_now[v] = st
        if self.zones is None:
            return
        out = self.exu.OutputVariableType
        g = self.mbs.GetNodeOutput
        mu_road = self.scene.road.friction
        for v in range(self.nv):
            it = self.items[v]
            for k in range(NW):
                nw = it["wheels"][k]["nodeNumber"]
                r, vel = g(nw, out.Position), g(nw, out.Velocity)
                mu = DI.road_friction(r[0] + vel[0] * (t - s) / 2, r[1] + vel[1] * (t - s) / 2, mu_road,
                                      *self.zones)
                if mu != self.mu_wheel[v, k]:
                    self.mbs.SetObjectParameter(it["discs"][k], "dryFriction", [mu, mu])
                    self.mu_wheel[v, k] = mu

    def _wheel_torques(self, mbs):
        """Rolling resistance and brake moments (common/tyre_moments.py) against the wheel's spin relative to
        its knuckle, with the tyre's radius as the arm, held over the step. `braked`: the UA tyre's brake
        moment (eta of the locking torque, as before actions existed); a brake fraction b on a rolling wheel
        (§2a): b times the friction left beside the lateral force, b R sqrt((mu F_z)^2 - F_y^2), the rolling
        resistance its floor."""
        if not self.wheel_torques:
            return
        out = self.exu.OutputVariableType
        g = self.mbs.GetNodeOutput
        for v, k, fr, eta, radius, tw, tk in self.wheel_torques:
            it = self.items[v]
            mode, b = self.mode[v], self.brake[v]
            if self.locked[v] or (fr == 0.0 and mode != BRAKED and b == 0.0):
                M = np.zeros(3)
            else:
                mu = self.mu_wheel[v, k]
                nw, nk = it["wheels"][k]["nodeNumber"], it["knuckles"][k]["nodeNumber"]
                Aw = np.asarray(g(nw, out.RotationMatrix)).reshape(3, 3)
                axis = Aw[:, 1]
                w_rel = float((np.asarray(g(nw, out.AngularVelocity)) - np.asarray(g(nk, out.AngularVelocity)))
                              @ axis)
                f = mbs.GetObjectOutput(it["discs"][k], out.ForceLocal)
                fz = max(float(f[2]), 0.0)
                m = rolling_resistance_moment(fr, fz, radius, w_rel)
                if mode == BRAKED:
                    m += brake_moment(eta, mu, fz, radius, w_rel)
                elif b > 0.0:
                    fy = float(f[FY_LOCAL])
                    mb = brake_moment(b, 1.0, math.sqrt(max((mu * fz) ** 2 - fy * fy, 0.0)), radius, w_rel)
                    # the share of the brake moment that decelerates the wheel's own spin, I_yy a_fwd / R
                    # (a_fwd: the hub's acceleration over the last step): the road force is then b times the
                    # friction left, not 2 % less (a Clio wheel's I_yy / R^2 = 4.7 kg)
                    vel = np.asarray(g(nw, out.Velocity))
                    fwd = np.cross(axis, (0.0, 0.0, 1.0))
                    dt = self.s_cur - self.t_hub[v, k]     # a hub velocity of the previous step only
                    a_fwd = float((vel - self.v_hub[v, k]) @ fwd) / dt if 0.0 < dt <= 1.5 * self.o["step"] else 0.0
                    self.v_hub[v, k], self.t_hub[v, k] = vel, self.s_cur
                    mb += self.vehs[v].BODY[5 + k, 2] * a_fwd / radius * math.tanh(abs(w_rel) / OMEGA_BRAKE)
                    m = mb if abs(mb) > abs(m) else m
                M = m * axis
            mbs.SetLoadParameter(tw, "loadVector", M.tolist())
            mbs.SetLoadParameter(tk, "loadVector", (-M).tolist())
