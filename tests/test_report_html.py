"""DIR/report.html of `crashlab reconstruct --out DIR` and `crashlab infer --out DIR` (issue 15, item 6;
crashlab.reconstruction.html_report): one self-contained page. Parsed with html.parser: every <img> is a
data: URI whose bytes are the figure's file, every figure the run wrote is embedded, nothing is loaded from
elsewhere, the Pareto table holds pareto.csv row by row, the posterior table the quantiles of posterior.csv,
the evidence its sigmas, refine.md/refine.csv appear when a refine step wrote them, and a missing or failing
animation is said so. The default runs use a tiny study with the animation replaced by a two-frame GIF; the
slow test runs case 5 with the real animation, checks the 5 MB limit and screenshots the page in headless
Chromium."""
from __future__ import annotations

import base64
import math
import shutil
import subprocess
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from conftest import two_frame_gif

from crashlab.reconstruction import html_report, html_sections, load_study
from crashlab.reconstruction.infer import run_posterior
from crashlab.reconstruction.posterior import load_posterior

REPO = Path(__file__).resolve().parent.parent
SIDE = REPO / "studies" / "pc_crash" / "side.toml"
CASE5 = REPO / "studies" / "reconstruction" / "case5.toml"
TWIN_INFER = REPO / "studies" / "infer" / "twin_infer.toml"
SIZE_LIMIT = 5_000_000  # bytes: issue 15's limit for case 5's report.html
# a shown number is within this of the true one: html_page.num's 3 decimals or 4 significant digits
ABS_TOL, REL_TOL = 5e-4, 5e-4
PNG, GIF = b"\x89PNG\r\n\x1a\n", b"GIF8"


class Page(HTMLParser):
    """The parts of a page the tests read: images, tags, links and every table by id (header, rows)."""

    def __init__(self, text: str):
        super().__init__()
        self.imgs, self.tags, self.urls, self.tables = [], [], [], {}
        self._table = self._row = self._cell = None
        self.text = []
        self.feed(text)

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        self.tags.append(tag)
        for key in ("src", "href", "data", "poster", "srcset"):
            if key in a:
                self.urls.append((tag, key, a[key]))
        if tag == "img":
            self.imgs.append(a)
        elif tag == "table":
            self._table = self.tables.setdefault(a.get("id") or f"table{len(self.tables)}", [])
        elif tag == "tr" and self._table is not None:
            self._row = []
            self._table.append(self._row)
        elif tag in ("td", "th") and self._row is not None:
            self._cell = []

    def handle_endtag(self, tag):
        if tag in ("td", "th") and self._cell is not None:
            self._row.append("".join(self._cell).strip())
            self._cell = None
        elif tag == "table":
            self._table = self._row = None

    def handle_data(self, data):
        self.text.append(data)
        if self._cell is not None:
            self._cell.append(data)


def _read(out: Path) -> Page:
    return Page((out / "report.html").read_text(encoding="utf-8"))


def _tiny_study(tmp_path: Path) -> Path:
    """twin1 (the two speeds free, evidence the model's own run) with 8 x 2 evaluations and a polish of 6,
    simulated in this process."""
    text = (REPO / "studies" / "reconstruction" / "twin1.toml").read_text()
    for old, new in (('scene = "../pc_crash/side.toml"', f'scene = "{SIDE.as_posix()}"'),
                     ("pop_size = 75", "pop_size = 8"), ("generations = 20", "generations = 2"),
                     ("evaluations = 250", "evaluations = 6"),
                     ('backend = "serial"', 'backend = "serial"\ntimeout_s = 0')):
        assert old in text, old
        text = text.replace(old, new, 1)
    path = tmp_path / "tiny.toml"
    path.write_text(text)
    return path


@pytest.fixture(scope="module")
def reconstruct_out(tmp_path_factory):
    out = tmp_path_factory.mktemp("reconstruct") / "out"
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(html_report, "_animate", two_frame_gif)
        load_study(_tiny_study(out.parent)).run(out_dir=out)
    return out


