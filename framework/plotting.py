"""Figures: the top view of a simulated scene."""
from __future__ import annotations

import numpy as np

from .scene import barrier_outline, vehicle_outline
from .units import deg_to_rad


def top_view(scene, outcome, path, title=None, measured=None):
    """Outlines at start (dotted), at first contact (dashed) and at rest (solid), and CG paths.
    `measured`: optional {vehicle: (x, y, heading_deg)} drawn in grey (evidence)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 6))
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for i, v in enumerate(scene.vehicles):
        c = colours[i % len(colours)]
        poses = [((v.x, v.y, v.heading), ":", "start")]
        fc = outcome.contact_si[i]
        if not np.isnan(fc[0]):
            poses.append(((fc[0], fc[1], fc[2]), "--", "first contact"))
        if outcome.outcome_ok:
            r = outcome.rest_si[i]
            poses.append(((r[0], r[1], r[2]), "-", "rest"))
        for (x, y, h), ls, label in poses:
            poly = vehicle_outline(v, x, y, h)
            poly = np.vstack([poly, poly[:1]])
            ax.plot(poly[:, 0], poly[:, 1], ls, color=c, label=f"{v.name} {label}")
            ax.arrow(x, y, 0.6 * np.cos(h), 0.6 * np.sin(h), color=c, head_width=0.12, length_includes_head=True)
        if v.name in getattr(outcome, "_trajectories", {}):
            tr = outcome._trajectories[v.name]
            ax.plot(tr["x"], tr["y"], "-", color=c, lw=0.8, alpha=0.6)
        if measured and v.name in measured:
            mx, my, mh = measured[v.name]
            if mh is None:  # a measured position without heading: a cross
                ax.plot([mx], [my], "x", color="0.4", ms=10, mew=2, label=f"{v.name} measured")
                continue
            poly = vehicle_outline(v, mx, my, deg_to_rad(mh))
            poly = np.vstack([poly, poly[:1]])
            ax.plot(poly[:, 0], poly[:, 1], "-", color="0.5", lw=2, alpha=0.6, label=f"{v.name} measured")
    for b in scene.barriers:
        poly = barrier_outline(b)
        ax.fill(poly[:, 0], poly[:, 1], color="0.3")
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title(title or f"{scene.name} ({outcome.model})")
    ax.legend(fontsize=7, loc="best")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
