"""``snapshot analyze``: every table (CSV, Markdown, LaTeX), figure (PNG, PDF) and a
one-page, self-contained HTML report.

Layout of the output folder::

    results/
      report.html            one page, images embedded: send it as it is
      summary.json           the headline numbers, machine-readable
      tables/<name>.csv|.md|.tex
      figures/<name>.png|.pdf

Tables (columns documented in :mod:`analysis.votes` and :mod:`analysis.frames`):
``votes`` (Table 2 with shares and Wilson CIs), ``chisquare`` (no preference),
``pairwise`` (ours vs each baseline, exact binomial + Holm), ``strengths`` (Luce model,
bootstrap CIs), ``agreement`` (Fleiss' kappa), ``frame_hits`` (hit rates of the
algorithm and baselines), ``frame_tests`` (permutation tests), ``participants``.
"""

from __future__ import annotations

import base64
import html
import json
import math
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
import pandas as pd

from . import frames as fr
from . import votes as vt
from .load import attention_summary, load_responses, ordered_scenes, pose_choices, view_choices

__all__ = [
    "format_table",
    "to_markdown",
    "to_latex",
    "write_table",
    "analyze",
    "analyze_counts",
    "html_report",
    "DEFAULT_BOOT",
]

#: Bootstrap resamples for the Luce strengths' intervals.
DEFAULT_BOOT = 1000


# ----------------------------------------------------------------- table writers


def _fmt(col: str, v) -> str:
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


def _is_numeric(cells) -> bool:
    """Whether a column of formatted cells holds only numbers (and blanks)."""
    return all(_is_number(v) for v in cells if v != "")


def _is_number(s: str) -> bool:
    try:
        float(s.lstrip("<"))
        return True
    except ValueError:
        return False


def write_table(df: pd.DataFrame, stem, *, caption: str = "") -> list[Path]:
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


# ----------------------------------------------------------------- HTML


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


# ----------------------------------------------------------------- the analyses


def _ci(v, lo, hi) -> str:
    return f"{v:.2f} [{lo:.2f}, {hi:.2f}]"


def _compact_pairwise(pair: pd.DataFrame) -> pd.DataFrame:
    """The pairwise table narrowed for the page (the CSV keeps every column)."""
    return pd.DataFrame(
        {
            "scene": pair["scene"],
            "baseline": pair["baseline"],
            "votes ours : baseline": [
                f"{a} : {b}"
                for a, b in zip(pair["reference_votes"], pair["baseline_votes"], strict=True)
            ],
            "share of ours [95% CP]": [
                _ci(v, lo, hi)
                for v, lo, hi in zip(
                    pair["share_reference"], pair["ci_low"], pair["ci_high"], strict=True
                )
            ],
            "p_value": pair["p_value"],
            "p_holm": pair["p_holm"],
            "verdict": pair["verdict"],
        }
    )


def _pct(v, lo=None, hi=None) -> str:
    if lo is None or (isinstance(lo, float) and math.isnan(lo)):
        return f"{100 * v:.0f}%"
    return f"{100 * v:.0f}% [{100 * lo:.0f}, {100 * hi:.0f}]"


def _compact_hits(hits: pd.DataFrame, tolerances=fr.TOLERANCES_S) -> pd.DataFrame:
    """Hit rates for the page: one ``rate [low, high]`` cell per tolerance."""
    out = pd.DataFrame(
        {
            "scene": hits["scene"],
            "predictor": hits["predictor"],
            "frame": hits["predicted_frame"],
            "mean |Δ| s": hits["mean_abs_error_s"],
            "median |Δ| s": hits["median_abs_error_s"],
        }
    )
    for t in tolerances:
        c = f"hit_{t:g}s"
        out[f"within ±{t:g} s"] = [
            _pct(v, lo, hi)
            for v, lo, hi in zip(hits[c], hits[c + "_low"], hits[c + "_high"], strict=True)
        ]
    return out


