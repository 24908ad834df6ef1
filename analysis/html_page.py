"""The one-page HTML report: a self-contained page (style inline, figures embedded as
base64 PNG) of headed sections holding tables, figures and text.
"""

from __future__ import annotations

import base64
import html
from pathlib import Path

import pandas as pd

from .tables import format_table

__all__ = ["html_report"]


_CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Helvetica,Arial,sans-serif;max-width:1100px;
margin:2em auto;padding:0 1em;color:#222;line-height:1.45}
h1{font-size:1.5em;margin-bottom:.2em}h2{font-size:1.15em;margin-top:1.6em;border-bottom:1px solid #ddd}
table{border-collapse:collapse;font-size:.82em;margin:.6em 0}
th,td{border-bottom:1px solid #e4e4e4;padding:.2em .6em;text-align:right}
th{background:#f4f4f4}td:first-child,th:first-child{text-align:left}
img{max-width:100%;height:auto;border:1px solid #eee}
.claim{background:#fff6e8;border-left:4px solid #D55E00;padding:.5em .8em;margin:.6em 0}
.meta{color:#666;font-size:.85em}.note{color:#555;font-size:.85em}
"""


def _img(path: Path) -> str:
    data = base64.b64encode(Path(path).read_bytes()).decode("ascii")
    return f'<img alt="{html.escape(Path(path).stem)}" src="data:image/png;base64,{data}">'


def html_report(
    sections: list, path, *, title: str, meta: str = "", labels: dict | None = None
) -> Path:
    """Write a one-page self-contained HTML report.

    Parameters
    ----------
    sections : list of (str, list)
        ``(heading, items)``; an item is a DataFrame (a table), a Path to a PNG (embedded
        as base64), or a str (HTML paragraph text; escaped unless it starts with ``<``).
    labels : dict, optional
        Scene id → display name, applied to a ``scene`` column of every table.
    """
    labels = labels or {}
    parts = [
        f"<!doctype html><html lang='en'><head><meta charset='utf-8'>"
        f"<title>{html.escape(title)}</title><style>{_CSS}</style></head><body>",
        f"<h1>{html.escape(title)}</h1>",
    ]
    if meta:
        parts.append(f"<p class='meta'>{meta}</p>")
    for heading, items in sections:
        parts.append(f"<h2>{html.escape(heading)}</h2>")
        for item in items:
            if isinstance(item, pd.DataFrame):
                shown = item.copy()
                if "scene" in shown:
                    shown["scene"] = shown["scene"].map(lambda v: labels.get(v, v))
                parts.append(format_table(shown).to_html(index=False, border=0, escape=True))
            elif isinstance(item, Path):
                parts.append(_img(item))
            else:
                text = str(item)
                parts.append(text if text.startswith("<") else f"<p>{html.escape(text)}</p>")
    parts.append("</body></html>")
    path = Path(path)
    path.write_text("\n".join(parts), encoding="utf-8")
    return path