_INFER = {}  # the posterior and its result of infer_out, for the median draw's check


@pytest.fixture(scope="module")
def infer_out(tmp_path_factory):
    out = tmp_path_factory.mktemp("infer") / "out"
    post = load_posterior(TWIN_INFER)
    post.settings = post.settings.model_copy(update={"walkers": 8, "burn": 4, "samples": 160, "draws_plotted": 2})
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(html_report, "_animate", two_frame_gif)
        _INFER.update(post=post, result=run_posterior(post, out, progress=False))
    return out


def assert_self_contained(out: Path, page: Page, figures: set[str]):
    """Every <img> a data: URI whose bytes equal its file beside the page; every figure in `figures` among
    them; no script, style sheet, frame or object, and no URL that is not a data: URI."""
    assert page.imgs, "no figure on the page"
    embedded = {}
    for img in page.imgs:
        src = img.get("src", "")
        assert src.startswith(("data:image/png;base64,", "data:image/gif;base64,")), src[:60]
        data = base64.b64decode(src.split(",", 1)[1], validate=True)
        assert data[:8] == PNG or data[:4] == GIF
        name = img.get("data-file")
        assert data == (out / name).read_bytes(), name
        embedded[name] = data
    assert figures <= set(embedded), figures - set(embedded)
    assert not {"script", "link", "iframe", "object", "embed"} & set(page.tags)
    assert all(url.startswith("data:") for _, _, url in page.urls), page.urls
    text = (out / "report.html").read_text(encoding="utf-8")
    assert "url(" not in text and "@import" not in text
    assert len(text.encode()) < SIZE_LIMIT


def assert_cells_match(cells: list[str], values):
    for c, v in zip(cells, values, strict=True):
        if isinstance(v, float) and np.isnan(v):
            assert c == ""
        else:
            assert abs(float(c) - v) <= ABS_TOL + REL_TOL * abs(v), (c, v)


# ------------------------------------------------------------------ crashlab reconstruct
def test_reconstruction_report_embeds_every_figure(reconstruct_out):
    out = reconstruct_out
    page = _read(out)
    figures = {p.name for p in out.glob("*.png")} | {"best.gif"}
    assert {"objectives.png", "solution_0.png"} <= figures
    assert_self_contained(out, page, figures)


def pareto_tables(page: Page) -> list[list[list[str]]]:
    """The Pareto set's tables ("pareto", "pareto-2", ...) in page order."""
    return [t for name, t in page.tables.items() if name == "pareto" or name.startswith("pareto-")]


def test_pareto_table_holds_pareto_csv_row_by_row(reconstruct_out):
    """Split into tables of at most PARETO_COLUMNS_MAX columns (no box hides any), each led by "row": together
    every column of pareto.csv exactly once, every cell equal to the CSV's."""
    table = pd.read_csv(reconstruct_out / "pareto.csv")
    tables = pareto_tables(_read(reconstruct_out))
    assert len(tables) >= 2  # twin1's 28 columns do not fit one
    seen = []
    for rows in tables:
        head = rows[0]
        assert head[0] == "row" and 2 <= len(head) <= html_report.PARETO_COLUMNS_MAX + 1
        assert len(rows) - 1 == len(table) >= 1
        seen += head[1:]
        for k, cells in enumerate(rows[1:]):
            assert cells[0] == str(k)
            assert_cells_match(cells[1:], table.loc[k, head[1:]].to_numpy(dtype=float))
    assert sorted(seen) == sorted(table.columns) and len(seen) == len(set(seen))
    assert 'class="scroll"' not in (reconstruct_out / "report.html").read_text()


