"""[[road.lines]] in scene files (issue 26): edges, lane markings, kerbs and centre lines as polylines, read into
crashlab.scene.RoadLine (SI), refused in one line when malformed, drawn in every top view (crashlab.tools.plotting;
the animation: tests/test_animation.py), and changing no result of any model."""
from __future__ import annotations

import dataclasses
import tomllib
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from conftest import assert_one_error_line

import crashlab
from crashlab.scene import RoadLine
from crashlab.scene_file import scene_from_dict

REPO = Path(__file__).resolve().parent.parent
TUTORIAL = REPO / "studies" / "tutorial" / "scene.toml"


def _scene_text(lines: str) -> str:
    return TUTORIAL.read_text().split("\n# The crossroads as the sketch draws it")[0] + "\n" + lines


def test_lines_are_read_in_order_with_kind_and_style():
    scene = crashlab.load_scene(TUTORIAL)
    assert len(scene.road.lines) == 8
    assert scene.road.lines[0] == RoadLine(points=((-20.0, -3.5), (-3.5, -3.5), (-3.5, -20.0)), kind="kerb")
    assert {ln.kind for ln in scene.road.lines} == {"kerb", "centre"}
    data = tomllib.loads(_scene_text('[[road.lines]]\npoints = [[0, 0], [5, 0.5]]\nstyle = "dotted"\n'))
    line = scene_from_dict(data, base_dir=TUTORIAL.parent).road.lines[0]
    assert line == RoadLine(points=((0.0, 0.0), (5.0, 0.5)), kind="edge", style="dotted")


@pytest.mark.parametrize("lines, key", [
    ('[[road.lines]]\npoints = [[0, 0]]\n', "road.lines.0.points"),
    ('[[road.lines]]\npoints = [[0, 0], [1, 1]]\nkind = "curb"\n', "road.lines.0.kind"),
    ('[[road.lines]]\npoints = [[0, 0], [1, 1]]\nstyle = "wavy"\n', "road.lines.0.style"),
    ('[[road.lines]]\npoints = [[0, 0], [1e9, 1]]\n', "road.lines.0.points.1.0"),
    ('[[road.lines]]\npoints = [[0, 0], [1, 1]]\ncolour = "red"\n', "road.lines.0.colour"),
])
def test_bad_lines_are_one_line_exit_2(tmp_path, capsys, lines, key):
    from crashlab.cli import main
    path = tmp_path / "scene.toml"
    path.write_text(_scene_text(lines))  # its vehicles come from the library, by name
    code = main(["simulate", str(path)])
    cap = capsys.readouterr()
    assert_one_error_line(SimpleNamespace(returncode=code, stdout=cap.out, stderr=cap.err), path, key)


@pytest.mark.parametrize("model", ["impulse", "pymunk"])
def test_lines_change_no_result(model):
    """The tutorial's scene with its eight lines and without them: the same rest poses, end velocities, first
    contact and impact rows, bit for bit (a model never reads the lines)."""
    if model == "pymunk":
        pytest.importorskip("pymunk")
    scene = crashlab.load_scene(TUTORIAL)
    bare = scene.replace(road=dataclasses.replace(scene.road, lines=()))
    assert scene.road.lines and not bare.road.lines
    a, b = crashlab.simulate(scene, model=model), crashlab.simulate(bare, model=model)
    assert a.outcome_ok and b.outcome_ok
    for key in ("rest_si", "final_si", "contact_si"):
        assert np.array_equal(getattr(a, key), getattr(b, key)), key
    assert a.impacts.equals(b.impacts)


def road_collections(ax) -> list:
    """(points, RGB colour, dashed, label) of every LineCollection of one polyline on the axes."""
    import matplotlib.colors as mcolors
    out = []
    for c in ax.collections:
        segs = c.get_segments()
        if len(segs) == 1:
            dashes = c.get_linestyle()[0][1]
            out.append((np.asarray(segs[0]), tuple(c.get_edgecolor()[0][:3]), dashes is not None, c.get_label()))
    return out, mcolors


def test_every_line_is_drawn_in_the_top_view(tmp_path, monkeypatch):
    """top_view and compare_view draw each line with its points under the vehicles, in its kind's colour and
    style, without widening the view beyond the vehicles; one legend entry per kind."""
    from crashlab.tools import plotting
    scene = crashlab.load_scene(TUTORIAL)
    out = crashlab.simulate(scene, model="impulse")
    seen = []
    real = plotting._finish

    def finish(fig, ax, title, path):
        seen.append((road_collections(ax), ax.get_xlim(), ax.get_legend_handles_labels()[1]))
        real(fig, ax, title, path)
    monkeypatch.setattr(plotting, "_finish", finish)
    plotting.top_view(scene, out, tmp_path / "top.png")
    plotting.compare_view(scene, {"impulse": out}, tmp_path / "cmp.png")
    assert (tmp_path / "top.png").is_file() and (tmp_path / "cmp.png").is_file() and len(seen) == 2
    for (drawn, mcolors), xlim, labels in seen:
        for line in scene.road.lines:
            colour, _, style = plotting.ROAD_LINE_LOOK[line.kind]
            match = [d for d in drawn if d[0].shape == (len(line.points), 2) and np.allclose(d[0], line.points)]
            assert len(match) == 1, line
            assert np.allclose(match[0][1], mcolors.to_rgb(colour)) and match[0][2] == (style == "dashed")
        assert labels.count("road kerb") == 1 and labels.count("road centre") == 1
        assert xlim[0] > -19.0 and xlim[1] < 19.0  # the lines run to +-20 m: the vehicles set the view


def test_time_histories_have_units_and_the_distance_is_the_path_length(tmp_path, monkeypatch):
    from matplotlib.figure import Figure

    from crashlab.tools.plotting import distance_travelled, time_histories
    assert np.allclose(distance_travelled([0, 3, 3, 0], [0, 4, 8, 8]), [0, 5, 9, 12])
    assert len(distance_travelled([], [])) == 0
    scene = crashlab.load_scene(TUTORIAL)
    out = crashlab.simulate(scene, model="impulse")
    labels = []
    real = Figure.savefig

    def savefig(fig, path, *a, **k):
        labels.extend((ax.get_xlabel(), ax.get_ylabel()) for ax in fig.axes)
        return real(fig, path, *a, **k)
    monkeypatch.setattr(Figure, "savefig", savefig)
    time_histories(scene, out, tmp_path / "t.png")
    assert [y for _, y in labels] == ["speed [km/h]", "distance travelled [m]", "heading [deg]"]
    assert labels[-1][0] == "t [s]"
    assert (tmp_path / "t.png").read_bytes()[:4] == b"\x89PNG"
    with pytest.raises(ValueError, match="no trajectories"):
        time_histories(scene, SimpleNamespace(trajectories={}, model="batch"), tmp_path / "none.png")
