"""Result tables as text and files: display formatting of cells (p-values, frames,
counts), GitHub Markdown and ``booktabs`` LaTeX tables, and :func:`write_table`, which
writes one table as CSV (raw values), Markdown and LaTeX.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable
from pathlib import Path

import numpy as np
import pandas as pd

__all__ = ["format_table", "to_markdown", "to_latex", "write_table"]


def _fmt(col: str, v: object) -> str:
    if v is None or (isinstance(v, float) and math.isnan(v)) or v is pd.NA:
        return ""
    if isinstance(v, bool | np.bool_):
        return "yes" if v else "no"
    if isinstance(v, int | np.integer):
        return str(int(v))
    if isinstance(v, float | np.floating):
        v = float(v)
        if col.startswith("p_") or col == "p":
            return "<1e-300" if v < 1e-300 else (f"{v:.2g}" if v < 0.001 else f"{v:.3f}")
        # Frames and counts are whole numbers even when a column holds NaN (float dtype):
        # "54", not "54.000".
        if (
            v.is_integer()
            and abs(v) < 1e6
            and (
                col in ("predicted_frame", "n", "votes")
                or col.endswith("frame")
                or col.startswith("n_")
            )
        ):
            return str(int(v))
        return f"{v:.1f}" if abs(v) >= 100 else f"{v:.3f}"
    if isinstance(v, tuple | list):
        return ", ".join(map(str, v))
    return str(v)


def format_table(df: pd.DataFrame) -> pd.DataFrame:
    """Every cell as display text (p-values to 2–3 significant digits, others 3 decimals)."""
    return pd.DataFrame({c: [_fmt(str(c), v) for v in df[c]] for c in df.columns})


def to_markdown(df: pd.DataFrame) -> str:
    """A GitHub-flavoured Markdown pipe table of ``df`` (formatted cells, ``|`` escaped):
    :meth:`pandas.DataFrame.to_markdown` (tabulate's ``pipe`` format)."""
    f = format_table(df)
    align = ["right" if _is_numeric(f[c]) else "left" for c in f.columns]
    esc = lambda s: str(s).replace("|", "\\|")  # noqa: E731
    f = f.map(esc).rename(columns=esc)
    return f.to_markdown(index=False, tablefmt="pipe", disable_numparse=True, colalign=align) + "\n"


_LATEX_ESCAPES = {
    "\\": r"\textbackslash{}",
    "&": r"\&",
    "%": r"\%",
    "$": r"\$",
    "#": r"\#",
    "_": r"\_",
    "{": r"\{",
    "}": r"\}",
    "~": r"\textasciitilde{}",
    "^": r"\textasciicircum{}",
    "<": r"\textless{}",
    ">": r"\textgreater{}",
    "−": "-",
    "–": "--",
    "±": r"$\pm$",
    "α": r"$\alpha$",
    "|": r"\textbar{}",
}


def _latex_escape(s: str) -> str:
    return "".join(_LATEX_ESCAPES.get(ch, ch) for ch in str(s))


def to_latex(df: pd.DataFrame, *, caption: str = "", label: str = "") -> str:
    """A ``booktabs`` LaTeX table of ``df`` (formatted cells, special characters escaped),
    written by :meth:`pandas.io.formats.style.Styler.to_latex`: numeric columns
    right-aligned, the caption above the table."""
    f = format_table(df)
    spec = "".join("r" if _is_numeric(f[c]) else "l" for c in f.columns)
    f = f.map(_latex_escape).rename(columns=_latex_escape)
    styler = f.style.hide(axis="index").set_table_styles([{"selector": "small", "props": ":;"}])
    return styler.to_latex(
        column_format=spec,
        position="ht",
        position_float="centering",
        hrules=True,
        caption=_latex_escape(caption) if caption else None,
        label=label or None,
    )


def _is_numeric(cells: Iterable[str]) -> bool:
    """Whether a column of formatted cells holds only numbers (and blanks)."""
    return all(_is_number(v) for v in cells if v != "")


def _is_number(s: str) -> bool:
    try:
        float(s.lstrip("<"))
        return True
    except ValueError:
        return False


def write_table(df: pd.DataFrame, stem: str | Path, *, caption: str = "") -> list[Path]:
    """Write ``df`` as ``<stem>.csv`` (raw values), ``.md`` and ``.tex`` (formatted)."""
    stem = Path(stem)
    stem.parent.mkdir(parents=True, exist_ok=True)
    csv_df = df.copy()
    for c in csv_df.columns:
        if csv_df[c].map(lambda v: isinstance(v, tuple)).any():
            csv_df[c] = csv_df[c].map(lambda v: json.dumps(list(v)) if isinstance(v, tuple) else v)
    paths = [stem.with_suffix(".csv"), stem.with_suffix(".md"), stem.with_suffix(".tex")]
    csv_df.to_csv(paths[0], index=False)
    paths[1].write_text((f"{caption}\n\n" if caption else "") + to_markdown(df), encoding="utf-8")
    paths[2].write_text(to_latex(df, caption=caption, label=f"tab:{stem.name}"), encoding="utf-8")
    return paths