def test_pareto_table_keeps_every_digit_it_shows_and_says_when_it_is_cut(monkeypatch):
    """Numbers from 1e-12 to 1e9, negative, NaN (an unmeasured heading) within the stated tolerance; more
    rows than PARETO_ROWS_MAX: the first ones, and the page says so."""
    values = [1.234567e-12, -3.3e-5, 0.0012345, -0.4996, 49.99951, -172.61049, 12345678.9, 9.9e8, math.nan, 0.0]
    table = pd.DataFrame({"V1.speed": values, "f_V1": values[::-1]})
    monkeypatch.setattr(html_report, "PARETO_ROWS_MAX", 7)
    text = html_report.pareto_table_html(table)
    rows = Page(text).tables["pareto"]
    assert rows[0] == ["row", "V1.speed", "f_V1"] and len(rows) == 1 + 7
    for k, cells in enumerate(rows[1:]):
        assert cells[0] == str(k)
        assert_cells_match(cells[1:], table.iloc[k].to_numpy(dtype=float))
    assert "first 7 of 10 rows" in text
    assert "rows are shown" not in html_report.pareto_table_html(table.head(7))


def test_reconstruction_report_names_the_study_and_the_evidence(reconstruct_out):
    page = _read(reconstruct_out)
    study = load_study(reconstruct_out.parent / "tiny.toml")
    free = page.tables["free"]
    assert free[0][:4] == ["free variable", "unit", "lower", "upper"]
    assert [r[:4] for r in free[1:]] == [["V1.speed", "km/h", "30.000", "70.000"],
                                         ["V2.speed", "km/h", "10.000", "50.000"]]
    ev = page.tables["evidence"]
    for (n, (x, y, h)), cells in zip(study.evidence.items(), ev[1:], strict=True):
        assert cells[0] == n
        assert_cells_match(cells[1:], [x, y, h])
    text = " ".join(page.text)
    assert "nsga-sharing" in text and "impulse" in text and "Side collision" in text


def test_no_feasible_solution_is_a_page_that_says_so(reconstruct_out, tmp_path):
    from crashlab.reconstruction.report import ReconstructionResult
    study = load_study(reconstruct_out.parent / "tiny.toml")
    info = {"optimizer": "nsga-sharing", "search_evaluations": 16, "polish_evaluations": 0, "polish_budget": 6}
    result = ReconstructionResult(pd.DataFrame(), 16, 16, 0.0, 1.0, study.make_problem(), info)
    html_report.write_reconstruction_report(study, result, tmp_path, [], near=pd.DataFrame(columns=["V1.speed"]),
                                            tol=0.1, notes=["objectives.png could not be drawn: `x` **y**"],
                                            failure_reasons={"model raised N": 16})
    page = _read(tmp_path)
    text = " ".join(page.text)
    assert "No feasible solution" in text and "animation unavailable: no solution to animate" in text
    assert "objectives.png: not drawn" in text
    assert ["failed: model raised N", "16"] in page.tables["evaluations"]
    assert "pareto" not in page.tables and not page.imgs
    assert "<code>x</code> <strong>y</strong>" in (tmp_path / "report.html").read_text()


# ------------------------------------------------------------------ crashlab infer
def test_posterior_report_embeds_its_figures_the_quantiles_and_the_sigmas(infer_out):
    out = infer_out
    page = _read(out)
    assert_self_contained(out, page, {"corner.png", "posterior_top_view.png", "best.gif"})
    df = pd.read_csv(out / "posterior.csv")
    rows = page.tables["posterior"]
    head = rows[0]
    assert [r[0] for r in rows[1:]] == ["V1.speed", "V2.speed", "road.friction"]
    for cells in rows[1:]:
        q = df[cells[0]].quantile([0.5, 0.05, 0.95]).to_numpy()
        assert_cells_match([cells[head.index(c)] for c in ("median", "5 %", "95 %")], q)
    # the evidence with its sigmas: each rest pose's x and y at 0.2 m, its heading at 5 deg
    ev = {(r[0], r[2]): r for r in page.tables["evidence"][1:]}
    for n in ("V1", "V2"):
        assert ev[(f"rest.{n}", "x")][4] == ev[(f"rest.{n}", "y")][4] == "0.200"
        assert ev[(f"rest.{n}", "heading")][4] == "5.000"
    assert "<td class=\"text\"><code>V1.speed &gt; 50</code></td>" in (out / "report.html").read_text()
    assert [r[0] for r in page.tables["questions"][1:]] == ["V1.speed > 50",
                                                          "V1.speed > V2.speed + 15 and V2.speed < 35"]
    assert "emcee" in " ".join(page.text)