def _compact_tests(tests: pd.DataFrame) -> pd.DataFrame:
    """Permutation tests for the page."""
    return pd.DataFrame(
        {
            "scene": tests["scene"],
            "baseline": tests["baseline"],
            "n": tests["n"],
            "mean |Δ| algorithm s": tests["algorithm_mean_abs_s"],
            "mean |Δ| baseline s": tests["baseline_mean_abs_s"],
            "closer by s [95% CI]": [
                _ci(v, lo, hi)
                for v, lo, hi in zip(
                    tests["difference_s"],
                    tests["difference_low"],
                    tests["difference_high"],
                    strict=True,
                )
            ],
            "r (rank-biserial)": tests["rank_biserial"],
            "p_value": tests["p_value"],
            "p_holm": tests["p_holm"],
            "algorithm closer": tests["significant"],
            "test": tests["method"] + np.where(tests["note"] != "", " (" + tests["note"] + ")", ""),
        }
    )


def _compact_strengths(strengths: pd.DataFrame) -> pd.DataFrame:
    """Strengths as scenes × methods, each cell ``value [low, high]``."""
    cell = strengths.assign(
        text=[
            _ci(v, lo, hi)
            for v, lo, hi in zip(
                strengths["strength"], strengths["ci_low"], strengths["ci_high"], strict=True
            )
        ]
    )
    wide = cell.pivot(index="scene", columns="method", values="text")
    wide = wide.loc[
        list(dict.fromkeys(strengths["scene"])), list(dict.fromkeys(strengths["method"]))
    ]
    wide.columns.name = None
    return wide.reset_index()


def _vote_section(counts, out, *, labels, n_boot, seed, alpha, choices=None):
    """Every vote table and figure; returns (html sections, summary dict)."""
    from .plots import plot_strengths, plot_votes, save_figure

    tables, figs = out / "tables", out / "figures"
    table = vt.vote_table(counts)
    chi = vt.chisquare_no_preference(counts, alpha=alpha)
    pair = vt.ours_vs_baselines(counts, alpha=alpha)
    choices = vt.choices_from_counts(counts) if choices is None else choices
    strengths = vt.luce_strengths(choices, n_boot=n_boot, seed=seed, order=list(counts.index))
    kappa = vt.fleiss_kappa(counts)
    claims = vt.claim_summary(pair, alpha=alpha, labels=labels)
    write_table(
        table,
        tables / "votes",
        caption="Votes per method per scene with shares and 95% Wilson intervals.",
    )
    write_table(
        chi,
        tables / "chisquare",
        caption="Chi-square goodness-of-fit test against no preference, per scene.",
    )
    write_table(
        pair,
        tables / "pairwise",
        caption="Ours vs each baseline: exact two-sided binomial test among the two "
        "methods' votes, Holm-adjusted over all scenes and baselines.",
    )
    write_table(
        strengths,
        tables / "strengths",
        caption=f"Luce strengths (choix ilsr_top1) with 95% percentile bootstrap "
        f"intervals ({n_boot} resamples, seed {seed}).",
    )
    write_table(kappa, tables / "agreement", caption="Fleiss' kappa over scenes.")
    f_votes = save_figure(plot_votes(table, pairwise=pair, labels=labels), figs / "votes")[0]
    f_str = save_figure(plot_strengths(strengths, labels=labels), figs / "strengths")[0]
    k = kappa.iloc[0]
    wide = counts.copy()
    wide.insert(0, "scene", [labels.get(s, s) for s in counts.index])
    sections = [
        (
            "Views: which method's view do people prefer?",
            [wide.reset_index(drop=True), f_votes]
            + [f"<div class='claim'>{html.escape(c)}</div>" for c in claims],
        ),
        ("No preference? Chi-square per scene", [chi]),
        ("Ours vs each baseline (exact binomial, Holm)", [_compact_pairwise(pair)]),
        (
            "Method strengths (Luce model: probability of being chosen, 95% bootstrap CI)",
            [_compact_strengths(strengths), f_str],
        ),
        (
            "Agreement",
            [
                f"Fleiss' kappa over {int(k['n_items'])} scenes = {k['kappa']:.3f} "
                f"(chance-corrected agreement on the best view; 0 = chance, 1 = all "
                f"agree); z = {k['z']:.2f}, one-sided p = {_fmt('p_value', k['p_value'])}."
            ],
        ),
    ]
    summary = {
        "claims": claims,
        "votes": {s: {m: int(v) for m, v in row.items()} for s, row in counts.iterrows()},
        "chisquare_p": dict(zip(chi["scene"], chi["p_value"].astype(float), strict=True)),
        "pairwise": pair[["scene", "baseline", "p_value", "p_holm", "verdict"]].to_dict(
            orient="records"
        ),
        "fleiss_kappa": float(k["kappa"]),
    }
    return sections, summary


