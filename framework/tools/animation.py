"""Animation of one simulated run: `crashlab simulate SCENE --animate FILE.gif|mp4`.

    write_animation(scene, outcome, path, fps=25, speed=1.0, max_frames=300, dpi=80, title=None) -> Path

draws, frame by frame, every vehicle's outline with a heading arrow at its interpolated pose, its CG path
growing behind it, each impact flashed at its point (a large star and its time for FLASH_S of simulated
time, then a small star), the time stamp, and the road (zones and lines), barriers and scale bar as the top
view draws them (crashlab.tools.plotting). The frames sample the recorded trajectories at `animation_times`
(frame 0 is the start, the last frame the end of the run, so the last frame shows the rest or end poses of
`outcome.rest_si`). A GIF is written with Pillow; an MP4 with ffmpeg, refused in one line
(crashlab.InputError) when ffmpeg is not on PATH. Matplotlib runs headless (Agg).
"""
from __future__ import annotations

import math
import shutil
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..outdir import check_output_file
from ..scene import vehicle_outline
from ..units import length_axes_in

FORMATS = (".gif", ".mp4")
FLASH_S = 0.2  # s of simulated time an impact stays flashed (at least one frame: see animation_times)


def check_animation_path(path, key: str = "path") -> Path:
    """The path as a Path when its extension is .gif or .mp4 (and for .mp4 ffmpeg is on PATH); otherwise
    crashlab.InputError naming the path and `key` (the CLI passes '--animate')."""
    path = Path(path)
    ext = path.suffix.lower()
    if ext not in FORMATS:
        raise InputError(str(path), key, f"an animation is written as .gif or .mp4, not {ext or 'no extension'!r}")
    if ext == ".mp4" and shutil.which("ffmpeg") is None:
        raise InputError(str(path), key, "an .mp4 needs ffmpeg on PATH, which is not there; write a .gif instead")
    return check_output_file(path, key)


def animation_times(outcome, fps: float = 25.0, speed: float = 1.0, max_frames: int = 300) -> np.ndarray:
    """Simulated times [s] of the frames: equally spaced from 0 to the end of the recorded trajectories,
    `speed` simulated seconds per second of playback at `fps` frames per second (about t_end * fps / speed
    + 1 frames, at least 2), at most `max_frames` (a long run then plays faster)."""
    if not fps > 0 or not speed > 0 or max_frames < 2:
        raise ValueError(f"fps and speed must be positive and max_frames at least 2 (got {fps}, {speed}, "
                         f"{max_frames})")
    t_end = max((float(tr["t"][-1]) for tr in outcome.trajectories.values() if len(tr["t"])), default=math.nan)
    if not math.isfinite(t_end):
        raise ValueError(f"model {outcome.model!r} recorded no trajectories to animate")
    n = int(math.ceil(t_end * fps / speed - 1e-9)) + 1
    return np.linspace(0.0, t_end, min(max(n, 2), max_frames))


def frame_poses(scene, outcome, times) -> dict:
    """Vehicle name -> (len(times), 3) array of x, y [m], heading [rad, continuous] at the frame times,
    interpolated linearly in the recorded trajectory (held at its last sample after it ends); a vehicle
    without a trajectory stays at its start pose."""
    poses = {}
    for v in scene.vehicles:
        tr = outcome.trajectories.get(v.name)
        if tr is None or not len(tr["t"]):
            poses[v.name] = np.tile([v.x, v.y, v.heading], (len(times), 1))
            continue
        t = np.asarray(tr["t"], dtype=float)
        poses[v.name] = np.column_stack([np.interp(times, t, np.asarray(tr[k], dtype=float))
                                         for k in ("x", "y", "heading")])
    return poses


def _arrow_polygon(x, y, h, length, width):
    """A heading arrow from the CG (shaft and head) as a polygon."""
    c, s = math.cos(h), math.sin(h)
    shaft, half = 0.7 * length, width / 8
    local = np.array([[0, -half], [shaft, -half], [shaft, -width / 2], [length, 0],
                      [shaft, width / 2], [shaft, half], [0, half]])
    return np.column_stack([x + c * local[:, 0] - s * local[:, 1], y + s * local[:, 0] + c * local[:, 1]])