# ------------------------------------------------------------------ animation and refine
def test_a_missing_or_failing_animation_is_said_so(tmp_path, monkeypatch):
    def missing(*a, **k):
        raise ImportError("No module named 'crashlab.tools.animation'")

    def failing(*a, **k):
        raise RuntimeError("no frames")
    monkeypatch.setattr(html_report, "_animate", missing)
    text = html_report.animation_section((None, None), tmp_path, "row 0")
    assert "animation unavailable" in text and "<img" not in text
    monkeypatch.setattr(html_report, "_animate", failing)
    text = html_report.animation_section((None, None), tmp_path, "row 0")
    assert "animation unavailable: RuntimeError: no frames" in text and "<img" not in text
    assert "animation unavailable" in html_report.animation_section(None, tmp_path, "row 0")


def test_refine_files_become_a_section(tmp_path):
    """refine.md (escaped, as written) and refine.csv (a table) make the Refinement section; none without them."""
    assert html_sections.refine_section(tmp_path) == ""
    (tmp_path / "refine.md").write_text("# Refinement\n\nV1.speed <narrowed> & kept\n")
    pd.DataFrame({"variable": ["V1.speed", "V2.speed"], "before": [49.9, 30.1], "after": [50.0004, 1.5e-5]}) \
        .to_csv(tmp_path / "refine.csv", index=False)
    text = html_sections.refine_section(tmp_path)
    assert text.count("<h2>Refinement</h2>") == 1
    assert "V1.speed &lt;narrowed&gt; &amp; kept" in text
    assert "<td>50.000</td>" in text and "<td>1.500e-05</td>" in text and "<td>49.900</td>" in text


# ------------------------------------------------------------------ case 5 in headless Chromium (slow)
def _chromium() -> str | None:
    return next((b for b in ("chromium", "chromium-browser", "google-chrome") if shutil.which(b)), None)


def screenshot(html: Path, png: Path, height: int = 6000) -> Path:
    """Headless Chromium's screenshot of the page (1280 px wide)."""
    browser = _chromium()
    cmd = [browser, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
           f"--window-size=1280,{height}", f"--screenshot={png}", html.resolve().as_uri()]
    subprocess.run(cmd, capture_output=True, timeout=180, check=False)
    return png


def assert_not_blank(png: Path):
    from PIL import Image
    assert png.is_file() and png.read_bytes()[:8] == PNG, png
    grey = np.asarray(Image.open(png).convert("L"), dtype=float)
    assert grey.std() > 10.0  # a blank (or all-grey) page has none
    assert np.mean(grey < 128) > 0.01  # text and figures: dark pixels on more than 1 % of the page


@pytest.mark.slow
@pytest.mark.skipif(_chromium() is None, reason="no chromium binary (Debian: apt-get install chromium)")
def test_case5_report_is_under_5_mb_and_renders_in_headless_chromium(tmp_path, real_report_animation):
    """case 5 as written (250 x 40 + polish, the real animation of its first Pareto row)."""
    out = tmp_path / "case5"
    res = load_study(CASE5).run(out_dir=out)
    size = (out / "report.html").stat().st_size
    print(f"case 5 report.html {size / 1e6:.2f} MB, {len(res.pareto)} Pareto rows")
    assert size < SIZE_LIMIT
    page = _read(out)
    assert_self_contained(out, page, {p.name for p in out.glob("*.png")})
    assert len(page.tables["pareto"]) - 1 == len(res.pareto)
    assert_not_blank(screenshot(out / "report.html", tmp_path / "case5.png"))


