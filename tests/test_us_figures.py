"""US customary units in the figures (issue 26 item 4): with `system="us"` the top views (top_view,
compare_view), the time histories and the animation show feet and mph on their axes, scale bar and labels,
while the drawing itself stays in metres; reconstruct and infer pass `--units us` to the figures they draw
(solution_k.png, solution_0_time.png, median_draw*.png).

The matplotlib objects are inspected (Figure.savefig recorded), not the images. The expected numbers use the
exact definitions (1 ft = 0.3048 m, 1 mile = 1609.344 m; NIST SP 811), independent of the pint conversion the
code uses."""
from __future__ import annotations

import contextlib
import io
import math
import re
from pathlib import Path

import numpy as np
import pytest

import crashlab

FT, MPH = 0.3048, 1.609344  # m, km/h per US unit (exact by definition)
REPO = Path(__file__).resolve().parent.parent
TUTORIAL = REPO / "studies" / "tutorial" / "scene.toml"


@pytest.fixture(scope="module")
def run():
    scene = crashlab.load_scene(TUTORIAL)
    return scene, crashlab.simulate(scene, model="impulse")


@pytest.fixture
def saved(monkeypatch):
    """{file name: figure} of every figure saved while the test runs (the figure as it was saved)."""
    from matplotlib.figure import Figure
    figures = {}
    real = Figure.savefig

    def savefig(fig, path, *a, **k):
        out = real(fig, path, *a, **k)
        figures[Path(str(path)).name] = fig
        return out
    monkeypatch.setattr(Figure, "savefig", savefig)
    return figures


def round_in_feet(values) -> bool:
    """Every value (in m) a whole multiple of its spacing in ft: ticks at round ft values."""
    ft = np.asarray(values, dtype=float) / FT
    step = np.min(np.diff(ft))
    return bool(np.allclose(ft / step, np.round(ft / step), atol=1e-6))


def scale_bar_of(ax):
    """(length in the drawing's unit m, its label) of the scale bar: the text beside a thick black 2-point line."""
    bars = [ln for ln in ax.get_lines() if len(ln.get_xdata()) == 2 and ln.get_linewidth() == 3
            and ln.get_color() == "k"]
    texts = [t.get_text() for t in ax.texts if re.fullmatch(r"[\d.e+-]+ (m|ft)", t.get_text())]
    assert len(bars) == 1 and len(texts) == 1
    x = bars[0].get_xdata()
    return x[1] - x[0], texts[0]


def assert_top_view_in_feet(ax):
    assert ax.get_xlabel() == "x [ft]" and ax.get_ylabel() == "y [ft]"
    ax.figure.canvas.draw()
    for axis in (ax.xaxis, ax.yaxis):
        ticks = axis.get_majorticklocs()
        assert len(ticks) >= 3 and round_in_feet(ticks), ticks
        labels = [t.get_text() for t in axis.get_majorticklabels()]
        assert [float(s.replace("\u2212", "-")) for s in labels] == pytest.approx(ticks / FT, abs=1e-6)
    length, label = scale_bar_of(ax)
    number, unit = label.split()
    assert unit == "ft" and length == pytest.approx(float(number) * FT, rel=1e-12)
    assert float(number) / 10 ** math.floor(math.log10(float(number))) in (1, 2, 5)
    legend = ax.get_legend_handles_labels()[1]
    assert not any(re.search(r"\bm\b|km/h", s) for s in legend), legend


def test_top_view_in_us_units(run, saved, tmp_path):
    from crashlab.tools import plotting
    scene, out = run
    plotting.top_view(scene, out, tmp_path / "si.png")
    plotting.top_view(scene, out, tmp_path / "us.png", system="us")
    si, us = saved["si.png"].axes[0], saved["us.png"].axes[0]
    assert si.get_xlabel() == "x [m]" and scale_bar_of(si)[1].endswith(" m")
    assert_top_view_in_feet(us)
    r = min(out.impact_rows, key=lambda row: row["t"])
    poi = [s for s in us.get_legend_handles_labels()[1] if s.startswith("point of impact")]
    assert poi == [f"point of impact ({r['point_x'] / FT:.2f}, {r['point_y'] / FT:.2f}) ft, t = {r['t']:.3f} s"]
    # the drawing stays in m: the same outlines in both
    assert np.allclose(si.get_lines()[0].get_xydata(), us.get_lines()[0].get_xydata())


def test_a_moving_end_pose_says_mph(run):
    from types import SimpleNamespace

    from crashlab.tools.plotting import pose_text
    moving = SimpleNamespace(at_rest_mask=[False, True], end_speed_si=[10.0, 0.0])
    assert pose_text(moving, 0, "us") == f"end pose (moving {10.0 * 3.6 / MPH:.1f} mph)"
    assert pose_text(moving, 0) == "end pose (moving 36.0 km/h)"
    assert pose_text(moving, 1, "us") == "rest"