def _frame_section(pose, out, *, scenes, n_permutations, seed, alpha):
    del n_permutations  # the frame tests are Wilcoxon signed-rank tests now
    from .plots import plot_error_distributions, plot_frame_histograms, save_figure

    tables, figs = out / "tables", out / "figures"
    hits = fr.hit_rates(pose, scenes)
    tests = fr.closeness_tests(pose, scenes, seed=seed, alpha=alpha)
    dist = fr.frame_distances(pose, scenes)
    write_table(
        hits,
        tables / "frame_hits",
        caption="Distance of chosen frames to each predictor and hit rates within "
        "±0.25/0.5/1 s (Wilson 95% intervals).",
    )
    write_table(
        tests,
        tables / "frame_tests",
        caption="Is the algorithm closer to people than each baseline? Per scene, "
        "each participant's distance to the baseline's frame minus their "
        "distance to the algorithm's: one-sided Wilcoxon signed-rank over "
        "participants, mean difference (s) with a 95% bootstrap interval over "
        "participants, rank-biserial r; Holm over the tests that can differ "
        "(a baseline on the algorithm's frame is not tested).",
    )
    f_hist = save_figure(plot_frame_histograms(pose, scenes), figs / "fig13_frame_histograms")[0]
    f_err = save_figure(
        plot_error_distributions(dist, scenes, hits=hits), figs / "frame_distances"
    )[0]
    algo = hits[hits["predictor"] == "algorithm"]
    lines = [
        f"{scenes[r['scene']].title or r['scene']}: median |chosen − algorithm| = "
        f"{r['median_abs_error_s']:.2f} s; {100 * r['hit_0.5s']:.0f}% of people within "
        f"±0.5 s, {100 * r['hit_1s']:.0f}% within ±1 s."
        for r in algo.to_dict(orient="records")
    ]
    better = tests[tests["significant"]]
    worse = tests[~tests["significant"] & tests["p_value"].notna()]
    verdict = (
        f"The algorithm is significantly closer to people (Holm, α = {alpha:g}) than: "
        + (
            ", ".join(
                f"{b} in {scenes[s].title or s}"
                for s, b in zip(better["scene"], better["baseline"], strict=True)
            )
            or "none"
        )
        + ". Not significantly closer than: "
        + (
            ", ".join(
                f"{b} in {scenes[s].title or s}"
                for s, b in zip(worse["scene"], worse["baseline"], strict=True)
            )
            or "none"
        )
        + "."
    )
    missing = [s for s, i in scenes.items() if not i.baseline_frames]
    note = (
        "The fastest and most-stretched baselines are the selectors' picks recorded in "
        f"the stimuli manifest; they are missing for {', '.join(missing)} (pass "
        "--stimuli manifest.json)."
        if missing
        else ""
    )
    sections = [
        (
            "Poses: which frame do people pick?",
            [
                f_hist,
                *lines,
                f"<div class='claim'>{html.escape(verdict)}</div>",
                _compact_hits(hits),
                _compact_tests(tests),
                f_err,
            ]
            + ([f"<p class='note'>{html.escape(note)}</p>"] if note else []),
        )
    ]
    summary = {
        "frames": algo[
            ["scene", "n", "median_abs_error_s", "hit_0.25s", "hit_0.5s", "hit_1s"]
        ].to_dict(orient="records"),
        "frame_verdict": verdict,
    }
    sections += _selector_section(pose, out, scenes=scenes)
    return sections, summary


