"""Figures: the top view of a simulated scene, speed, distance and heading against time, and the drawing
helpers the other figures share (crashlab.tools.animation, the Monte Carlo figure): the road (friction zones
and road lines), barriers, the point of impact, a scale bar."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..scene import barrier_outline, vehicle_outline
from ..units import deg_to_rad, length_axes_in, ms_to_kmh, unit_in, us_factor, value_in, wrap_deg


def check_plot_path(path, key: str = "--plot") -> Path:
    """The path of a figure as a Path when its extension names a format matplotlib writes (.png, .pdf, .svg, ...),
    and it can be written (outdir.check_output_file); otherwise crashlab.InputError naming the path and `key` (the
    CLI checks before the run: a name without an extension is refused, as --animate refuses one, not written as
    NAME.png)."""
    from matplotlib.backend_bases import FigureCanvasBase

    from ..errors import InputError
    from ..outdir import check_output_file
    path = Path(path)
    ext = path.suffix.lower()
    formats = sorted(FigureCanvasBase.get_supported_filetypes())
    if ext[1:] not in formats:
        raise InputError(str(path), key, f"a figure is written as .png, .pdf, .svg or another format matplotlib "
                         f"writes ({', '.join(formats)}), not {ext or 'no extension'!r}")
    return check_output_file(path, key)


def _arrow(ax, x, y, h, length, colour, **kw):
    ax.annotate("", xy=(x + length * np.cos(h), y + length * np.sin(h)), xytext=(x, y),
                arrowprops=dict(arrowstyle="-|>", color=colour, lw=kw.get("lw", 1.5), alpha=kw.get("alpha", 1.0),
                                shrinkA=0, shrinkB=0, mutation_scale=12))


def draw_zones(ax, road):
    """Friction zones shaded (darker for lower friction) and named with their friction."""
    for z in road.zones:
        poly = np.asarray(z.polygon + z.polygon[:1])
        shade = 0.55 + 0.4 * min(z.friction / max(road.friction, 1e-9), 1.0)
        ax.fill(poly[:, 0], poly[:, 1], color=(shade, shade, 1.0), alpha=0.6, zorder=0)
        ax.text(*poly[:-1].mean(axis=0), f"{z.name} (mu {z.friction:g})", ha="center", va="center", fontsize=7,
                color="0.25", zorder=0)


# how each kind of road line is drawn (colour, width, default style); a line's own `style` replaces the style
ROAD_LINE_LOOK = {"edge": ("0.15", 1.6, "solid"), "kerb": ("0.35", 3.0, "solid"),
                  "lane": ("0.45", 1.0, "dashed"), "centre": ("darkgoldenrod", 1.4, "dashed")}
_LINESTYLE = {"solid": "-", "dashed": (0, (6, 4)), "dotted": ":"}


def draw_road_lines(ax, road, legend: bool = True):
    """The road's lines (edges, kerbs, lane markings, centre lines: crashlab.scene.RoadLine) under everything
    else, one LineCollection each, added without widening the view (the vehicles set it); one legend entry
    per kind drawn (legend=False: none)."""
    from matplotlib.collections import LineCollection
    shown = set()
    for line in getattr(road, "lines", ()):
        colour, width, style = ROAD_LINE_LOOK[line.kind]
        label = f"road {line.kind}" if legend and line.kind not in shown else None
        shown.add(line.kind)
        ax.add_collection(LineCollection([np.asarray(line.points, dtype=float)], colors=colour, linewidths=width,
                                         linestyles=_LINESTYLE[line.style or style], zorder=0.5, label=label),
                          autolim=False)


def draw_road(ax, road, legend: bool = True):
    """The road under a top view: its friction zones shaded, then its lines."""
    draw_zones(ax, road)
    draw_road_lines(ax, road, legend)


def draw_barriers(ax, barriers):
    """Barriers filled dark grey."""
    for b in barriers:
        poly = barrier_outline(b)
        ax.fill(poly[:, 0], poly[:, 1], color="0.3")


def vehicle_colours() -> list:
    """One colour per vehicle, in scene order (cycled): the same in every figure."""
    import matplotlib.pyplot as plt
    return plt.rcParams["axes.prop_cycle"].by_key()["color"]


def _action_marks(ax, v, tr, colour):
    """A marker on the CG path where each driver action starts, labelled with what it sets."""
    t = np.asarray(tr["t"])
    for a in v.actions:
        if not len(t) or a.t > t[-1]:
            continue
        x, y = np.interp(a.t, t, tr["x"]), np.interp(a.t, t, tr["y"])
        what = [s for s in (a.wheels, None if a.brake is None else f"brake {a.brake:g}",
                            None if a.steer is None else f"steer {np.degrees(a.steer):.1f} deg") if s]
        ax.plot([x], [y], "v", color=colour, ms=7, mec="k", mew=0.5)
        ax.annotate(f"{a.t:g} s: {', '.join(what)}", (x, y), textcoords="offset points", xytext=(4, 6),
                    fontsize=7, color=colour)


def pose_text(outcome, i: int, system: str = "si") -> str:
    """'rest' or 'end pose (moving N km/h)' for vehicle i (Outcome.pose_label), the speed in `system`'s unit."""
    if outcome.at_rest_mask[i]:
        return "rest"
    return f"end pose (moving {value_in(ms_to_kmh(outcome.end_speed_si[i]), 'km/h', system):.1f} " \
           f"{unit_in('km/h', system)})"