# ------------------------------------------------------------------ issue 26: what an expert hands over
def assert_impact_table_is_the_outcomes(rows: list[list[str]], outcome):
    """Every cell of the impact table equals the Outcome's number to the digits printed (half a unit of the
    last printed digit), computed here from the Outcome's public tables: impacts, first_contact and the
    trajectories (a later impact's speed: the last sample before it)."""
    head = rows[0]
    assert head[:3] == ["vehicle", "other", "struck side"] and len(rows) - 1 == len(outcome.impacts) >= 2
    imp = outcome.impacts.assign(crush=[r["crush_energy"] for r in outcome.impact_rows])
    first = outcome.first_contact
    for cells in rows[1:]:
        got = dict(zip(head, cells))
        t = float(got["t [s]"])
        match = imp[(imp.vehicle == got["vehicle"]) & (imp.other == got["other"]) & (abs(imp.t - t) <= 5e-4)]
        assert len(match) == 1, got
        r = match.iloc[0]
        if abs(r.t - imp[imp.vehicle == r.vehicle].t.min()) < 1e-12:
            speed = first.loc[r.vehicle, "speed"]
        else:
            tr = outcome.trajectory(r.vehicle)
            before = tr[tr.t < r.t].iloc[-1]
            speed = math.hypot(before.vx, before.vy)
        expected = {"t [s]": r.t, "speed at impact [km/h]": speed, "delta-V [km/h]": r.delta_v,
                    "EES [km/h]": r.ees, "PDOF [deg]": r.pdof, "PDOF [clock]": r.pdof_clock,
                    "energy dissipated [kJ]": r.energy / 1e3, "of it this vehicle's [kJ]": r.crush / 1e3}
        assert set(expected) == set(head[3:]) and got["struck side"] == r.side
        for key, value in expected.items():
            digits = html_sections.IMPACT_DIGITS[key]
            if isinstance(value, float) and math.isnan(value):
                assert got[key] == "", (key, got[key])
                continue
            assert abs(float(got[key]) - value) <= 0.5 * 10.0 ** -digits + 1e-9, (key, got[key], value)


def test_impact_table_equals_the_outcome_of_pareto_row_0(reconstruct_out):
    """Pareto row 0 simulated again here (the study's model, the start of pareto.csv's first row at full
    precision from the search's archive): each impact and vehicle's time, speed at impact, delta-V, EES,
    PDOF, energy are the Outcome's to the printed digit."""
    import crashlab
    study = load_study(reconstruct_out.parent / "tiny.toml")
    pareto = pd.read_csv(reconstruct_out / "pareto.csv")
    x = pareto.loc[0, [v.label for v in study.variables]].to_numpy(dtype=float)
    outcome = crashlab.simulate(study.make_problem().scene_for(x), model=study.spec.model)
    page = _read(reconstruct_out)
    assert_impact_table_is_the_outcomes(page.tables["impacts"], outcome)
    assert {"solution_0_time.png", "time_distance.png"} <= {img["data-file"] for img in page.imgs}
    # the time-distance table (docs/physics.md §29): each vehicle's distance to go is 0 at its first impact
    td = pd.read_csv(reconstruct_out / "time_distance.csv")
    for name, part in td.groupby("vehicle"):
        t_c = outcome.impacts.loc[outcome.impacts["vehicle"] == name, "t"].min()
        assert abs(np.interp(t_c, part["t"], part["to_impact"])) < 1e-3, name
    text = (reconstruct_out / "report.html").read_text()
    assert "@media print" in text and "@page" in text  # the print layout of the same page


