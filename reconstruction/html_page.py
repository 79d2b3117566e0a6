"""The machinery of the report pages (report.html of `crashlab reconstruct` and `crashlab infer`;
crashlab.reconstruction.html_report): one self-contained page, every figure embedded as a base64 data: URI,
rendered from the Jinja2 templates in reconstruction/templates/ with autoescape on. Python builds plain data
(numbers formatted by `num`, text as str, the only markup from `md_inline`) in Table, Figure and Solution;
the templates hold every tag. A figure named but not on disk is said so on the page ("not drawn"), never
left as a broken image."""
from __future__ import annotations

import base64
import datetime as _dt
import math
import re
from dataclasses import dataclass, field
from pathlib import Path

from markupsafe import Markup, escape

from crashlab.version import package_version

REPORT_NAME = "report.html"
_MIME = {".png": "image/png", ".gif": "image/gif", ".jpg": "image/jpeg", ".jpeg": "image/jpeg",
         ".svg": "image/svg+xml"}


# ---------------------------------------------------------------- small pieces
def md_inline(text: str) -> Markup:
    """A line of summary.md's markdown as HTML: escaped, **bold** and `code` kept (nothing else is used)."""
    s = str(escape(str(text)))
    s = re.sub(r"\*\*(.+?)\*\*", r"<strong>\1</strong>", s)
    return Markup(re.sub(r"`(.+?)`", r"<code>\1</code>", s))


def wrap_name(text) -> Markup:
    """A column name that may break after '_' and '.' (long headers wrap instead of widening the table)."""
    if isinstance(text, Markup):
        return text
    return Markup(str(escape(str(text))).replace("_", "_<wbr>").replace(".", ".<wbr>"))


def num(value, digits: int = 3) -> str:
    """A table cell's number: fixed `digits` decimals within [1e-3, 1e7), else scientific; empty for NaN
    and None. The shown value is within 0.5e-3 absolute or 0.5e-3 relative of the true one (the test's
    tolerance)."""
    if value is None:
        return ""
    try:
        v = float(value)
    except (TypeError, ValueError):
        return str(value)
    if math.isnan(v):
        return ""
    if v == 0 or 1e-3 <= abs(v) < 1e7 or digits < 3:
        return f"{v:.{digits}f}"
    return f"{v:.{digits}e}"


@dataclass
class Table:
    """An HTML table for the templates: header and rows of cells (str, escaped when rendered, or Markup);
    columns in text_cols are left-aligned."""
    header: list
    rows: list
    id: str | None = None
    text_cols: tuple = (0,)
    caption: str | None = None
    css: str | None = None
    md_cols: tuple = ()  # columns whose cells are summary.md's inline markdown (**bold**, `code`): md_inline


@dataclass
class Figure:
    name: str
    caption: str
    uri: str | None = None  # None: not drawn
    why: str | None = None


@dataclass
class Solution:
    """The chosen solution's section: its impact table and figures."""
    title: str
    intro: str
    impacts: Table | None
    impacts_note: str = ""
    figures: list = field(default_factory=list)


_ENV = None


def environment():
    """The Jinja2 environment of the report templates (package data: reconstruction/templates), autoescaped."""
    global _ENV
    if _ENV is None:
        import jinja2
        _ENV = jinja2.Environment(loader=jinja2.PackageLoader("crashlab.reconstruction", "templates"),
                                  autoescape=True, undefined=jinja2.StrictUndefined, trim_blocks=True,
                                  lstrip_blocks=True, keep_trailing_newline=True)
        _ENV.filters["md"] = md_inline
        _ENV.filters["wrap_name"] = wrap_name
    return _ENV


def render(template: str, **context) -> str:
    return environment().get_template(template).render(**context)


def macro(name: str, *args) -> Markup:
    """One macro of templates/macros.html rendered on its own (a section the tests read alone)."""
    return Markup(getattr(environment().get_template("macros.html").module, name)(*args))


def data_uri(path: Path) -> str:
    mime = _MIME.get(path.suffix.lower(), "application/octet-stream")
    return f"data:{mime};base64," + base64.b64encode(path.read_bytes()).decode("ascii")


def figure_of(path, caption: str, why: str | None = None) -> Figure:
    """The file as a Figure embedded as a data: URI; a missing file is a Figure without one ("not drawn")."""
    path = Path(path)
    return Figure(path.name, caption, data_uri(path) if path.is_file() else None, why)


def write_page(path: Path, text: str) -> Path:
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(text, encoding="utf-8")
    tmp.replace(path)
    return path


def write_report_page(template: str, out_dir: Path, title: str, **context) -> Path:
    """out_dir/report.html rendered from `template` with the title, version and time stamp."""
    stamp = _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    text = render(template, title=title, version=package_version(), stamp=stamp, **context)
    return write_page(Path(out_dir) / REPORT_NAME, text)
