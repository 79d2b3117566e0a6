"""The model-independent result of one simulation.

Models fill it with SI numpy arrays; the public tables (pandas, reconstructionist's units) are built
on first access, so a batch of thousands of outcomes inside an optimisation stays cheap.
"""
from __future__ import annotations

import math

import numpy as np

from .units import ms_to_kmh, rad_to_deg

IMPACT_COLUMNS = ["t", "vehicle", "other", "dvx", "dvy", "delta_v", "d_yaw_rate", "energy", "ees",
                  "pdof", "kind", "point_x", "point_y", "plane_angle"]


class Outcome:
    """Result of `model.simulate(scene)`.

    rest_si: (n, 3) x [m], y [m], heading [rad] (continuous), final_si: (n, 3) vx, vy [m/s], yaw rate
    [rad/s]; contact_si: (n, 4) x, y, heading, speed at first contact (NaN without contact);
    trajectories: name -> dict of SI arrays (t, x, y, heading, vx, vy, yaw_rate, optional z, roll, pitch);
    impact_rows: list of dicts in SI (see `impacts`), or a picklable callable returning it (built on
    first access, so batch runs that only need rest poses do not pay for it).
    """

    def __init__(self, names, rest_si, final_si=None, contact_si=None, contact_time=math.nan,
                 trajectories=None, impact_rows=(), diagnostics=None, warnings=(), ok=True,
                 model="", wall_time_s=0.0):
        self.names = list(names)
        self.rest_si = np.asarray(rest_si, dtype=float)
        n = len(self.names)
        self.final_si = np.zeros((n, 3)) if final_si is None else np.asarray(final_si, dtype=float)
        self.contact_si = np.full((n, 4), np.nan) if contact_si is None else np.asarray(contact_si, float)
        self.contact_time = contact_time
        self._trajectories = trajectories or {}
        self._impact_rows = impact_rows if callable(impact_rows) else list(impact_rows)
        self.diagnostics = dict(diagnostics or {})
        self.warnings = list(warnings)
        self.outcome_ok = bool(ok)
        self.model = model
        self.wall_time_s = wall_time_s

    @classmethod
    def failed(cls, names, reason: str, model: str = "", wall_time_s: float = 0.0) -> Outcome:
        n = len(names)
        return cls(names, np.full((n, 3), np.nan), ok=False, warnings=[reason], model=model,
                   wall_time_s=wall_time_s)

    @property
    def impact_rows(self) -> list:
        if callable(self._impact_rows):
            self._impact_rows = list(self._impact_rows())
        return self._impact_rows

    # ---------------------------------------------------------------- public tables
    @property
    def rest(self):
        import pandas as pd
        return pd.DataFrame({"x": self.rest_si[:, 0], "y": self.rest_si[:, 1],
                             "heading": np.degrees(self.rest_si[:, 2])},
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
        d_yaw_rate [deg/s], energy [J] (dissipated, per impact), ees [km/h], pdof [deg], kind,
        point_x, point_y [m], plane_angle [deg]."""
        import pandas as pd
        rows = []
        for r in self.impact_rows:
            rows.append({"t": r["t"], "vehicle": r["vehicle"], "other": r["other"],
                         "dvx": ms_to_kmh(r["dvx"]), "dvy": ms_to_kmh(r["dvy"]),
                         "delta_v": ms_to_kmh(math.hypot(r["dvx"], r["dvy"])),
                         "d_yaw_rate": rad_to_deg(r["d_yaw_rate"]), "energy": r["energy"],
                         "ees": ms_to_kmh(r.get("ees", math.nan)), "pdof": rad_to_deg(r.get("pdof", math.nan)),
                         "kind": r["kind"], "point_x": r["point_x"], "point_y": r["point_y"],
                         "plane_angle": rad_to_deg(r["plane_angle"])})
        return pd.DataFrame(rows, columns=IMPACT_COLUMNS)

    def to_json_dict(self) -> dict:
        def num(v):
            return None if v is None or (isinstance(v, float) and math.isnan(v)) else round(float(v), 6)
        vehicles = {}
        for i, n in enumerate(self.names):
            vehicles[n] = {
                "rest": {"x": num(self.rest_si[i, 0]), "y": num(self.rest_si[i, 1]),
                         "heading": num(math.degrees(self.rest_si[i, 2]))},
                "final_velocity": {"vx": num(ms_to_kmh(self.final_si[i, 0])),
                                   "vy": num(ms_to_kmh(self.final_si[i, 1])),
                                   "yaw_rate": num(math.degrees(self.final_si[i, 2]))},
            }
        impacts = [{k: (num(v) if isinstance(v, float) else v) for k, v in row.items()}
                   for row in self.impacts.to_dict(orient="records")]
        return {"model": self.model, "ok": self.outcome_ok, "vehicles": vehicles, "impacts": impacts,
                "warnings": self.warnings, "wall_time_s": round(self.wall_time_s, 6)}