def test_a_broken_impact_table_fails_the_check(reconstruct_out):
    """The check above fails on a table one printed digit off (here: delta-V 0.1 km/h)."""
    import crashlab
    study = load_study(reconstruct_out.parent / "tiny.toml")
    x = pd.read_csv(reconstruct_out / "pareto.csv").loc[0, [v.label for v in study.variables]].to_numpy(float)
    outcome = crashlab.simulate(study.make_problem().scene_for(x), model=study.spec.model)
    rows = [list(r) for r in _read(reconstruct_out).tables["impacts"]]
    j = rows[0].index("delta-V [km/h]")
    rows[1][j] = f"{float(rows[1][j]) + 0.1:.1f}"
    with pytest.raises(AssertionError):
        assert_impact_table_is_the_outcomes(rows, outcome)


def test_posterior_report_shows_the_median_draw_and_its_impacts(infer_out):
    import crashlab
    post, res = _INFER["post"], _INFER["result"]
    from crashlab.reconstruction.infer_report import median_draw_index
    k = median_draw_index(res)
    outcome = crashlab.simulate(post.setter(res.samples[k]), model=post.study.spec.model)
    page = _read(infer_out)
    assert_impact_table_is_the_outcomes(page.tables["impacts"], outcome)
    assert {"median_draw_time.png", "median_draw.png", "time_distance.png"} <= {img["data-file"] for img in page.imgs}
    assert f"draw {k} of posterior.csv" in " ".join(page.text)


def test_median_draw_is_the_draw_nearest_every_median():
    """Two modes at -1 and +1 (x) with y tied to x: the component-wise median (0, 0) is no draw; the draw
    nearest it, in units of each variable's 90 % interval, is the one returned."""
    from types import SimpleNamespace

    from crashlab.reconstruction.infer_report import median_draw_index
    rng = np.random.default_rng(1)
    x = np.concatenate([rng.normal(-1, 0.1, 500), rng.normal(1, 0.1, 500)])
    samples = np.column_stack([x, 100 * x + rng.normal(0, 1, 1000)])
    res = SimpleNamespace(samples=samples, log_likelihood=np.zeros(1000),
                          interval=lambda: np.quantile(samples, (0.05, 0.5, 0.95), axis=0))
    k = median_draw_index(res)
    lo, med, hi = res.interval()
    d = np.sum(((samples - med) / (hi - lo)) ** 2, axis=1)
    assert k == int(np.argmin(d)) and d[k] <= d.min()
    res.log_likelihood = np.where(np.arange(1000) == k, -np.inf, 0.0)  # a draw that could not be scored
    assert median_draw_index(res) != k


def _case_study(tmp_path, case: str) -> Path:
    path = tmp_path / "case.toml"
    path.write_text((REPO / "studies" / "reconstruction" / "twin1.toml").read_text()
                    .replace('scene = "../pc_crash/side.toml"', f'scene = "{SIDE.as_posix()}"') + "\n" + case)
    return path


def test_case_is_shown_first_escaped(reconstruct_out, tmp_path):
    from crashlab.reconstruction.report import ReconstructionResult
    study = load_study(_case_study(tmp_path, '[case]\nid = "2026/117 <A&B>"\nanalyst = "J. Doe"\ndate = 2026-11-26\n'
                                         'notes = "for the court"\nassumptions = ["dry road", "x < 3 & y"]\n'
                                         'limitations = ["no EDR"]\n'))
    info = {"optimizer": "nsga-sharing", "search_evaluations": 0, "polish_evaluations": 0, "polish_budget": 0}
    result = ReconstructionResult(pd.DataFrame(), 0, 0, 0.0, 1.0, study.make_problem(), info)
    html_report.write_reconstruction_report(study, result, tmp_path, [], near=None)
    page = _read(tmp_path)
    assert page.tables["case"] == [["case", "2026/117 <A&B>"], ["analyst", "J. Doe"], ["date", "2026-11-26"],
                                   ["notes", "for the court"]]
    text = (tmp_path / "report.html").read_text()
    assert text.index("<h2>Case</h2>") < text.index("<h2>Study</h2>") < text.index("<h2>Evidence</h2>")
    assert "2026/117 &lt;A&amp;B&gt;" in text and "<li>x &lt; 3 &amp; y</li>" in text and "<li>no EDR</li>" in text
    # without [case]: the page says where to add one
    study = load_study(_case_study(tmp_path, ""))
    html_report.write_reconstruction_report(study, result, tmp_path, [], near=None)
    assert "no [case] table" in " ".join(_read(tmp_path).text)


