"""The model-independent result of one simulation.

Models fill it with SI numpy arrays; the public tables (pandas, reconstructionist's units) are built
on first access, so a batch of thousands of outcomes inside an optimisation stays cheap.
"""
from __future__ import annotations

import math

import numpy as np

from .diagnostics import Diagnostics
from .restitution import V_MIN
from .units import json_number, ms_to_kmh, rad_to_deg

# A vehicle is at rest at the end when its CG moves slower than REST_SPEED and it turns slower than
# REST_YAW_RATE (docs: 0.1 m/s = 0.36 km/h, well below what a reconstructionist reads off a rest pose)
REST_SPEED = 0.1  # m/s
REST_YAW_RATE = 0.1  # rad/s

IMPACT_COLUMNS = ["t", "vehicle", "other", "dvx", "dvy", "delta_v", "d_yaw_rate", "energy", "ees",
                  "pdof", "pdof_clock", "side", "kind", "slip_reversed", "point_x", "point_y", "plane_angle"]
# units of the impact table's columns (printed headers)
# units of Outcome.trajectory's columns (file units)
TRAJECTORY_UNITS = {"t": "s", "x": "m", "y": "m", "heading": "deg", "vx": "km/h", "vy": "km/h", "yaw_rate": "deg/s",
                    "z": "m", "roll": "deg", "pitch": "deg"}
IMPACT_UNITS = {"t": "s", "dvx": "km/h", "dvy": "km/h", "delta_v": "km/h", "d_yaw_rate": "deg/s", "energy": "J",
                "ees": "km/h", "pdof": "deg", "pdof_clock": "h", "point_x": "m", "point_y": "m", "plane_angle": "deg",
                "crush": "m", "peak_force": "N", "duration": "s"}
# columns of the impact table after IMPACT_COLUMNS where a model's rows carry them (the continuous-contact models:
# the vehicle's crush [m], the pair's peak normal force [N], the contact's duration [s] and its restitution, the
# rebound ratio of the normal velocities at the point; pymunk the duration)
CONTACT_COLUMNS = ["crush", "peak_force", "duration", "restitution"]


# an impact row's kind for the contact of a pair that outlasts its impact's pulse (one car pushing the other; every
# model, docs/physics.md §5, §15): it continues its impact's episode, it is no impact of its own. A contact episode
# lasts until the pair is SEPARATION [m] apart (a re-touch before continues it); its contact later than PUSH_TIME
# [s] after the impact is the push (a collision's pulse lasts about 0.1-0.2 s: NHTSA 10146's maximum crush at 74 ms)
PUSH = "push"
PUSH_TIME = 0.3
SEPARATION = 0.05
# m/s: a re-touch later than PUSH_TIME (or within a push) closing this fast or faster, whose impulse changes the
# pair's relative velocity by as much, is a re-impact with an impact row of its own, not the push (a struck car's
# flank swinging back into the other; the 3D and impulse models, docs/physics.md §15 "Re-impacts"): the least
# closing speed of the staged collisions the restitution law's data hold (Cipriani et al. 2002,
# crashlab.restitution.V_MIN)
REIMPACT_SPEED = V_MIN
# m/s: a push whose impulse changes the pair's relative velocity by less than this (0.1 km/h, the resolution crash
# tests report delta-V at) writes no row: its impulse acts, but a row would be noise (once places never crushed
# bear, 2026-11-28, light touches at rest gave push rows of 0.1-9 N s: 42 of exudyn's 250 rows on 90 random scenes)
PUSH_DV_MIN = 0.1 / 3.6


def collision_rows(rows) -> list[dict]:
    """The impact rows of impacts: every row but a push's (PUSH)."""
    return [r for r in rows if r["kind"] != PUSH]


def at_rest(final: np.ndarray) -> np.ndarray:
    """(..., nv) at rest at the end from the final velocities (..., nv, 3: vx, vy, yaw rate): speed <=
    REST_SPEED and |yaw rate| <= REST_YAW_RATE."""
    return (np.hypot(final[..., 0], final[..., 1]) <= REST_SPEED) & (np.abs(final[..., 2]) <= REST_YAW_RATE)