def _selector_section(pose, out, *, scenes):
    """Every pose selector against the people's choices (when the manifest has them)."""
    agree = fr.selector_agreement(pose, scenes)
    if agree.empty:
        return []
    write_table(
        agree,
        out / "tables" / "selector_agreement",
        caption="Each pose selector's top pick against the people's chosen frames: "
        "share of choices within ±0.5 s (Wilson 95%) and median distance.",
    )
    overall = agree[agree["scene"] == "ALL"].sort_values(
        ["hit", "median_abs_error_s"], ascending=[False, True]
    )
    best = overall.iloc[0]
    text = (
        f"Across scenes, the selector whose pick agrees with people best is "
        f"{best['selector']}: {100 * best['hit']:.0f}% of choices within ±0.5 s "
        f"(median distance {best['median_abs_error_s']:.2f} s)."
    )
    parts = [text, overall.round(3)]
    doc = fr.selector_timeline_document(pose, scenes)
    if doc is not None:
        from snapcore.render.keymoments_plot import plot_keymoment_timelines

        from .plots import save_figure

        extra = {
            s: pose.loc[pose["scene"] == s, "chosen_frame"].astype(int).tolist() for s in scenes
        }
        fig = plot_keymoment_timelines(doc, extra=extra)
        # The shared plot's title describes key-moment intervals (green), which this
        # figure has none of: say what is drawn.
        fig.axes[0].set_title(
            "each selector's picks (filled: top pick, hollow: picks 2..k) "
            "and the people's chosen frames (grey ticks)",
            fontsize=9,
        )
        parts.insert(0, save_figure(fig, out / "figures" / "selector_timeline")[0])
    return [("Poses: which selector agrees with people?", parts)]


_METHODS_TEXT = (
    "Methods. Vote shares: Wilson score 95% intervals. No preference: Pearson chi-square "
    "goodness of fit against equal shares. Ours vs each baseline: exact two-sided binomial test "
    "of ours' share among the votes for the two (null 1/2), Clopper–Pearson intervals, Holm "
    "adjustment over every scene × baseline. Strengths: Luce choice model fitted by iterative "
    "Luce spectral ranking (choix.ilsr_top1), percentile bootstrap over choices. Agreement: "
    "Fleiss' kappa (scenes = items, methods = categories). Frames: distances in seconds; hit "
    "rates within ±0.25/0.5/1 s; baselines middle frame, uniform random frame (exact "
    "expectation), the fastest and most-stretched poses (the pose selectors' picks); "
    "per scene and baseline, a one-sided Wilcoxon signed-rank test over participants of "
    "each person's distance to the baseline's frame (to a uniform random frame: its "
    "expectation) minus their distance to the algorithm's, effect sizes the mean "
    "difference (percentile bootstrap over participants) and the rank-biserial "
    "correlation; Holm over the tests that can differ (a baseline on the algorithm's "
    "frame is reported, not tested). Rows pooled over scenes: intervals from a bootstrap "
    "over participants."
)


