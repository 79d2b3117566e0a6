"""Comparison of models with each other and with published results (PC-Crash, the thesis)."""
from __future__ import annotations

import math

import pandas as pd

from ..units import rad_to_deg, wrap_deg

# units of comparison_table's columns, printed in the headers (d_<source>_m / _deg: see comparison_units)
COMPARE_UNITS = {"x": "m", "y": "m", "heading": "deg, -180..180", "yaw_turned": "deg", "vx": "km/h", "vy": "km/h"}


def comparison_table(scene, outcomes: dict) -> pd.DataFrame:
    """One row per (source, vehicle): rest pose and final velocity of each model and each reference,
    with the differences of every model row to every reference (distance [m], wrapped heading [deg]);
    a failed run (ok False) shows where it stopped and no differences; at_rest False marks an end pose of
    a vehicle still moving when the run ended. `heading` is the pose's heading wrapped to (-180, 180] deg
    (models and references alike); `yaw_turned` [deg] is how far a model's vehicle turned from its start,
    continuous (two spins read 720 more; NaN for a reference, which gives only the pose)."""
    rows = []
    start = {v.name: rad_to_deg(v.heading) for v in scene.vehicles}
    for model, out in outcomes.items():
        rest, fin = out.rest, out.final
        for name in out.names:
            h = float(rest.at[name, "heading"])
            rows.append({"source": model, "vehicle": name, "x": rest.at[name, "x"], "y": rest.at[name, "y"],
                         "heading": wrap_deg(h), "yaw_turned": h - start[name],
                         "at_rest": bool(rest.at[name, "at_rest"]),
                         "vx": fin.at[name, "vx"], "vy": fin.at[name, "vy"], "ok": out.outcome_ok})
    for src, per_vehicle in scene.references.items():
        for name, ref in per_vehicle.items():
            rows.append({"source": src, "vehicle": name, **{k: ref.get(k, math.nan)
                                                              for k in ("x", "y", "heading", "vx", "vy")},
                         "yaw_turned": math.nan})
            rows[-1]["heading"] = wrap_deg(rows[-1]["heading"])
    df = pd.DataFrame(rows, columns=["source", "vehicle", "x", "y", "heading", "yaw_turned", "at_rest", "vx", "vy",
                                     "ok"])
    for src in scene.references:
        ref = df[df.source == src].set_index("vehicle")
        d_pos, d_head = [], []
        for _, r in df.iterrows():
            if r.source in outcomes and outcomes[r.source].outcome_ok and r.vehicle in ref.index:
                q = ref.loc[r.vehicle]
                d_pos.append(math.hypot(r.x - q.x, r.y - q.y))
                d_head.append(wrap_deg(r.heading - q.heading))
            else:
                d_pos.append(math.nan)
                d_head.append(math.nan)
        df[f"d_{src}_m"] = d_pos
        df[f"d_{src}_deg"] = d_head
    return df


def comparison_units(df: pd.DataFrame) -> dict:
    """Column -> unit of a comparison_table (the differences to a reference: d_<source>_m in m,
    d_<source>_deg in deg, wrapped to (-180, 180])."""
    units = {c: u for c, u in COMPARE_UNITS.items() if c in df}
    for c in df.columns:
        if c.startswith("d_") and c.endswith("_m"):
            units[c] = "m"
        elif c.startswith("d_") and c.endswith("_deg"):
            units[c] = "deg"
    return units


def with_unit_headers(df: pd.DataFrame) -> pd.DataFrame:
    """The table with its units in the column names for printing: 'x [m]', 'd_pc_crash [m]', ..."""
    units = comparison_units(df)

    def name(c):
        if c not in units:
            return c
        base = c[:-2] if c.endswith("_m") and c.startswith("d_") else c[:-4] if c.endswith("_deg") else c
        return f"{base.replace('_', ' ') if base == 'yaw_turned' else base} [{units[c]}]"
    return df.rename(columns={c: name(c) for c in df.columns})


def model_spread(df: pd.DataFrame, outcomes: dict) -> pd.DataFrame:
    """The spread between the models of a comparison_table: per vehicle, over every pair of models that ran
    (ok), the largest distance between their rest positions [m] and the largest wrapped heading difference [deg],
    each with the pair it belongs to; empty with fewer than two such models. The choice of model is an
    uncertainty of its own, which the evidence's sigmas do not contain."""
    ran = [m for m, out in outcomes.items() if out.outcome_ok]
    rows = []
    for name in dict.fromkeys(df["vehicle"]):
        poses = df[(df.vehicle == name) & df.source.isin(ran)].set_index("source")
        pairs = [(a, b) for i, a in enumerate(poses.index) for b in poses.index[i + 1:]]
        if not pairs:
            continue
        dist = {p: math.hypot(poses.at[p[0], "x"] - poses.at[p[1], "x"], poses.at[p[0], "y"] - poses.at[p[1], "y"])
                for p in pairs}
        head = {p: abs(wrap_deg(poses.at[p[1], "heading"] - poses.at[p[0], "heading"])) for p in pairs}
        far, turned = max(pairs, key=dist.get), max(pairs, key=head.get)
        rows.append({"vehicle": name, "models": len(poses), "distance_m": dist[far], "distance_pair": "/".join(far),
                     "heading_deg": head[turned], "heading_pair": "/".join(turned)})
    return pd.DataFrame(rows, columns=["vehicle", "models", "distance_m", "distance_pair", "heading_deg",
                                       "heading_pair"])