@pytest.mark.parametrize("case, key", [('assumptions = "one string"', "case.assumptions"),
                                       ("analyst = 3", "case.analyst"), ('idd = "x"', "case.idd")])
def test_bad_case_is_one_line_exit_2(tmp_path, capsys, case, key):
    from types import SimpleNamespace

    from conftest import assert_one_error_line

    from crashlab.cli import main
    path = _case_study(tmp_path, "[case]\n" + case + "\n")
    code = main(["reconstruct", str(path)])
    cap = capsys.readouterr()
    assert_one_error_line(SimpleNamespace(returncode=code, stdout=cap.out, stderr=cap.err), path, key)


def test_objectives_figure_takes_zero_objectives_and_says_why_none_is_feasible(tmp_path):
    """A perfect fit (objective 0) is drawn on linear axes (log axes refuse it: "Data cannot be log-scaled");
    with no feasible evaluation nothing is drawn and the reason counts the infeasible starts."""
    import matplotlib
    matplotlib.use("Agg")
    from types import SimpleNamespace

    import matplotlib.pyplot as plt

    from crashlab.reconstruction import search_figures
    from crashlab.reconstruction.problem import evaluation_counts
    problem = SimpleNamespace(objective_names=["V1", "V2"], evidence_set=None)
    F = np.array([[0.0, 0.0], [0.5, 2.0], [1.0, 0.1]])
    arch = {"X": np.zeros((5, 1)), "F": np.vstack([F, [[9, 9], [9, 9]]]), "ok": np.array([1, 1, 1, 1, 0], bool),
            "G": np.array([[0, 0], [0, 0], [0, 0], [0.3, 0], [1, 1]], float), "reason": np.array([""] * 4 + ["x"])}
    pareto = pd.DataFrame({"f_V1": [0.0], "f_V2": [0.0]})
    assert search_figures.objectives_figure(problem, arch, pareto, tmp_path / "o.png", plt) is None
    ax = plt.gcf().axes[0]
    assert ax.get_xscale() == "linear" and ax.get_xlabel().startswith("f_V1 [m]") and ax.get_ylabel() == "f_V2 [m]"
    plt.close("all")
    arch_pos = dict(arch, F=arch["F"] + 0.1)
    search_figures.objectives_figure(problem, arch_pos, pareto + 0.1, tmp_path / "o.png", plt)
    assert plt.gcf().axes[0].get_xscale() == "log"
    plt.close("all")
    none = dict(arch, ok=np.array([1, 1, 0, 0, 0], bool), G=np.array([[0.2, 0], [0, 1], [0, 0], [0, 0], [1, 1]]))
    why = search_figures.objectives_figure(problem, none, pareto.iloc[:0], tmp_path / "n.png", plt)
    assert why == ("no feasible evaluation to draw: 0 of 5 evaluations feasible: of the others 1 had the vehicles "
                   "overlapping at the start, 1 made no contact, 3 failed (failures.csv gives each reason).")
    assert evaluation_counts(problem, none) == {"total": 5, "feasible": 0, "overlap": 1, "no_contact": 1,
                                                       "failed": 3}


