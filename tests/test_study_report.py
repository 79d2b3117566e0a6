"""`crashlab study all`'s report page: self-contained (every figure embedded), a table per study from the
CSV contract columns; and the command's bad input (one line, exit 2)."""
import base64
import re
import subprocess
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import pandas as pd  # noqa: E402

from crashlab.comparison.report import write_report  # noqa: E402


def _png(path):
    fig, ax = plt.subplots(figsize=(2, 2))
    ax.plot([0, 1], [0, 1])
    fig.savefig(path)
    plt.close(fig)


def test_report_embeds_every_figure_and_summarises_each_study(tmp_path):
    pd.DataFrame({"model": ["impulse"] * 2, "scene": ["side"] * 2, "setting": ["{}", '{"dt": 0.01}'],
                  "wall_time_s": [1e-3, 5e-4], "error_m": [0.01, 0.2], "error_deg": [0.1, 2.0],
                  "error_kind": ["numerical"] * 2}).to_csv(tmp_path / "workprecision.csv", index=False)
    pd.DataFrame({"model": ["impulse"] * 3, "setting": ["{}"] * 3, "speed_kmh": [10, 50, 90],
                  "ok": [True, False, True], "violation": [None, "below_road", None]}
                 ).to_csv(tmp_path / "stability.csv", index=False)
    pd.DataFrame({"model": ["impulse"] * 2, "n_vehicles": [2, 32], "variant": ["parked"] * 2,
                  "wall_time_s": [1e-3, 3e-3]}).to_csv(tmp_path / "scaling.csv", index=False)
    for name in ("workprecision_side.png", "stability_impulse.png", "scaling.png"):
        _png(tmp_path / name)
    page = write_report(tmp_path).read_text()
    images = re.findall(r'src="data:image/png;base64,([A-Za-z0-9+/=]+)"', page)
    assert len(images) == 3
    for data in images:
        assert base64.b64decode(data).startswith(b"\x89PNG")
    assert not re.search(r'src="(?!data:)', page), "every figure is embedded, none referenced by path"
    assert "below_road" in page and "not run" in page  # stability's violation kinds; validation missing


def test_study_bad_input_is_one_line_exit_2(tmp_path):
    for argv, key in ((["nosuch", "--out", str(tmp_path)], "study"),
                      (["stability", "--models", "impuls", "--out", str(tmp_path)], "--models"),
                      (["stability", "--out", str(tmp_path / "f" / "x")], "--out")):
        if key == "--out":
            (tmp_path / "f").write_text("a file, not a folder")
        r = subprocess.run([sys.executable, "-m", "crashlab.cli", "study", *argv], capture_output=True, text=True)
        assert r.returncode == 2, (argv, r.stderr)
        assert len(r.stderr.strip().splitlines()) == 1 and key in r.stderr, r.stderr