def test_compare_view_in_us_units(run, saved, tmp_path):
    from crashlab.tools import plotting
    scene, out = run
    plotting.compare_view(scene, {"impulse": out}, tmp_path / "cmp.png", system="us")
    assert_top_view_in_feet(saved["cmp.png"].axes[0])


def test_time_histories_in_us_units(run, saved, tmp_path):
    from crashlab.tools.plotting import time_histories
    scene, out = run
    time_histories(scene, out, tmp_path / "t.png", system="us")
    axes = saved["t.png"].axes
    assert [ax.get_ylabel() for ax in axes] == ["speed [mph]", "distance travelled [ft]", "heading [deg]"]
    assert axes[2].get_xlabel() == "t [s]"
    tr = out.trajectories[scene.vehicles[0].name]
    speed, distance = axes[0].get_lines()[0].get_ydata(), axes[1].get_lines()[0].get_ydata()
    # independent: m/s -> mph and the path's chords summed, in ft
    assert np.allclose(speed, np.hypot(tr["vx"], tr["vy"]) * 3.6 / MPH, rtol=1e-12)
    path = np.sum(np.hypot(np.diff(tr["x"]), np.diff(tr["y"])))
    assert distance[-1] == pytest.approx(path / FT, rel=1e-12)
    assert np.allclose(axes[2].get_lines()[0].get_ydata(), np.degrees(tr["heading"]))


def test_animation_axes_in_us_units(run, tmp_path, monkeypatch):
    import matplotlib.animation as mpl_animation

    from crashlab.tools import animation
    scene, out = run
    axes = []

    def save(anim, *a, **k):  # the figure as the frames would be written; the frames are not needed
        axes.append(anim._fig.axes[0])
        anim._draw_was_started = True  # no "deleted without rendering" warning
        raise RuntimeError("recorded")
    monkeypatch.setattr(mpl_animation.FuncAnimation, "save", save)
    with pytest.raises(RuntimeError, match="recorded"):
        animation.write_animation(scene, out, tmp_path / "a.gif", system="us")
    assert_top_view_in_feet(axes[0])


@pytest.fixture(scope="module")
def us_study(tmp_path_factory):
    from test_us_studies import SI, SIDE, STUDY
    path = tmp_path_factory.mktemp("us_fig") / "si.toml"
    path.write_text(STUDY.format(units="", scene=SIDE.as_posix(), **{k: repr(v) for k, v in SI.items()}))
    return path


def labels_of(fig):
    return [(ax.get_xlabel(), ax.get_ylabel()) for ax in fig.axes]


def test_simulate_and_compare_plot_in_us_units(saved, tmp_path):
    """The command line's --units reaches simulate --plot and compare --plot (not only the plotting functions)."""
    from crashlab.cli.main import main
    with contextlib.redirect_stdout(io.StringIO()):
        assert main(["simulate", str(TUTORIAL), "--units", "us", "--plot", str(tmp_path / "one.png")]) == 0
        assert main(["compare", str(TUTORIAL), "--models", "impulse,pymunk", "--units", "us", "--plot",
                     str(tmp_path / "two.png")]) == 0
    assert_top_view_in_feet(saved["one.png"].axes[0])
    assert_top_view_in_feet(saved["two.png"].axes[0])


def test_reconstruct_and_infer_draw_their_figures_and_evidence_in_us_units(us_study, saved, tmp_path, monkeypatch):
    from conftest import two_frame_gif

    from crashlab.cli.main import main
    from crashlab.reconstruction import html_report
    animated = []  # report.html's animation in the shown units too

    def animate(scene, outcome, path, fps, system="si"):
        animated.append(system)
        return two_frame_gif(scene, outcome, path, fps, system)
    monkeypatch.setattr(html_report, "_animate", animate)
    for command in ("reconstruct", "infer"):
        with contextlib.redirect_stdout(io.StringIO()):
            assert main([command, str(us_study), "--no-progress", "--units", "us", "--out",
                         str(tmp_path / command)]) == 0
    assert animated == ["us", "us"]
    for name in ("solution_0.png", "median_draw.png"):
        assert_top_view_in_feet(saved[name].axes[0])
    for name in ("solution_0_time.png", "median_draw_time.png"):
        assert [y for _, y in labels_of(saved[name])] == ["speed [mph]", "distance travelled [ft]", "heading [deg]"]
    # summary.md's evidence lines in US units too (EvidenceSet.describe; tests/test_us_evidence.py)
    for command in ("reconstruct", "infer"):
        summary = (tmp_path / command / "summary.md").read_text()
        assert "file units" not in summary and f"- rest.V1: x = {6.66 / FT:.2f} ± {0.3 / FT:.3g} ft" in summary