def top_view(scene, outcome, path, title=None, measured=None, system: str = "si"):
    """Outlines at start (dotted), at first contact (dashed) and at the end (solid: 'rest', or 'end pose
    (moving N km/h)' for a vehicle still moving), CG paths, and a heading arrow on every pose, one colour
    per vehicle. `measured`: optional {vehicle: (x, y, heading_deg or None)}, the evidence, drawn thick
    and pale in the vehicle's colour with its heading arrow (a cross where no heading was measured);
    the legend gives simulated and measured end headings. `system` "us": axes, scale bar and labels in ft and
    mph (the drawing stays in m: crashlab.units.length_axes_in)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 6))
    colours = vehicle_colours()
    draw_road(ax, scene.road)
    for i, v in enumerate(scene.vehicles):
        c = colours[i % len(colours)]
        arrow_len = 0.8 * v.spec.cg_to_front
        poses = [((v.x, v.y, v.heading), ":", "start")]
        fc = outcome.contact_si[i]
        if not np.isnan(fc[0]):
            poses.append(((fc[0], fc[1], fc[2]), "--", "first contact"))
        r = outcome.rest_si[i]
        if outcome.outcome_ok and np.all(np.isfinite(r)):
            heading = wrap_deg(np.degrees(r[2]))  # the wrapped pose (-180, 180]; the turn is in the tables
            poses.append(((r[0], r[1], r[2]), "-", f"{pose_text(outcome, i, system)}, heading {heading:.1f} deg"))
        for (x, y, h), ls, label in poses:
            poly = vehicle_outline(v, x, y, h)
            poly = np.vstack([poly, poly[:1]])
            ax.plot(poly[:, 0], poly[:, 1], ls, color=c, label=f"{v.name} {label}")
            _arrow(ax, x, y, h, arrow_len, c)
        tr = getattr(outcome, "trajectories", None) or getattr(outcome, "_trajectories", {})
        if v.name in tr:
            ax.plot(tr[v.name]["x"], tr[v.name]["y"], "-", color=c, lw=0.8, alpha=0.6)
            _action_marks(ax, v, tr[v.name], c)
        if measured and v.name in measured:
            mx, my, mh = measured[v.name]
            if mh is None:  # a measured position without heading: a cross
                ax.plot([mx], [my], "x", color=c, ms=10, mew=2, alpha=0.6, label=f"{v.name} measured (no heading)")
                continue
            poly = vehicle_outline(v, mx, my, deg_to_rad(mh))
            poly = np.vstack([poly, poly[:1]])
            mh_w = wrap_deg(mh)
            ax.plot(poly[:, 0], poly[:, 1], "-", color=c, lw=3, alpha=0.35,
                    label=f"{v.name} measured, heading {mh_w:.1f} deg")
            _arrow(ax, mx, my, deg_to_rad(mh), arrow_len, c, lw=3, alpha=0.45)
    draw_barriers(ax, scene.barriers)
    point_of_impact(ax, outcome, system)
    length_axes(ax, system)
    _finish(fig, ax, title or f"{scene.name} ({outcome.model})", path)


def length_axes(ax, system: str = "si"):
    """A top view's axes: x, y in m (ticks and labels in ft with system "us": crashlab.units.length_axes_in)
    and a scale bar of a round length in the same unit."""
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    length_axes_in(ax, system)
    scale_bar(ax, system)


def _finish(fig, ax, title, path):
    """Equal scale, the title, the legend beside the drawing (never over it); saved and closed (the axes'
    labels and scale bar: length_axes)."""
    ax.set_aspect("equal")
    ax.set_title(title)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    Path(path).parent.mkdir(parents=True, exist_ok=True)  # (outdir.check_output_file: missing folders are made)
    fig.savefig(path, dpi=120, bbox_inches="tight")
    import matplotlib.pyplot as plt
    plt.close(fig)


def point_of_impact(ax, outcome, system: str = "si"):
    """The first impact's point (a star, its coordinates in `system`'s length unit) and its contact plane (a
    line through it, 2 m long)."""
    rows = outcome.impact_rows if outcome.outcome_ok else []
    if not rows:
        return
    r = min(rows, key=lambda row: row["t"])
    px, py, th = r["point_x"], r["point_y"], r.get("plane_angle", np.nan)
    ax.plot([px], [py], "*", color="k", ms=12, mfc="yellow", zorder=5,
            label=f"point of impact ({value_in(px, 'm', system):.2f}, {value_in(py, 'm', system):.2f}) "
                  f"{unit_in('m', system)}, t = {r['t']:.3f} s")
    if np.isfinite(th):
        ax.plot([px - np.cos(th), px + np.cos(th)], [py - np.sin(th), py + np.sin(th)], "-", color="k", lw=1.2,
                zorder=5, label="contact plane")


def scale_bar(ax, system: str = "si"):
    """A scale bar of a round length (1, 2, 5 x 10^k m, or ft with system "us", about a fifth of the view) in
    the lower left of a drawing in m."""
    x0, x1 = ax.get_xlim()
    y0, y1 = ax.get_ylim()
    per_unit = us_factor("m") if system == "us" else 1.0  # m per shown length unit
    target = (x1 - x0) / 5.0 / per_unit
    k = 10.0 ** np.floor(np.log10(target))
    length = max(m * k for m in (1, 2, 5) if m * k <= target)
    bx, by = x0 + 0.04 * (x1 - x0), y0 + 0.05 * (y1 - y0)
    ax.plot([bx, bx + length * per_unit], [by, by], "-", color="k", lw=3, solid_capstyle="butt", zorder=6)
    ax.text(bx + length * per_unit / 2, by + 0.015 * (y1 - y0), f"{length:g} {unit_in('m', system)}", ha="center",
            va="bottom", fontsize=8, zorder=6)


def compare_view(scene, outcomes: dict, path, title=None, system: str = "si"):
    """Every model's run in one top view (`crashlab compare --plot`): one colour per model, one line style
    per vehicle; start outlines grey and dotted, CG paths, end outlines with heading arrows in the model's
    colour (a failed run: its path up to where it stopped, no end pose), each reference's published rest
    poses thick and pale grey with heading arrows; zones, barriers, scale bar, the legend beside the drawing;
    `system` "us": axes, scale bar and labels in ft and mph."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 6))
    colours = vehicle_colours()
    styles = ["-", "--", "-.", ":"]
    draw_road(ax, scene.road)
    draw_barriers(ax, scene.barriers)
    for v in scene.vehicles:
        poly = vehicle_outline(v)
        poly = np.vstack([poly, poly[:1]])
        ax.plot(poly[:, 0], poly[:, 1], ":", color="0.45", lw=1.0)
        _arrow(ax, v.x, v.y, v.heading, 0.8 * v.spec.cg_to_front, "0.45", lw=1.0)
        ax.annotate(v.name, (v.x, v.y), textcoords="offset points", xytext=(-4, -12), fontsize=8, color="0.3")
    for m, (model, out) in enumerate(outcomes.items()):
        c = colours[m % len(colours)]
        for i, v in enumerate(scene.vehicles):
            ls = styles[i % len(styles)]
            tr = out.trajectories.get(v.name)
            label = f"{model}: {v.name}"
            if tr is not None and len(tr["t"]):
                ax.plot(tr["x"], tr["y"], ls, color=c, lw=1.0, alpha=0.8)
            r = out.rest_si[i]
            if not (out.outcome_ok and np.all(np.isfinite(r))):
                ax.plot([], [], ls, color=c, label=f"{label} failed, no end pose")
                continue
            poly = vehicle_outline(v, *r)
            poly = np.vstack([poly, poly[:1]])
            ax.plot(poly[:, 0], poly[:, 1], ls, color=c, lw=1.6,
                    label=f"{label} {pose_text(out, i, system)}, heading {wrap_deg(np.degrees(r[2])):.1f} deg")
            _arrow(ax, r[0], r[1], r[2], 0.8 * v.spec.cg_to_front, c)
    greys = ["0.2", "0.5", "0.7"]
    by_name = {v.name: v for v in scene.vehicles}
    for k, (src, per_vehicle) in enumerate(scene.references.items()):
        g = greys[k % len(greys)]
        for name, ref in per_vehicle.items():
            v = by_name.get(name)
            if v is None or not all(key in ref for key in ("x", "y", "heading")):
                continue
            h = deg_to_rad(ref["heading"])
            poly = vehicle_outline(v, ref["x"], ref["y"], h)
            poly = np.vstack([poly, poly[:1]])
            ax.plot(poly[:, 0], poly[:, 1], "-", color=g, lw=3, alpha=0.45,
                    label=f"{src}: {name}, heading {wrap_deg(ref['heading']):.1f} deg")
            _arrow(ax, ref["x"], ref["y"], h, 0.8 * v.spec.cg_to_front, g, lw=3, alpha=0.5)
    length_axes(ax, system)
    _finish(fig, ax, title or f"{scene.name}: " + ", ".join(outcomes), path)


