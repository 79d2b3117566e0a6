"""Comparison of models with each other and with published results (PC-Crash, the thesis)."""
from __future__ import annotations

import math

import pandas as pd

from .units import wrap_deg


def comparison_table(scene, outcomes: dict) -> pd.DataFrame:
    """One row per (source, vehicle): rest pose and final velocity of each model and each reference,
    with the differences of every model row to every reference (distance [m], wrapped heading [deg]);
    a failed run (ok False) shows where it stopped and no differences; at_rest False marks an end pose of
    a vehicle still moving when the run ended."""
    rows = []
    for model, out in outcomes.items():
        rest, fin = out.rest, out.final
        for name in out.names:
            rows.append({"source": model, "vehicle": name, "x": rest.at[name, "x"], "y": rest.at[name, "y"],
                         "heading": rest.at[name, "heading"], "at_rest": bool(rest.at[name, "at_rest"]),
                         "vx": fin.at[name, "vx"], "vy": fin.at[name, "vy"], "ok": out.outcome_ok})
    for src, per_vehicle in scene.references.items():
        for name, ref in per_vehicle.items():
            rows.append({"source": src, "vehicle": name, **{k: ref.get(k, math.nan)
                                                              for k in ("x", "y", "heading", "vx", "vy")}})
    df = pd.DataFrame(rows)
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
