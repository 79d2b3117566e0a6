"""What a user reads in the impact table: the PDOF also as the SAE J224 clock, units in printed headers."""
import subprocess
import sys

import pytest
from conftest import PC_CRASH

import crashlab
from crashlab.outcome import pdof_clock


@pytest.mark.parametrize("pdof, hour", [(0.0, 12), (-10.0, 12), (-90.0, 3), (90.0, 9), (180.0, 6), (-180.0, 6),
                                        (-30.0, 1), (-44.0, 1), (-46.0, 2), (15.1, 11)])
def test_pdof_clock_is_clockwise_from_straight_ahead(pdof, hour):
    assert pdof_clock(pdof) == hour


def test_side_collision_reads_twelve_for_the_striking_car_and_nine_for_the_car_struck_on_its_left():
    """V1 drives +x into V2, which heads +y: V1 is hit from straight ahead, V2 on its left side (west)."""
    out = crashlab.simulate(crashlab.load_scene(PC_CRASH / "side.toml"), model="impulse")
    first = out.impacts.groupby("vehicle").first()
    assert first.loc["V1", "pdof_clock"] == 12 and first.loc["V2", "pdof_clock"] == 9
    res = subprocess.run([sys.executable, "-m", "crashlab.cli", "simulate", str(PC_CRASH / "side.toml")],
                         capture_output=True, text=True)
    assert "delta_v [km/h]" in res.stdout and "pdof [deg]" in res.stdout  # the table within 100 columns
    res = subprocess.run([sys.executable, "-m", "crashlab.cli", "simulate", str(PC_CRASH / "side.toml"), "--wide"],
                         capture_output=True, text=True)
    assert "pdof_clock [h]" in res.stdout  # every column with --wide


def test_simulate_csv_exports_the_trajectories_and_impacts(tmp_path):
    import pandas as pd
    from conftest import assert_one_error_line
    res = subprocess.run([sys.executable, "-m", "crashlab.cli", "simulate", str(PC_CRASH / "side.toml"), "--csv",
                          str(tmp_path / "out")], capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
    traj = pd.read_csv(tmp_path / "out" / "trajectories.csv")
    assert list(traj.columns) == ["vehicle", "t", "x", "y", "heading", "vx", "vy", "yaw_rate"]
    out = crashlab.simulate(crashlab.load_scene(PC_CRASH / "side.toml"), model="impulse")
    for i, name in enumerate(out.names):  # the last sample is the rest pose
        last = traj[traj.vehicle == name].iloc[-1]
        assert (last.x, last.y) == pytest.approx(tuple(out.rest_si[i, :2]), abs=1e-9)
    imp = pd.read_csv(tmp_path / "out" / "impacts.csv")
    assert list(imp.columns) == list(out.impacts.columns) and len(imp) == len(out.impacts)
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    res = subprocess.run([sys.executable, "-m", "crashlab.cli", "simulate", str(PC_CRASH / "side.toml"), "--csv",
                          str(blocker / "sub")], capture_output=True, text=True)
    assert_one_error_line(res, blocker / "sub", "--csv", ["cannot write"])


def test_top_view_marks_the_point_of_impact_and_keeps_the_legend_off_the_drawing(tmp_path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from crashlab.tools.plotting import top_view
    scene = crashlab.load_scene(PC_CRASH / "side.toml")
    out = crashlab.simulate(scene, model="impulse")
    captured = {}
    close = plt.close
    plt.close = lambda fig=None: captured.setdefault("fig", fig) or close(fig)
    try:
        top_view(scene, out, tmp_path / "side.png")
    finally:
        plt.close = close
    ax = captured["fig"].axes[0]
    first = min(out.impact_rows, key=lambda r: r["t"])
    star = [ln for ln in ax.lines if ln.get_label().startswith("point of impact")]
    assert star and tuple(star[0].get_xydata()[0]) == pytest.approx((first["point_x"], first["point_y"]))
    legend = ax.get_legend().get_window_extent(captured["fig"].canvas.get_renderer())
    assert legend.x0 >= ax.get_window_extent().x1  # beside the axes, not over the data
    assert (tmp_path / "side.png").stat().st_size > 0
    close(captured["fig"])


def test_a_3d_run_shows_each_cars_crush_peak_force_duration_and_restitution(tmp_path):
    """The 3D models' impact rows carry each car's crush, the peak force, the duration and the restitution; the
    CLI's JSON and CSV (and --wide) dropped them (a fuzzer, 2026-11-27). Now columns of Outcome.impacts where a
    model gives them, in US units under --units us (crush in ft: 1 ft = 0.3048 m; force in lbf: 4.4482216 N)."""
    import json

    import pandas as pd
    scene = PC_CRASH / "side.toml"
    out = crashlab.simulate(crashlab.load_scene(scene), model="multibody")
    rows = [r for r in out.impact_rows if r["kind"] != "push"]
    assert list(out.impacts.columns[-4:]) == ["crush", "peak_force", "duration", "restitution"]
    for col in ("crush", "peak_force", "duration", "restitution"):
        assert out.impacts[col].iloc[0] == pytest.approx(rows[0][col], rel=1e-12)
    assert "crush" not in crashlab.simulate(crashlab.load_scene(scene), model="impulse").impacts.columns
    res = subprocess.run([sys.executable, "-m", "crashlab.cli", "simulate", str(scene), "--model", "multibody",
                          "--json", "--units", "us"], capture_output=True, text=True)
    doc = json.loads(res.stdout)
    first = doc["results"][0]["impacts"][0]
    assert first["crush"] == pytest.approx(rows[0]["crush"] / 0.3048, rel=1e-5)
    assert first["peak_force"] == pytest.approx(rows[0]["peak_force"] / 4.4482216152605, rel=1e-5)
    assert first["restitution"] == pytest.approx(rows[0]["restitution"], rel=1e-5)
    assert doc["units"]["impacts.crush"] == "ft" and doc["units"]["impacts.peak_force"] == "lbf"
    res = subprocess.run([sys.executable, "-m", "crashlab.cli", "simulate", str(scene), "--model", "multibody",
                          "--csv", str(tmp_path / "out")], capture_output=True, text=True)
    imp = pd.read_csv(tmp_path / "out" / "impacts.csv")
    assert imp["crush"].iloc[0] == pytest.approx(rows[0]["crush"], rel=1e-9)
    res = subprocess.run([sys.executable, "-m", "crashlab.cli", "simulate", str(scene), "--model", "multibody",
                          "--wide"], capture_output=True, text=True)
    assert "crush [m]" in res.stdout and "peak_force [N]" in res.stdout