def test_near_optimal_figure_is_in_sigma_with_units(tmp_path):
    import matplotlib
    matplotlib.use("Agg")
    from types import SimpleNamespace

    import matplotlib.pyplot as plt

    from crashlab.reconstruction import search_figures
    from crashlab.reconstruction.schema import FreeVariable
    free = [FreeVariable(vehicle="V1", field="speed", lower=30, upper=70),
            FreeVariable(vehicle="V2", field="y", lower=-3, upper=3)]
    near = pd.DataFrame({"V1.speed": [40.0, 41.0], "V2.y": [0.1, 0.2], "f_V1": [0.5, 0.9], "f_V2": [0.2, 1.0]})
    for evidence_set, unit in ((object(), "sigma"), (None, "m")):
        search_figures.near_optimal_figure(SimpleNamespace(free=free, evidence_set=evidence_set), near,
                                           tmp_path / "n.png", plt)
        ax, bar = plt.gcf().axes
        assert bar.get_ylabel() == f"largest objective [{unit}]"
        assert (ax.get_xlabel(), ax.get_ylabel()) == ("V1.speed [km/h]", "V2.y [m]")
        plt.close("all")


def test_spread_between_models_is_a_table(tmp_path):
    """After a [refine]: both models' rest poses at each candidate, the distance between them and the heading
    difference wrapped to -180..180 (179 and -179 deg are 2 deg apart)."""
    from types import SimpleNamespace
    t = pd.DataFrame({"candidate": [0], "row": [3], "model_gap_V1": [0.5],
                      "search_rest_V1_x": [1.0], "search_rest_V1_y": [2.0], "search_rest_V1_heading": [179.0],
                      "refine_rest_V1_x": [1.3], "refine_rest_V1_y": [2.4], "refine_rest_V1_heading": [-179.0]})
    refined = SimpleNamespace(table=t, search_model="impulse", model="multibody", source="Pareto rows")
    text = html_sections.refine_section(tmp_path, refined, {"V1": (1.1, 2.1, None)})
    rows = Page(text).tables["spread"]
    assert rows[0][:3] == ["candidate", "row", "vehicle"] and "distance apart [m]" in rows[0]
    got = dict(zip(rows[0], rows[1]))
    assert got["distance apart [m]"] == "0.50" and got["heading multibody - impulse [deg]"] == "2.0"
    assert got["impulse x [m]"] == "1.00" and got["multibody y [m]"] == "2.40"
    assert got["measured x, y [m], heading [deg]"] == "1.10, 2.10"
    assert "at most V1 0.50 m apart" in text


def _weasyprint() -> bool:
    return html_report.pdf_writer()[0] is not None


@pytest.mark.skipif(not _weasyprint(), reason="WeasyPrint (or its Pango library) is not installed")
def test_pdf_is_the_same_report_on_a4(reconstruct_out, tmp_path):
    html = tmp_path / "report.html"
    shutil.copy(reconstruct_out / "report.html", html)
    pdf = html_report.write_pdf(html)
    data = pdf.read_bytes()
    assert pdf.name == "report.pdf" and data.startswith(b"%PDF-")
    if shutil.which("pdftotext"):  # Debian: poppler-utils
        text = subprocess.run(["pdftotext", "-layout", str(pdf), "-"], capture_output=True, text=True).stdout
        assert text.count("\f") >= 3  # pages
        for words in ("Pareto set: state at first contact", "The chosen solution", "speed at", "page 1 of"):
            assert words in text, words


def test_pdf_refused_in_one_line_before_the_run(tmp_path, capsys, monkeypatch):
    """--pdf without --out, or without a usable WeasyPrint: exit 2, one line naming --pdf and what to install,
    before any evaluation (no output folder made)."""
    from types import SimpleNamespace

    from conftest import assert_one_error_line

    from crashlab.cli import main
    study = _tiny_study(tmp_path)

    def run(*args):
        code = main(["reconstruct", str(study), *args])
        cap = capsys.readouterr()
        return SimpleNamespace(returncode=code, stdout=cap.out, stderr=cap.err)
    assert_one_error_line(run("--pdf"), study, "--pdf", ["--out"])
    monkeypatch.setattr(html_report, "pdf_writer", lambda: (None, "ImportError: No module named 'weasyprint'"))
    assert_one_error_line(run("--pdf", "--out", str(tmp_path / "o")), study, "--pdf", ["pip install weasyprint"])
    assert not (tmp_path / "o").exists()
