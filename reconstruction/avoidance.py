"""The figures and tables of "would it have been avoided?" (issue 28; docs/physics.md §29): the time-distance
table and diagram of one run (time_distance.csv: each vehicle's distance travelled, speed and distance to
the point of impact against time), the impact speeds of the posterior beside a counterfactual's, and top
views of a few draws with and without the change. Drawn with matplotlib (Agg); callers name a figure that
cannot be drawn instead of failing."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from crashlab.outcome import collision_rows
from crashlab.units import frame_in, unit_in, value_in

TIME_DISTANCE_CAPTION = ("each vehicle's distance to the point of impact along its CG path (positive: still to go) and "
                         "speed against time; dashed: the impacts; the numbers in time_distance.csv.")
TOP_VIEW_DRAWS = 3  # draws shown with and without each change
TOP_VIEW_COUNTERFACTUALS = 3  # counterfactuals shown beside the draws as they are
TIME_DISTANCE_UNITS = {"t": "s", "s": "m", "speed": "km/h", "to_impact": "m"}  # time_distance's columns


# ---------------------------------------------------------------- time-distance
def time_distance(outcome):
    """DataFrame (vehicle, t [s], s [m], speed [km/h], to_impact [m]) of every recorded sample of every vehicle:
    s the distance travelled along its CG path, to_impact = s(t_c) - s(t) with t_c the vehicle's first contact
    (positive before it: the distance still to go; empty without an impact). Raises ValueError without
    recorded trajectories (a batch run)."""
    import pandas as pd

    from crashlab.tools.plotting import distance_travelled
    frames = []
    rows = outcome.impact_rows
    for name in outcome.names:
        tr = (outcome.trajectories or {}).get(name)
        if tr is None or not len(tr["t"]):
            raise ValueError(f"no recorded trajectory of {name}")
        t = np.asarray(tr["t"], float)
        s = distance_travelled(tr["x"], tr["y"])
        hits = [r["t"] for r in rows if r["vehicle"] == name]
        s_c = float(np.interp(min(hits), t, s)) if hits else math.nan
        frames.append(pd.DataFrame({"vehicle": name, "t": t, "s": s,
                                    "speed": np.hypot(tr["vx"], tr["vy"]) * 3.6, "to_impact": s_c - s}))
    return pd.concat(frames, ignore_index=True)


def time_distance_figure(table, outcome, path: Path, title: str, system: str = "si") -> None:
    """Distance to the point of impact and speed against time, one colour per vehicle; dashed: the impacts;
    in US units (ft, mph) with system "us"."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from crashlab.tools.plotting import vehicle_colours
    colours = vehicle_colours()
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    for i, (name, part) in enumerate(table.groupby("vehicle", sort=False)):
        c = colours[i % len(colours)]
        top.plot(part["t"], value_in(part["to_impact"], "m", system), color=c, label=name)
        bottom.plot(part["t"], value_in(part["speed"], "km/h", system), color=c, label=name)
    for t in sorted({r["t"] for r in collision_rows(outcome.impact_rows)}):
        for ax in (top, bottom):
            ax.axvline(t, color="grey", ls="--", lw=0.8)
    top.axhline(0.0, color="black", lw=0.5)
    top.set_ylabel(f"distance to the point of impact [{unit_in('m', system)}]")
    bottom.set_ylabel(f"speed [{unit_in('km/h', system)}]")
    bottom.set_xlabel("time [s]")
    top.legend(loc="best", fontsize=8)
    top.set_title(title)
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)


def write_time_distance(outcome, out_dir: Path, title: str, system: str = "si") -> tuple[str | None, list[str]]:
    """out_dir/time_distance.csv and time_distance.png of a run: (the figure's name or None, notes); in US units
    with system "us" (the converted columns named with their unit: "speed [mph]")."""
    import matplotlib.pyplot as plt
    notes = []
    try:
        table = time_distance(outcome)
        frame_in(table, system, TIME_DISTANCE_UNITS).to_csv(Path(out_dir) / "time_distance.csv", index=False,
                                                            float_format="%.4f")
    except ValueError as err:
        return None, [f"time_distance.csv not written: {err}."]
    try:
        time_distance_figure(table, outcome, Path(out_dir) / "time_distance.png", title, system)
        return "time_distance.png", notes
    except Exception as err:  # noqa: BLE001 - the table stands without the figure
        return None, [f"time_distance.png could not be drawn ({type(err).__name__} in the plotting library)."]
    finally:
        plt.close("all")


