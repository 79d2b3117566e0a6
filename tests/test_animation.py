"""`crashlab simulate SCENE --animate FILE.gif|mp4` and crashlab.tools.animation.write_animation: the GIF has one frame
per frame time, frame 0 shows the start poses and the last frame the outcome's rest poses (checked on the
pixels), a bad extension or a missing ffmpeg is one line and exit status 2."""
from __future__ import annotations

import math
import shutil
from types import SimpleNamespace

import numpy as np
import pytest
from conftest import PC_CRASH, assert_one_error_line

import crashlab
from crashlab.scene import vehicle_outline
from crashlab.tools.animation import animation_times, frame_poses, write_animation


def _cli(capsys, *args):
    """crashlab.cli.main in this process: what assert_one_error_line reads (returncode, stdout, stderr)."""
    from crashlab.cli import main
    code = main([str(a) for a in args])
    captured = capsys.readouterr()
    return SimpleNamespace(returncode=code, stdout=captured.out, stderr=captured.err)


@pytest.fixture(scope="module")
def side():
    scene = crashlab.load_scene(PC_CRASH / "side.toml")
    return scene, crashlab.simulate(scene, model="impulse")


def test_frame_times_and_poses_run_from_the_start_to_the_rest_poses(side):
    scene, out = side
    t_end = out.trajectories["V1"]["t"][-1]
    times = animation_times(out, fps=10.0)
    assert len(times) == math.ceil(t_end * 10.0) + 1 and times[0] == 0.0 and times[-1] == t_end
    assert len(animation_times(out, fps=10.0, speed=0.5)) == math.ceil(t_end * 20.0) + 1  # slow motion
    assert len(animation_times(out, fps=1000.0, max_frames=50)) == 50
    poses = frame_poses(scene, out, times)
    for i, v in enumerate(scene.vehicles):
        assert poses[v.name][0] == pytest.approx([v.x, v.y, v.heading], abs=1e-12)
        assert poses[v.name][-1] == pytest.approx(out.rest_si[i], abs=1e-9)


def _colour_near(frame, xy_px, colour, radius=2, tol=60):
    """Whether a pixel within `radius` of xy_px (image coordinates) has `colour` (RGB, 0-255) within tol."""
    x, y = int(round(xy_px[0])), int(round(xy_px[1]))
    patch = frame[max(y - radius, 0):y + radius + 1, max(x - radius, 0):x + radius + 1].astype(int)
    return bool((np.abs(patch - np.asarray(colour)).sum(axis=2) < tol).any())