def distance_travelled(x, y) -> np.ndarray:
    """m, the length of the CG path from its first sample to each sample (cumulative sum of the chords)."""
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    return np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(x), np.diff(y)))]) if len(x) else np.empty(0)


def time_histories(scene, outcome, path, title=None, system: str = "si"):
    """Speed [km/h], distance travelled [m] and heading [deg, continuous] of every vehicle's CG against time
    [s], from the outcome's recorded trajectories, one colour per vehicle as in the top views; each impact a
    vertical line. `system` "us": speed in mph, distance in ft (crashlab.units.value_in). Raises ValueError
    when the outcome recorded no trajectories (a batch run)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    tr = outcome.trajectories or {}
    if not any(len(tr.get(v.name, {}).get("t", ())) for v in scene.vehicles):
        raise ValueError(f"model {outcome.model!r} recorded no trajectories to plot")
    colours = vehicle_colours()
    fig, axes = plt.subplots(3, 1, figsize=(8, 7), sharex=True)
    for i, v in enumerate(scene.vehicles):
        t = tr.get(v.name)
        if t is None or not len(t["t"]):
            continue
        c = colours[i % len(colours)]
        speed = value_in(ms_to_kmh(np.hypot(t["vx"], t["vy"])), "km/h", system)
        axes[0].plot(t["t"], speed, color=c, label=v.name)
        axes[1].plot(t["t"], value_in(distance_travelled(t["x"], t["y"]), "m", system), color=c, label=v.name)
        axes[2].plot(t["t"], np.degrees(np.asarray(t["heading"], dtype=float)), color=c, label=v.name)
    times = sorted({round(r["t"], 9) for r in outcome.impact_rows}) if outcome.outcome_ok else []
    for ax in axes:
        for k, ti in enumerate(times):
            ax.axvline(ti, color="k", lw=0.8, ls="--", label="impact" if k == 0 and ax is axes[0] else None)
        ax.grid(alpha=0.3)
    axes[0].set_ylabel(f"speed [{unit_in('km/h', system)}]")
    axes[1].set_ylabel(f"distance travelled [{unit_in('m', system)}]")
    axes[2].set_ylabel("heading [deg]")
    axes[2].set_xlabel("t [s]")
    axes[0].legend(fontsize=8, loc="upper right")
    axes[0].set_title(title or f"{scene.name} ({outcome.model}): speed, distance and heading against time")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