def _impacts(outcome) -> list:
    """One (t, x, y, label) per impact (the table has one row per vehicle and impact)."""
    seen, out = set(), []
    for r in sorted(outcome.impact_rows, key=lambda row: row["t"]):
        key = (round(r["t"], 9), frozenset((r["vehicle"], r["other"])))
        if key in seen or not (math.isfinite(r["point_x"]) and math.isfinite(r["point_y"])):
            continue
        seen.add(key)
        out.append((r["t"], r["point_x"], r["point_y"], f"impact {r['vehicle']}-{r['other']}, t = {r['t']:.3f} s"))
    return out


def _limits(scene, poses):
    """Fixed axes limits: every pose of every vehicle with its outline, and the barriers."""
    from ..scene import barrier_outline
    pts = []
    for v in scene.vehicles:
        reach = math.hypot(max(v.spec.cg_to_front, v.spec.cg_to_rear), v.spec.width / 2)
        p = poses[v.name][:, :2]
        pts += [p.min(axis=0) - reach, p.max(axis=0) + reach]
    for b in scene.barriers:
        pts += list(barrier_outline(b))
    pts = np.asarray(pts)
    lo, hi = pts.min(axis=0) - 1.0, pts.max(axis=0) + 1.0
    return (lo[0], hi[0]), (lo[1], hi[1])


def _canvas_pillow_writer(fps):
    """A PillowWriter at `fps` that takes the frames from the canvas (defined here: matplotlib is imported late)."""
    from matplotlib.animation import PillowWriter
    from PIL import Image

    class CanvasPillowWriter(PillowWriter):
        """PillowWriter that takes each frame from the canvas as the frame function drew it (blitted) instead of
        redrawing the whole figure through savefig, which would also skip the animated artists."""

        def grab_frame(self, **savefig_kwargs):
            canvas = self.fig.canvas
            im = Image.frombuffer("RGBA", canvas.get_width_height(), canvas.buffer_rgba(), "raw", "RGBA", 0, 1)
            self._frames.append(im.convert("RGB"))  # a copy: the canvas buffer is drawn over next frame

    return CanvasPillowWriter(fps=fps)