def test_gif_has_one_frame_per_time_with_the_start_and_rest_outlines_drawn(side, tmp_path, monkeypatch):
    """The GIF's frame 0 draws each vehicle's outline at its start pose and its last frame at the outcome's rest
    pose: the midpoints of the outline's edges, mapped through the figure's axes to pixels, carry the
    vehicle's colour there (and the rest outline's do not in frame 0: the vehicles moved)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.colors as mcolors
    import matplotlib.pyplot as plt
    from PIL import Image

    from crashlab.tools.plotting import vehicle_colours
    scene, out = side
    captured = {}
    close = plt.close
    monkeypatch.setattr(plt, "close", lambda fig=None: captured.setdefault("fig", fig))
    path = write_animation(scene, out, tmp_path / "side.gif", fps=10.0)
    assert path == tmp_path / "side.gif"
    img = Image.open(path)
    assert img.format == "GIF" and img.n_frames == len(animation_times(out, fps=10.0))
    fig = captured["fig"]
    ax = fig.axes[0]
    height = img.size[1]
    assert tuple(img.size) == tuple(int(round(d)) for d in fig.get_size_inches() * fig.dpi)

    def frame(k):
        img.seek(k)
        return np.asarray(img.convert("RGB"))

    first, last = frame(0), frame(img.n_frames - 1)
    for i, v in enumerate(scene.vehicles):
        colour = np.asarray(mcolors.to_rgb(vehicle_colours()[i])) * 255
        for pose, image in (((v.x, v.y, v.heading), first), (tuple(out.rest_si[i]), last)):
            corners = vehicle_outline(v, *pose)
            mids = (corners + np.roll(corners, -1, axis=0)) / 2
            px = ax.transData.transform(mids)
            px[:, 1] = height - px[:, 1]  # image rows count down
            assert all(_colour_near(image, p, colour) for p in px), (v.name, pose)
        rest_mids = ax.transData.transform((lambda c: (c + np.roll(c, -1, axis=0)) / 2)(
            vehicle_outline(v, *out.rest_si[i])))
        rest_mids[:, 1] = height - rest_mids[:, 1]
        assert not all(_colour_near(first, p, colour) for p in rest_mids), "frame 0 is not the rest pose"
    close(fig)


def test_cli_animate_writes_a_gif_and_refuses_bad_paths(tmp_path, capsys, monkeypatch):
    gif = tmp_path / "side.gif"
    res = _cli(capsys, "simulate", PC_CRASH / "side.toml", "--animate", gif, "--fps", 5)
    assert res.returncode == 0, res.stderr
    out = crashlab.simulate(crashlab.load_scene(PC_CRASH / "side.toml"), model="impulse")
    from PIL import Image
    assert Image.open(gif).n_frames == math.ceil(out.trajectories["V1"]["t"][-1] * 5) + 1 == 9
    bad = tmp_path / "side.png"
    assert_one_error_line(_cli(capsys, "simulate", PC_CRASH / "side.toml", "--animate", bad), bad, "--animate",
                          [".gif or .mp4"])
    assert_one_error_line(_cli(capsys, "simulate", PC_CRASH / "side.toml", "--animate", gif, "--fps", 0),
                          "command line", "--fps")
    assert_one_error_line(_cli(capsys, "simulate", PC_CRASH.parent / "montecarlo" / "side.toml", "--animate", gif,
                               "--monte-carlo", 10), "command line", "--animate")
    mp4 = tmp_path / "side.mp4"
    monkeypatch.setenv("PATH", str(tmp_path))  # no ffmpeg on this PATH
    assert_one_error_line(_cli(capsys, "simulate", PC_CRASH / "side.toml", "--animate", mp4), mp4, "--animate",
                          ["ffmpeg"])
    assert not bad.exists() and not mp4.exists()


@pytest.mark.skipif(shutil.which("ffmpeg") is None, reason="an .mp4 needs ffmpeg on PATH")
def test_mp4_with_ffmpeg(side, tmp_path):
    scene, out = side
    path = write_animation(scene, out, tmp_path / "side.mp4", fps=10.0)
    assert path.read_bytes()[4:8] == b"ftyp" and path.stat().st_size > 1000


def test_road_lines_are_drawn_in_every_frame(tmp_path, monkeypatch):
    """The tutorial's road lines (crashlab.scene.RoadLine) are in the animation's axes with their points, and a
    kerb's pixels carry the kerb's grey in the first and the last frame (the static background every frame
    restores)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.colors as mcolors
    import matplotlib.pyplot as plt
    from PIL import Image

    from crashlab.tools.plotting import ROAD_LINE_LOOK
    scene = crashlab.load_scene(PC_CRASH.parent / "tutorial" / "scene.toml")
    out = crashlab.simulate(scene, model="impulse")
    captured = {}
    close = plt.close
    monkeypatch.setattr(plt, "close", lambda fig=None: captured.setdefault("fig", fig))
    path = write_animation(scene, out, tmp_path / "tutorial.gif", fps=4.0)
    fig = captured["fig"]
    ax = fig.axes[0]
    drawn = [np.asarray(c.get_segments()[0]) for c in ax.collections if len(c.get_segments()) == 1]
    for line in scene.road.lines:
        assert any(d.shape == (len(line.points), 2) and np.allclose(d, line.points) for d in drawn), line
    img = Image.open(path)
    height = img.size[1]
    kerb = np.asarray(mcolors.to_rgb(ROAD_LINE_LOOK["kerb"][0])) * 255
    px = ax.transData.transform([(-11.75, -3.5)])[0]  # the middle of the south-west kerb's first segment
    px[1] = height - px[1]
    for k in (0, img.n_frames - 1):
        img.seek(k)
        assert _colour_near(np.asarray(img.convert("RGB")), px, kerb, tol=40), k
    close(fig)
