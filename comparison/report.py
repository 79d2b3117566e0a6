"""`crashlab study all`: one self-contained page, DIR/report.html, with every study's table and figures
(PNG embedded as base64 data URIs, so the page can be mailed or archived alone).

Each study's table is a summary of its CSV built from the CSV's contract columns only, so it holds for
every model, plugins included; the full CSVs stay beside the page.
"""
from __future__ import annotations

import base64
import html
import importlib
from pathlib import Path

import pandas as pd

from . import STUDIES
from .base import shown_column

# Each summary reads the CSV as written, in the units its columns name (`--units`: base.shown_column).


def _workprecision(df: pd.DataFrame, system: str = "si") -> pd.DataFrame:
    """Each model's default setting per scene: wall time and errors (numerical and against references)."""
    if "is_default" in df:
        df = df[df["is_default"].astype(bool)]
    else:
        df = df[df["setting"] == "{}"]
    return df.pivot_table(index=["model", "scene"], columns="error_kind",
                          values=["wall_time_s", shown_column("error_m", system)], aggfunc="first")


def _stability(df: pd.DataFrame, system: str = "si") -> pd.DataFrame:
    """Runs and the share not ok per model and setting, with the violation kinds seen."""
    def kinds(v):
        seen = sorted({k for x in v.dropna() for k in str(x).split("|") if k})
        return ", ".join(seen)
    g = df.groupby(["model", "setting"], sort=False)
    return pd.DataFrame({"runs": g.size(), "not ok": g["ok"].apply(lambda s: int((~s.astype(bool)).sum())),
                         "violations": g["violation"].apply(kinds)})


def _scaling(df: pd.DataFrame, system: str = "si") -> pd.DataFrame:
    """Wall time per simulation [s] against the number of vehicles, per model and variant."""
    return df.pivot_table(index=["model", "variant"], columns="n_vehicles", values="wall_time_s", aggfunc="median")


def _validation(df: pd.DataFrame, system: str = "si") -> pd.DataFrame:
    return df[["model", "test", "quantity", "unit", "published", "simulated", "error"]]


def _pc_crash(df: pd.DataFrame, system: str = "si") -> pd.DataFrame:
    """Rest-pose distance to PC-Crash [m, or ft] per case and variant, both vehicles."""
    depth = shown_column("engagement_depth", system)
    df = df.assign(**{depth: df[depth].fillna(0.0)})
    return df.pivot_table(index=["model", "law", "contact", depth], columns=["case", "vehicle"],
                          values=[shown_column("d_pc_crash_m", system)])  # a list: the heading names the unit


SUMMARIES = {"workprecision": _workprecision, "stability": _stability, "scaling": _scaling,
             "validation": _validation, "pc_crash": _pc_crash}


def _text(name: str) -> str:
    """The first paragraph of the study module's docstring: what the study does."""
    try:
        doc = importlib.import_module(f"crashlab.comparison.{name}").__doc__ or ""
    except ImportError:  # a study this installation does not have
        return ""
    return " ".join(doc.strip().split("\n\n")[0].split())


def _figure(path: Path) -> str:
    data = base64.b64encode(path.read_bytes()).decode("ascii")
    return (f'<figure><img alt="{html.escape(path.name)}" src="data:image/png;base64,{data}">'
            f"<figcaption>{html.escape(path.name)}</figcaption></figure>")


def write_report(out: Path, studies=STUDIES, system: str = "si") -> Path:
    """DIR/report.html from the CSVs and figures the studies wrote into `out` (in `system`'s units, as the
    studies wrote them)."""
    parts = ["<!DOCTYPE html><html><head><meta charset='utf-8'><title>crashlab comparison studies</title>",
             "<style>body{font-family:sans-serif;max-width:1100px;margin:auto}table{border-collapse:collapse;"
             "font-size:13px}td,th{border:1px solid #bbb;padding:2px 6px}img{max-width:100%}</style></head><body>",
             "<h1>crashlab comparison studies</h1>"]
    for name in studies:
        csv = out / f"{name}.csv"
        parts.append(f"<h2>{html.escape(name)}</h2><p>{html.escape(_text(name))}</p>")
        if not csv.is_file():
            parts.append("<p><em>not run</em></p>")
            continue
        df = pd.read_csv(csv)
        try:
            table = SUMMARIES[name](df, system)
        except (KeyError, ValueError, TypeError) as err:  # a CSV without the contract columns
            table = df.head(50)
            parts.append(f"<p><em>summary not available ({html.escape(str(err))}); first rows:</em></p>")
        parts.append(table.to_html(float_format=lambda v: f"{v:.4g}", na_rep="—"))
        parts.append(f"<p>Full table: {html.escape(csv.name)} ({len(df)} rows).</p>")
        for fig in sorted(out.glob(f"{name}*.png")):
            parts.append(_figure(fig))
    parts.append("</body></html>")
    path = out / "report.html"
    path.write_text("\n".join(parts), encoding="utf-8")
    return path