# ---------------------------------------------------------------- the counterfactuals' figures
def impact_speed_figure(answers, names, path: Path, system: str = "si") -> None:
    """Histograms of each vehicle's speed at first contact [km/h]: the posterior's draws beside each
    counterfactual's (answers: counterfactual.Answer, the posterior first, filled grey), each labelled with its share of
    draws that still touch."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, len(names), figsize=(4.5 * len(names), 3.6), squeeze=False)
    hits = [a.pop.ok & (a.pop.n_impacts > 0) for a in answers]
    for i, (ax, name) in enumerate(zip(axes[0], names)):
        values = [value_in(a.pop.contact[h, i, 3] * 3.6, "km/h", system) for a, h in zip(answers, hits)]
        finite = np.concatenate([v[np.isfinite(v)] for v in values] + [np.zeros(0)])
        bins = np.linspace(finite.min(), finite.max() + 1e-9, 31) if len(finite) else 10
        for k, (a, h, v) in enumerate(zip(answers, hits, values)):
            style = dict(histtype="stepfilled", color="0.75") if k == 0 else dict(histtype="step", lw=1.5)
            ax.hist(v[np.isfinite(v)], bins=bins, label=f"{a.name}: touch in {int(h.sum())} of "
                    f"{int(a.pop.ok.sum())}", **style)
        ax.set_xlabel(f"{name}: speed at first contact [{unit_in('km/h', system)}]")
        ax.set_ylabel("draws")
        ax.legend(loc="best", fontsize=7)
    fig.suptitle("Impact speed: the posterior's draws and each counterfactual's")
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)


def top_views_figure(answers, path: Path, n: int = TOP_VIEW_DRAWS, system: str = "si") -> int:
    """Top views of n draws (rows) as they are and with each change (columns, at most
    TOP_VIEW_COUNTERFACTUALS): CG paths, outlines at the start (dotted), at first contact or, without one, at
    the closest approach (dashed) and at the end (solid). Returns the number of draws drawn."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from crashlab.tools.plotting import draw_road, vehicle_colours

    from . import counterfactual
    shown = answers[:1 + TOP_VIEW_COUNTERFACTUALS]
    ok = np.logical_and.reduce([a.pop.ok for a in shown])
    rows = counterfactual.subsample(np.flatnonzero(ok), n)
    colours = vehicle_colours()
    fig, axes = plt.subplots(max(len(rows), 1), len(shown), figsize=(3.6 * len(shown), 3.0 * max(len(rows), 1)),
                             squeeze=False)
    for r, k in enumerate(rows):
        for c, a in enumerate(shown):
            ax = axes[r, c]
            scene = a.pop.variants[int(k):int(k) + 1].scenes()[0]
            outcome = a.pop.outcome(int(k))
            t, poses = counterfactual.tracks(outcome)
            corners = [counterfactual.outline_corners(v.spec, p) for v, p in zip(scene.vehicles, poses)]
            hit = a.pop.n_impacts[k] > 0
            if hit:
                tc = float(np.nanmin(a.pop.first_impact_t[k]))
                moment = int(np.argmin(np.abs(t - tc)))
            else:
                gap = np.min([counterfactual.outline_distance(corners[i], corners[j])
                              for i in range(len(corners)) for j in range(i + 1, len(corners))], axis=0)
                moment = int(np.argmin(gap))
            draw_road(ax, scene.road, legend=False)
            for i in range(len(scene.vehicles)):
                col = colours[i % len(colours)]
                ax.plot(poses[i, :, 0], poses[i, :, 1], color=col, lw=0.8)
                for step, style in ((0, ":"), (moment, "--"), (-1, "-")):
                    poly = np.vstack([corners[i][step], corners[i][step][:1]])
                    ax.plot(poly[:, 0], poly[:, 1], style, color=col, lw=1.0)
            ax.set_aspect("equal")
            ax.tick_params(labelsize=6)
            what = "touch" if hit else (f"miss by {value_in(a.miss_distance[k], 'm', system):.2f} "
                                        f"{unit_in('m', system)}") if np.isfinite(a.miss_distance[k]) else "miss"
            ax.set_title(f"{a.name}, draw {int(k)}: {what}", fontsize=8)
    fig.suptitle("Draws as they are and with each change: start dotted, contact or closest approach dashed, end "
                 "solid", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=70)
    plt.close(fig)
    return len(rows)


def write_counterfactual_figures(answers, names, out_dir: Path, system: str = "si") -> tuple[list, list[str]]:
    """counterfactual_impact_speed.png and counterfactual_top_views.png: ([(file name, caption)], notes); in US
    units with system "us"."""
    import matplotlib.pyplot as plt
    figures, notes = [], []
    for name, draw, caption in (
            ("counterfactual_impact_speed.png", lambda p: impact_speed_figure(answers, names, p, system),
             "each vehicle's speed at first contact in the draws that still touch: the posterior's beside each "
             "counterfactual's (the legend gives how many of the draws touch)."),
            ("counterfactual_top_views.png", lambda p: top_views_figure(answers, p, system=system),
             "a few draws (rows) as they are and with each change (columns): CG paths, outlines at the start "
             "dotted, at first contact or the closest approach dashed, at the end solid.")):
        try:
            draw(Path(out_dir) / name)
            figures.append((name, caption))
        except Exception as err:  # noqa: BLE001 - the table stands without the figure
            notes.append(f"{name} could not be drawn ({type(err).__name__}: {err}).")
        finally:
            plt.close("all")
    return figures, notes
