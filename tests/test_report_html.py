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

from crashlab.reconstruction import html_report, load_study
from crashlab.reconstruction.infer import run_posterior
from crashlab.reconstruction.posterior import load_posterior

REPO = Path(__file__).resolve().parent.parent
SIDE = REPO / "studies" / "pc_crash" / "side.toml"
CASE5 = REPO / "studies" / "reconstruction" / "case5.toml"
TWIN_INFER = REPO / "studies" / "infer" / "twin_infer.toml"
SIZE_LIMIT = 5_000_000  # bytes: issue 15's limit for case 5's report.html
# a shown number is within this of the true one: html_report.num's 3 decimals or 4 significant digits
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


@pytest.fixture(scope="module")
def infer_out(tmp_path_factory):
    out = tmp_path_factory.mktemp("infer") / "out"
    post = load_posterior(TWIN_INFER)
    post.settings = post.settings.model_copy(update={"walkers": 8, "burn": 4, "samples": 160, "draws_plotted": 2})
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(html_report, "_animate", two_frame_gif)
        run_posterior(post, out, progress=False)
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
    assert html_report.refine_section(tmp_path) == ""
    (tmp_path / "refine.md").write_text("# Refinement\n\nV1.speed <narrowed> & kept\n")
    pd.DataFrame({"variable": ["V1.speed", "V2.speed"], "before": [49.9, 30.1], "after": [50.0004, 1.5e-5]}) \
        .to_csv(tmp_path / "refine.csv", index=False)
    text = html_report.refine_section(tmp_path)
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