def pdof_clock(pdof_deg: float) -> float:
    """The PDOF as the SAE J224 clock direction, 1-12 hours: 12 = force from straight ahead, 3 = from the
    right, 9 = from the left (clockwise; crashlab's pdof counts counter-clockwise, docs/physics.md §21)."""
    if not math.isfinite(pdof_deg):
        return math.nan
    hour = round((-pdof_deg) % 360.0 / 30.0) % 12
    return 12 if hour == 0 else hour


class Outcome:
    """Result of `model.simulate(scene)`.

    rest_si: (n, 3) x [m], y [m], heading [rad] (continuous), final_si: (n, 3) vx, vy [m/s], yaw rate
    [rad/s]; contact_si: (n, 4) x, y, heading, speed at first contact (NaN without contact);
    trajectories: name -> dict of SI arrays (t, x, y, heading, vx, vy, yaw_rate, optional z, roll, pitch
    and z_min, the lowest point of a 3D vehicle's body above the road, energy, its full mechanical energy [J]);
    impact_rows: list of dicts in SI (see `impacts`; each also carries crush_energy [J], the vehicle's share of
    the energy, docs/physics.md §21), or a picklable callable returning it (built on
    first access, so batch runs that only need rest poses do not pay for it);
    impact_energy: optional array of the energy dissipated per impact [J] (the guard reads it without
    building the rows); contact_intervals: optional list of (t_start, t_end) [s] during which any
    contact acted (an impulse is (t, t)); without it the impact rows' t (+ duration) are used.
    `violations` lists the kinds of physics-guard violations (crashlab.guard); `rolled_over` the vehicles
    that end upside down or on their side; `guarded` True once the guard has checked it (it checks it again
    each time a model returns it: nothing trusts the flag).
    """

    def __init__(self, names, rest_si, final_si=None, contact_si=None, contact_time=math.nan,
                 trajectories=None, impact_rows=(), diagnostics=None, warnings=(), ok=True,
                 model="", wall_time_s=0.0, contact_intervals=None, impact_energy=None):
        self.names = list(names)
        self.rest_si = np.asarray(rest_si, dtype=float)
        n = len(self.names)
        # final velocities unknown are not zero: a model that does not report them gets no rest pose
        self.final_si = np.full((n, 3), np.nan) if final_si is None else np.asarray(final_si, dtype=float)
        self.contact_si = np.full((n, 4), np.nan) if contact_si is None else np.asarray(contact_si, float)
        self.contact_time = contact_time
        self._trajectories = trajectories or {}
        self._impact_rows = impact_rows if callable(impact_rows) else list(impact_rows)
        self.diagnostics = Diagnostics.of(diagnostics)
        if self.diagnostics.wall_time_s is None:  # (a model's own diagnostics may carry it)
            self.diagnostics.wall_time_s = wall_time_s
        self.warnings = list(warnings)
        self.outcome_ok = bool(ok)
        self.model = model
        self.contact_intervals = None if contact_intervals is None else [tuple(c) for c in contact_intervals]
        self._impact_energy = None if impact_energy is None else np.asarray(impact_energy, dtype=float)
        self.violations: list[str] = []
        self.rolled_over: list[str] = []
        self.guarded = False

    @property
    def wall_time_s(self) -> float:
        """Wall-clock time of the simulation [s]: diagnostics.wall_time_s (one home)."""
        return self.diagnostics.wall_time_s

    @wall_time_s.setter
    def wall_time_s(self, value: float) -> None:
        self.diagnostics.wall_time_s = value

    def fail(self, kind: str, reason: str) -> None:
        """Mark the outcome failed by a physics check: outcome_ok False, the reason in warnings."""
        self.outcome_ok = False
        self.violations.append(kind)
        self.warnings.append(f"physics guard: {kind}: {reason}")

    @classmethod
    def failed(cls, names, reason: str, model: str = "", wall_time_s: float = 0.0) -> Outcome:
        n = len(names)
        return cls(names, np.full((n, 3), np.nan), np.full((n, 3), np.nan), ok=False, warnings=[reason],
                   model=model, wall_time_s=wall_time_s)

    @property
    def impact_rows(self) -> list:
        if callable(self._impact_rows):
            self._impact_rows = list(self._impact_rows())
        return self._impact_rows

    @property
    def impact_energy(self) -> np.ndarray:
        """Energy dissipated per impact [J] (one entry per impact, not per vehicle row)."""
        if self._impact_energy is None:
            seen, e = set(), []
            for r in self.impact_rows:
                key = (r["t"], frozenset((r["vehicle"], r["other"])))
                if key not in seen:
                    seen.add(key)
                    e.append(r["energy"])
            self._impact_energy = np.asarray(e, dtype=float)
        return self._impact_energy

    @property
    def trajectories(self) -> dict:
        """name -> dict of SI arrays (empty for batch runs that record none)."""
        return self._trajectories

    @property
    def end_speed_si(self) -> np.ndarray:
        """Speed of each vehicle's CG at the end of the run [m/s]."""
        return np.hypot(self.final_si[:, 0], self.final_si[:, 1])

    @property
    def at_rest_mask(self) -> np.ndarray:
        """Per vehicle: at rest at the end (speed <= REST_SPEED and |yaw rate| <= REST_YAW_RATE)."""
        return at_rest(self.final_si)

    def pose_label(self, i: int) -> str:
        """'rest' or 'end pose (moving N km/h)' for vehicle i."""
        if self.at_rest_mask[i]:
            return "rest"
        return f"end pose (moving {ms_to_kmh(self.end_speed_si[i]):.1f} km/h)"

    # ---------------------------------------------------------------- public tables
    @property
    def rest(self):
        """Pose at the end of the run: x, y [m], heading [deg, continuous: the start heading plus every turn
        since, so a scene's 720 plus a half turn reads 900; crashlab.units.wrap_deg gives -180..180], speed
        [km/h], at_rest (bool). A vehicle with at_rest False was still moving when the run ended: its row is
        an end pose, not a rest pose."""
        import pandas as pd
        return pd.DataFrame({"x": self.rest_si[:, 0], "y": self.rest_si[:, 1],
                             "heading": np.degrees(self.rest_si[:, 2]),
                             "speed": ms_to_kmh(self.end_speed_si), "at_rest": self.at_rest_mask},
                            index=pd.Index(self.names, name="vehicle"))

    @property
    def final(self):
        """Final velocities: vx, vy [km/h, global], yaw_rate [deg/s]."""
        import pandas as pd
        return pd.DataFrame({"vx": ms_to_kmh(self.final_si[:, 0]), "vy": ms_to_kmh(self.final_si[:, 1]),
                             "yaw_rate": np.degrees(self.final_si[:, 2])},
                            index=pd.Index(self.names, name="vehicle"))

    @property
    def first_contact(self):
        """State at first contact: x, y [m], heading [deg], speed [km/h]; NaN where nothing touched."""
        import pandas as pd
        c = self.contact_si
        return pd.DataFrame({"x": c[:, 0], "y": c[:, 1], "heading": np.degrees(c[:, 2]),
                             "speed": ms_to_kmh(c[:, 3])}, index=pd.Index(self.names, name="vehicle"))

    def trajectory(self, name: str):
        import pandas as pd
        tr = self._trajectories[name]
        df = pd.DataFrame({"t": tr["t"], "x": tr["x"], "y": tr["y"], "heading": np.degrees(tr["heading"]),
                           "vx": ms_to_kmh(tr["vx"]), "vy": ms_to_kmh(tr["vy"]),
                           "yaw_rate": np.degrees(tr["yaw_rate"])})
        for k in ("z", "roll", "pitch"):
            if k in tr:
                df[k] = np.degrees(tr[k]) if k != "z" else tr[k]
        return df

    @property
    def impacts(self):
        """One row per vehicle per impact: t [s], vehicle, other, dvx, dvy, delta_v [km/h],
        d_yaw_rate [deg/s], energy [J] (dissipated, per impact), ees [km/h], pdof [deg, counter-clockwise from
        straight ahead], pdof_clock [h, SAE J224: 12 from straight ahead, 3 from the right], side (the face it
        is struck on: front, rear, left or right, and in the 3D models a tilted car's roof or underbody, whose
        structure takes its share of the energy, docs/physics.md §21, §13a), kind
        (impulse model: full, sliding or, law routh, reversed; continuous-contact models: continuous; every model:
        push, the contact later than PUSH_TIME after the impact, one car pushing the other, §5, §15),
        slip_reversed (impulse model: the slip at the point stops and reverses in this impact, which
        the laws kudlich-slibar and brach do not follow; docs/physics.md §3), point_x, point_y [m],
        plane_angle [deg]; where the model's rows carry them (CONTACT_COLUMNS) crush [m] (the vehicle's share of the
        pair's largest crush, docs/physics.md §21), peak_force [N], duration [s], restitution (empty where it is no
        rebound ratio: a push, an approach below 0.1 m/s, a contact still open)."""
        import pandas as pd
        rows = []
        extra = [c for c in CONTACT_COLUMNS if any(c in r for r in self.impact_rows)]
        for r in self.impact_rows:
            rows.append({"t": r["t"], "vehicle": r["vehicle"], "other": r["other"],
                         "dvx": ms_to_kmh(r["dvx"]), "dvy": ms_to_kmh(r["dvy"]),
                         "delta_v": ms_to_kmh(math.hypot(r["dvx"], r["dvy"])),
                         "d_yaw_rate": rad_to_deg(r["d_yaw_rate"]), "energy": r["energy"],
                         "ees": ms_to_kmh(r.get("ees", math.nan)), "pdof": rad_to_deg(r.get("pdof", math.nan)),
                         "pdof_clock": pdof_clock(rad_to_deg(r.get("pdof", math.nan))),
                         "side": r.get("side", ""), "kind": r["kind"],
                         "slip_reversed": bool(r.get("slip_reversed", False)),
                         "point_x": r["point_x"], "point_y": r["point_y"],
                         "plane_angle": rad_to_deg(r["plane_angle"]),
                         **{c: math.nan if r.get(c) is None else float(r[c]) for c in extra}})
        return pd.DataFrame(rows, columns=IMPACT_COLUMNS + extra)

    def to_json_dict(self) -> dict:
        vehicles = {}
        speed, at_rest = self.end_speed_si, self.at_rest_mask
        for i, n in enumerate(self.names):
            vehicles[n] = {
                "rest": {"x": json_number(self.rest_si[i, 0]), "y": json_number(self.rest_si[i, 1]),
                         "heading": json_number(math.degrees(self.rest_si[i, 2])),
                         "speed": json_number(ms_to_kmh(speed[i])), "at_rest": bool(at_rest[i])},
                "pose": self.pose_label(i),
                "final_velocity": {"vx": json_number(ms_to_kmh(self.final_si[i, 0])),
                                   "vy": json_number(ms_to_kmh(self.final_si[i, 1])),
                                   "yaw_rate": json_number(math.degrees(self.final_si[i, 2]))},
            }
        impacts = [{k: (json_number(v) if isinstance(v, float) else v) for k, v in row.items()}
                   for row in self.impacts.to_dict(orient="records")]
        return {"model": self.model, "ok": self.outcome_ok, "vehicles": vehicles, "impacts": impacts,
                "warnings": self.warnings, "violations": self.violations, "rolled_over": self.rolled_over,
                "wall_time_s": round(self.wall_time_s, 6)}