def write_animation(scene, outcome, path, fps: float = 25.0, speed: float = 1.0, max_frames: int = 300,
                    dpi: int = 80, title: str | None = None, system: str = "si") -> Path:
    """Write the animation of `outcome` (the result of simulating `scene`) to `path` (.gif, or .mp4 with
    ffmpeg on PATH) and return the path. One frame per entry of animation_times(outcome, fps, speed,
    max_frames), played at `fps`; `dpi` sets the pixel size (80: about 690 x 480 px); `system` "us": the axes
    and the scale bar in ft (the drawing stays in m: crashlab.units.length_axes_in). Raises
    crashlab.InputError for a bad extension or a missing ffmpeg, ValueError when the outcome has no
    trajectories (a batch run records none)."""
    path = check_animation_path(path)
    path.parent.mkdir(parents=True, exist_ok=True)  # before the animation: one deleted unsaved warns on stderr
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.animation import FFMpegWriter, FuncAnimation
    from matplotlib.lines import Line2D
    from matplotlib.patches import Polygon

    from .plotting import ROAD_LINE_LOOK, draw_barriers, draw_road, scale_bar, vehicle_colours

    times = animation_times(outcome, fps, speed, max_frames)
    poses = frame_poses(scene, outcome, times)
    impacts = _impacts(outcome) if outcome.impact_rows else []
    colours = vehicle_colours()

    (x0, x1), (y0, y1) = _limits(scene, poses)
    aspect = (y1 - y0) / max(x1 - x0, 1e-9)
    # the figure at the writer's dpi: savefig then draws each frame once, without a re-layout
    # (the axes take about 5 of the 7 in width, the legend the rest)
    fig, ax = plt.subplots(figsize=(7.0, float(np.clip(5.0 * aspect, 2.5, 7.0)) + 1.0), dpi=dpi)
    draw_road(ax, scene.road, legend=False)
    draw_barriers(ax, scene.barriers)
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    ax.set_aspect("equal", adjustable="box")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    length_axes_in(ax, system)
    ax.grid(alpha=0.3)
    ax.set_title(title or f"{scene.name} ({outcome.model})", fontsize=10)

    vehicles = []
    for i, v in enumerate(scene.vehicles):
        c = colours[i % len(colours)]
        start = vehicle_outline(v)
        start = np.vstack([start, start[:1]])
        ax.plot(start[:, 0], start[:, 1], ":", color=c, lw=1.0, alpha=0.7)
        (outline,) = ax.plot([], [], "-", color=c, lw=2.0, label=v.name)
        (path_line,) = ax.plot([], [], "-", color=c, lw=1.0, alpha=0.7)
        arrow = Polygon(np.zeros((7, 2)), closed=True, color=c, zorder=4)
        ax.add_patch(arrow)
        tr = outcome.trajectories.get(v.name)
        vehicles.append((v, outline, path_line, arrow, tr))
    stars = []
    for t_imp, px, py, label in impacts:
        (star,) = ax.plot([px], [py], "*", color="k", mfc="yellow", ms=22, zorder=6, visible=False)
        text = ax.annotate(label, (px, py), textcoords="offset points", xytext=(8, 10), fontsize=8,
                           color="firebrick", fontweight="bold", zorder=7, visible=False,
                           bbox=dict(boxstyle="round", fc="white", ec="firebrick", alpha=0.85))
        stars.append((t_imp, star, text))
    stamp = ax.text(0.02, 0.97, "", transform=ax.transAxes, va="top", fontsize=10, family="monospace",
                    bbox=dict(boxstyle="round", fc="white", ec="0.6", alpha=0.85), zorder=7)
    handles = [Line2D([], [], color=colours[i % len(colours)], lw=2, label=v.name)
               for i, v in enumerate(scene.vehicles)]
    handles += [Line2D([], [], ls=":", color="0.4", label="start"), Line2D([], [], color="0.4", lw=1, label="CG path")]
    for kind in dict.fromkeys(line.kind for line in scene.road.lines):  # one entry per kind of road line
        colour, width, style = ROAD_LINE_LOOK[kind]
        handles.append(Line2D([], [], color=colour, lw=width, ls="--" if style == "dashed" else "-",
                              label=f"road {kind}"))
    if impacts:
        handles.append(Line2D([], [], ls="", marker="*", color="k", mfc="yellow", ms=10, label="impact"))
    ax.legend(handles=handles, fontsize=7, loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0)
    fig.tight_layout()
    scale_bar(ax, system)  # after the layout: the bar sits on the final limits
    frame_step = times[1] - times[0]
    moving = [a for _, outline, path_line, arrow, _ in vehicles for a in (path_line, outline, arrow)]
    moving += [a for _, star, text in stars for a in (star, text)] + [stamp]
    gif = path.suffix.lower() == ".gif"
    if gif:
        # blitting: the static drawing (zones, barriers, start outlines, axes, legend, scale bar) is rendered
        # once; each frame restores it and draws only the moving artists, which the writer then takes
        # from the canvas (a whole-figure redraw per frame costs about five times as much)
        for a in moving:
            a.set_animated(True)
        fig.canvas.draw()
        background = fig.canvas.copy_from_bbox(fig.bbox)

    def update(k):
        t = times[k]
        for v, outline, path_line, arrow, tr in vehicles:
            x, y, h = poses[v.name][k]
            poly = vehicle_outline(v, x, y, h)
            outline.set_data(np.append(poly[:, 0], poly[0, 0]), np.append(poly[:, 1], poly[0, 1]))
            arrow.set_xy(_arrow_polygon(x, y, h, 0.8 * v.spec.cg_to_front, 0.3 * v.spec.width))
            if tr is not None:
                upto = np.searchsorted(tr["t"], t, side="right")
                path_line.set_data(np.append(tr["x"][:upto], x), np.append(tr["y"][:upto], y))
        for t_imp, star, text in stars:
            # flashed from the impact for FLASH_S (at least one frame step), then a small mark
            flash = t_imp <= t < t_imp + max(FLASH_S, frame_step) or (k == len(times) - 1 and t == t_imp)
            star.set_visible(t >= t_imp)
            star.set_markersize(22 if flash else 9)
            text.set_visible(flash)
        stamp.set_text(f"t = {t:6.3f} s")
        if gif:
            fig.canvas.restore_region(background)
            for a in moving:
                ax.draw_artist(a)
        return []

    anim = FuncAnimation(fig, update, frames=len(times), blit=False, repeat=False, cache_frame_data=False)
    writer = _canvas_pillow_writer(fps) if gif else FFMpegWriter(fps=fps)
    # Animation.save draws each frame for the screen (draw_idle) before the writer grabs it; headless, the
    # writer's frame is all that is needed (the MP4 writer draws the whole figure itself)
    fig.canvas.draw_idle = lambda *args, **kwargs: None
    try:
        anim.save(str(path), writer=writer, dpi=dpi)
    finally:
        plt.close(fig)
    return path