def analyze_counts(
    counts: pd.DataFrame,
    out_dir,
    *,
    labels: dict | None = None,
    title: str = "Vote analysis",
    source: str = "",
    n_boot: int = DEFAULT_BOOT,
    seed: int = 0,
    alpha: float = vt.ALPHA,
) -> dict:
    """The vote analysis on a count table alone (e.g. the paper's Table 2).

    Returns
    -------
    dict
        The summary also written to ``summary.json`` (claims, votes, p-values, kappa).
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    labels = labels or {}
    sections, summary = _vote_section(
        counts, out, labels=labels, n_boot=n_boot, seed=seed, alpha=alpha
    )
    sections.append(("Methods", [_METHODS_TEXT]))
    meta = (
        f"{html.escape(source)} · {int(counts.to_numpy().sum())} votes over "
        f"{len(counts)} scenes · generated {datetime.now(UTC):%Y-%m-%d %H:%M} UTC"
    )
    html_report(sections, out / "report.html", title=title, meta=meta, labels=labels)
    summary["source"] = source
    _write_summary(out, summary)
    return summary


def completed_participants(df: pd.DataFrame) -> set:
    """Participants who finished the study: they answered its last trial, the attention
    check (every plan ends with it, ``study_app.design.protocol.trial_plan``)."""
    return set(df.loc[df["task"] == "attention", "participant_id"])


#: Where ``snapshot study`` keeps each study's stimuli by default (``<id>/manifest.json``).
DEFAULT_STIMULI_ROOT = Path(__file__).resolve().parents[1] / "var" / "stimuli"


def default_stimuli(df: pd.DataFrame, *, root: Path = DEFAULT_STIMULI_ROOT) -> Path | None:
    """The stimuli folder ``snapshot study`` serves by default for the data's study
    (``<root>/<study id>``), if there is exactly one study and its manifest exists."""
    ids = sorted(df["study_id"].dropna().unique())
    if len(ids) != 1:
        return None
    folder = Path(root) / str(ids[0])
    return folder if (folder / "manifest.json").is_file() else None


def analyze(
    source,
    out_dir,
    *,
    include_simulated: bool = False,
    stimuli=None,
    exclude_failed_attention: bool = False,
    n_boot: int = DEFAULT_BOOT,
    seed: int = 0,
    n_permutations: int = fr.N_PERMUTATIONS,
    alpha: float = vt.ALPHA,
    title: str | None = None,
    completed_only: bool = True,
    exclude_unwatched: bool = False,
) -> dict:
    """The whole analysis of study responses → tables, figures, ``report.html``.

    Parameters
    ----------
    source : str, Path, list or DataFrame
        A store URL, an export file, or rows (:func:`analysis.load.load_responses`).
    out_dir : str or Path
        Output folder (created).
    include_simulated : bool
        Analyse simulated participants too (they are excluded by default).
    stimuli : str, Path or dict, optional
        The stimuli manifest: scene titles, top-k picks, the fastest and
        stretch selectors' picks (baselines), and near-duplicate candidate views. Default: the
        study's stimuli folder ``var/stimuli/<study id>`` when it exists.
    exclude_failed_attention : bool
        Drop participants who failed an attention check.
    completed_only : bool
        Analyse the answers of participants who finished only (the default); False
        keeps those who started and left. The participants table reports both.
    exclude_unwatched : bool
        Leave out pose answers picked on the frame slider or before the animation was
        watched (:func:`analysis.load.exclude_unverified`); the summary's
        ``excluded_answers`` says how many.
    """
    from snapcore.errors import SnapshotError

    out = Path(out_dir)
    df = load_responses(source, include_simulated=include_simulated)
    out.mkdir(parents=True, exist_ok=True)  # after the load: bad input leaves no folder
    if df.empty:
        raise SnapshotError(
            f"{_source_name(source)}: no responses to analyse"
            + (
                ""
                if include_simulated
                else " (simulated participants are excluded; add --include-simulated)"
            )
        )
    att = attention_summary(df)
    failed = set(att.loc[~att["passed"], "participant_id"])
    parts = _participants_table(df, att)
    started = int(df["participant_id"].nunique())
    done = completed_participants(df)
    if completed_only:
        df = df[df["participant_id"].isin(done)]
        if df.empty:
            raise SnapshotError(
                f"{_source_name(source)}: no participant has finished the study "
                "(add --include-incomplete to analyse those who started)"
            )
    if exclude_failed_attention and failed:
        df = df[~df["participant_id"].isin(failed)]
    excluded = None
    if exclude_unwatched:
        from .load import exclude_unverified

        df, excluded = exclude_unverified(df)
    order, extra, labels = None, {}, {}
    if stimuli is None:
        stimuli = default_stimuli(df)
    dupes, replaced = pd.DataFrame(), pd.DataFrame()
    if stimuli is not None:
        from .stimuli import stimuli_scenes

        st = stimuli_scenes(stimuli)
        order = list(st["scene"])
        labels = dict(zip(st["scene"], st["title"], strict=True))
        extra = fr.baselines_from_stimuli(stimuli)
        from .stimuli import near_duplicate_scenes, replaced_views

        dupes = near_duplicate_scenes(stimuli)
        replaced = replaced_views(stimuli)
    if not labels:
        from .votes import paper_table2

        t = paper_table2()
        labels = dict(zip(t["scene"], t["scene_label"], strict=True))
    for sid, info in extra.items():
        info.setdefault("title", labels.get(sid))
    sections, summary = [], {}
    views = view_choices(df)
    if not views.empty:
        counts = vt.vote_counts(views, order=order)
        s, summ = _vote_section(
            counts, out, labels=labels, n_boot=n_boot, seed=seed, alpha=alpha, choices=views
        )
        sections += s
        summary.update(summ)
        if not dupes.empty:
            sections += _duplicate_section(counts, dupes, out, labels=labels, alpha=alpha)
            summary["near_duplicate_scenes"] = sorted(set(dupes["scene"]))
        if not replaced.empty:
            sections += _replaced_section(replaced, out)
            summary["replaced_views"] = [
                {"scene": r.scene, "method": r.method, "iou_before": r.iou_before}
                for r in replaced.itertuples()
            ]
    pose = pose_choices(df)
    if not pose.empty:
        extra = {
            sid: {**extra.get(sid, {}), "title": extra.get(sid, {}).get("title") or labels.get(sid)}
            for sid in ordered_scenes(pose["scene"], order)
        }
        scenes = fr.scene_frames_from_rows(pose, extra=extra, order=order)
        s, summ = _frame_section(
            pose, out, scenes=scenes, n_permutations=n_permutations, seed=seed, alpha=alpha
        )
        sections += s
        summary.update(summ)
    if excluded is not None:
        summary["excluded_answers"] = excluded
    write_table(
        parts,
        out / "tables" / "participants",
        caption="Participants (started and completed) and their responses.",
    )
    sections.insert(0, ("Participants", [parts]))
    sections.append(("Methods", [_METHODS_TEXT]))
    n_sim = int(df.loc[df["simulated"], "participant_id"].nunique())
    meta = (
        f"source: {html.escape(_source_name(source))} · "
        f"{df['participant_id'].nunique()} participants"
        + (
            f" (completed; {started} started)"
            if completed_only
            else f" (started, {len(done)} completed)"
        )
        + (f" ({n_sim} SIMULATED)" if n_sim else "")
        + f" · {len(df)} responses"
        + (
            f" · {len(failed)} failed the attention check"
            + (" (excluded)" if exclude_failed_attention else " (kept)")
            if failed
            else ""
        )
        + f" · generated {datetime.now(UTC):%Y-%m-%d %H:%M} UTC"
    )
    study = ", ".join(sorted(df["study_id"].dropna().unique()))
    html_report(
        sections,
        out / "report.html",
        title=title or f"Action Snapshot study: {study}",
        meta=meta,
        labels=labels,
    )
    summary.update(
        {
            "source": _source_name(source),
            "participants": int(df["participant_id"].nunique()),
            "simulated_participants": n_sim,
            "responses": len(df),
            "failed_attention": len(failed),
            "started_participants": started,
            "completed_participants": len(done),
        }
    )
    _write_summary(out, summary)
    return summary


def _plain(value):
    """``value`` as plain JSON: NumPy scalars as Python numbers, NaN and inf as None
    (an undefined statistic, e.g. Fleiss' kappa when no scene has two votes; strict
    JSON has no NaN), tuples as lists."""
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not np.isfinite(value):
        return None
    return value


def _write_summary(out: Path, summary: dict) -> None:
    """Write ``summary.json`` after checking it against data_schema/analysis_summary.schema.json."""
    from snapcore.schema import validate

    doc = _plain(summary)
    validate(doc, "analysis_summary", source="snapshot analyze summary.json")
    (out / "summary.json").write_text(json.dumps(doc, indent=2, allow_nan=False), encoding="utf-8")


def _duplicate_section(counts, dupes, out, *, labels, alpha):
    """Near-duplicate candidates: which scenes, and the votes with each pair as one option."""
    pairs = {}
    for r in dupes.itertuples():
        pairs.setdefault(r.scene, []).append((r.method_a, r.method_b))
    merged = vt.merge_near_duplicates(counts, pairs)
    write_table(
        dupes,
        out / "tables" / "near_duplicates",
        caption="Candidate views that are nearly the same picture (angle between their "
        "directions; over 90° means a near mirror image).",
    )
    write_table(
        merged,
        out / "tables" / "votes_duplicates_merged",
        caption="Sensitivity analysis: near-duplicate candidates counted as one option; "
        "chi-square against equal votes per distinct picture.",
    )
    keep = [s for s in counts.index if s not in pairs]
    text = [
        f"In {len(pairs)} scene(s) two candidates are nearly the same picture "
        f"({', '.join(labels.get(s, s) for s in pairs)}); votes may split between them."
    ]
    items = [dupes, *text, merged]
    if keep and len(keep) < len(counts):
        claims = vt.claim_summary(
            vt.ours_vs_baselines(counts.loc[keep], alpha=alpha), alpha=alpha, labels=labels
        )
        items += ["Without those scenes:"] + [
            f"<div class='claim'>{html.escape(c)}</div>" for c in claims
        ]
    return [("Near-duplicate candidates: sensitivity analysis", items)]


def _replaced_section(replaced, out):
    """Baseline views replaced at build time: which, why, and how far down its ranking."""
    write_table(
        replaced,
        out / "tables" / "replaced_views",
        caption="Baseline views replaced by the stimuli builder because their picture was "
        "nearly another candidate's (silhouette IoU, mirror images included): each by the "
        "best view of the same method's score whose picture is not.",
    )
    text = (
        f"{len(replaced)} baseline view(s) were replaced because their picture was nearly "
        "another candidate's; in those scenes a vote for that baseline is a vote for its "
        "best view unlike the others, not for its own pick."
    )
    return [("Replaced candidate views", [text, replaced])]


def _participants_table(df: pd.DataFrame, att: pd.DataFrame) -> pd.DataFrame:
    g = df.groupby("simulated")
    rows = []
    done = completed_participants(df)
    for sim, part in g:
        rows.append(
            {
                "participants": "simulated" if sim else "real",
                "n": int(part["participant_id"].nunique()),
                "started": int(part["participant_id"].nunique()),
                "completed": len(set(part["participant_id"]) & done),
                "responses": len(part),
                "pose_choices": int((part["task"] == "pose").sum()),
                "view_choices": int((part["task"] == "view").sum()),
                "attention_passed": int(
                    att[att["participant_id"].isin(part["participant_id"])]["passed"].sum()
                ),
                "median_response_time_s": float(part["response_time_s"].median()),
            }
        )
    return pd.DataFrame(rows)


def _source_name(source) -> str:
    if isinstance(source, pd.DataFrame | list | tuple):
        return "rows in memory"
    text = str(source)
    if "://" in text and "@" in text:  # never print a password
        scheme, rest = text.split("://", 1)
        return f"{scheme}://***@{rest.split('@', 1)[1]}"
    return text
