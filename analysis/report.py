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
algorithm and baselines), ``frame_tests`` (is the algorithm closer than each baseline:
:func:`analysis.frames.closeness_tests`), ``participants``; the report's "Who was left
out" and the summary's ``left_out`` count exclusions, withdrawals and unfinished
participants as the researcher page does.

This module runs the analysis and writes the folder; the sections' tables, figures and
text are in :mod:`analysis.sections`, table formatting and writing in
:mod:`analysis.tables`, the HTML page in :mod:`analysis.html_page`.
"""

from __future__ import annotations

import html
import json
import os
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
import pandas as pd

from . import frames as fr
from . import votes as vt
from .html_page import html_report
from .load import (
    Participants,
    ResponseSource,
    attention_summary,
    completed_participants,
    load_participants,
    load_responses,
    ordered_scenes,
    pose_choices,
    view_choices,
)
from .sections import (
    _METHODS_TEXT,
    _duplicate_section,
    _frame_section,
    _participants_table,
    _replaced_section,
    _vote_section,
)
from .tables import write_table

__all__ = ["analyze", "analyze_counts", "DEFAULT_BOOT"]


#: Bootstrap resamples for the Luce strengths' intervals.
DEFAULT_BOOT = 1000


def analyze_counts(
    counts: pd.DataFrame,
    out_dir: str | os.PathLike[str],
    *,
    labels: dict | None = None,
    title: str = "Vote analysis",
    source: str = "",
    n_boot: int = DEFAULT_BOOT,
    seed: int = 0,
    alpha: float = vt.ALPHA,
    figures: bool = True,
) -> dict:
    """The vote analysis on a count table alone (e.g. the paper's Table 2).

    ``figures=False`` writes the tables, summary and report without drawing the
    figures (as :func:`analyze`).

    Returns
    -------
    dict
        The summary also written to ``summary.json`` (claims, votes, p-values, kappa).
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    labels = labels or {}
    sections, summary = _vote_section(
        counts, out, labels=labels, n_boot=n_boot, seed=seed, alpha=alpha, figures=figures
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


#: Where ``snapshot study`` keeps each study's stimuli by default (``<id>/manifest.json``).
DEFAULT_STIMULI_ROOT = Path(__file__).resolve().parents[1] / "var" / "stimuli"


def default_stimuli(
    df: pd.DataFrame, *, root: Path = DEFAULT_STIMULI_ROOT, source: object = None
) -> Path | None:
    """The stimuli of the data: a Psych-DS dataset's own ``materials/manifest.json``
    when ``source`` is a file in its ``data/``; else the folder ``snapshot study``
    serves by default for the data's study (``<root>/<study id>``), if there is exactly
    one study and its manifest exists."""
    if isinstance(source, str | Path) and "://" not in str(source):
        data = Path(source).parent
        materials = data.parent / "materials" / "manifest.json"
        if data.name == "data" and materials.is_file():
            return materials
    ids = sorted(df["study_id"].dropna().unique())
    if len(ids) != 1:
        return None
    folder = Path(root) / str(ids[0])
    return folder if (folder / "manifest.json").is_file() else None


def analyze(
    source: ResponseSource,
    out_dir: str | os.PathLike[str],
    *,
    include_simulated: bool = False,
    stimuli: str | os.PathLike[str] | dict | None = None,
    exclude_failed_attention: bool = False,
    n_boot: int = DEFAULT_BOOT,
    seed: int = 0,
    n_permutations: int = fr.N_PERMUTATIONS,
    alpha: float = vt.ALPHA,
    title: str | None = None,
    completed_only: bool = True,
    exclude_unwatched: bool = False,
    figures: bool = True,
    participants: str | os.PathLike[str] | None = None,
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
    figures : bool
        Draw the figures (PNG and PDF, in the report too; the default). False writes the
        tables, ``summary.json`` and the report without them: drawing is most of the
        time of an analysis (seconds per figure), the numbers are the same.
    participants : str or Path, optional
        The participants export of an export file ``source`` (default: the Psych-DS
        participants file beside it): its ``excluded`` participants are left out and
        its ``completed_at`` says who finished, as the store's records do for a URL
        (:func:`analysis.load.load_participants`).

    Who was left out — excluded by the researcher (with the reasons), withdrawn, not
    finished — is counted by :func:`study_app.data.monitor.participation` (the
    researcher page's definitions) into the summary's ``left_out`` and the report.
    """
    from snapcore.errors import SnapshotError

    out = Path(out_dir)
    df = load_responses(source, include_simulated=include_simulated)
    people = load_participants(
        source, participants=participants, include_simulated=include_simulated
    )
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
    left_out, done, records = _left_out(df, people)
    df = df[~df["participant_id"].isin(left_out["excluded_ids"])]
    att = attention_summary(df)
    failed = set(att.loc[~att["passed"], "participant_id"])
    parts = _participants_table(df, att, done=done, records=records)
    started = left_out["started"]
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
        stimuli = default_stimuli(df, source=source)
    dupes, replaced = pd.DataFrame(), pd.DataFrame()
    if stimuli is not None:
        from .stimuli import read_stimuli, stimuli_scenes

        stimuli, _ = read_stimuli(stimuli)  # read and checked once, not once per use

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
            counts,
            out,
            labels=labels,
            n_boot=n_boot,
            seed=seed,
            alpha=alpha,
            choices=views,
            figures=figures,
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
            pose,
            out,
            scenes=scenes,
            n_permutations=n_permutations,
            seed=seed,
            alpha=alpha,
            figures=figures,
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
    analysed = int(df["participant_id"].nunique())
    left_out = {k: v for k, v in left_out.items() if k != "excluded_ids"}
    left_out.update(
        {
            "analysed": analysed,
            "failed_attention_excluded": len(failed) if exclude_failed_attention else 0,
        }
    )
    sections.insert(0, ("Who was left out", [_left_out_text(left_out, completed_only)]))
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
            "left_out": left_out,
        }
    )
    _write_summary(out, summary)
    return summary


def _left_out(df: pd.DataFrame, people: Participants) -> tuple[dict, set, list | None]:
    """Who was left out and who finished, by the page's definitions
    (:func:`study_app.data.monitor.participation`), for the studies in ``df``.

    Returns
    -------
    (dict, set, list or None)
        The counts (plus ``excluded_ids``, ``counted_from``), the finished ids and the
        participant records of the studies in ``df``. Without
        participant records (a bare responses file) started is who answered, finished
        who answered the last trial, and nobody is known to be excluded or withdrawn.
    """
    from study_app.data.monitor import participant_state, participation

    studies = set(df["study_id"].dropna())
    if people.records is None:
        done = completed_participants(df)
        n = int(df["participant_id"].nunique())
        counts: dict[str, object] = {
            "started": n,
            "finished": len(done),
            "excluded": None,
            "exclusion_reasons": {},
            "unfinished": n - len(done),
            "withdrawn": None,
            "counted_from": "responses",
            "excluded_ids": set(),
        }
        return counts, done, None
    records = [r for r in people.records if r.get("study_id") in studies]
    state = {
        r["participant_id"]: participant_state(r.get("completed_at"), r.get("excluded"))
        for r in records
    }
    gone = None if people.withdrawn is None else sum(people.withdrawn.get(s, 0) for s in studies)
    counts = participation(records, withdrawn=gone)
    counts["counted_from"] = "participant records"
    counts["excluded_ids"] = {p for p, s in state.items() if s == "excluded"}
    return counts, {p for p, s in state.items() if s == "finished"}, records


def _left_out_text(c: dict, completed_only: bool) -> str:
    """The report's sentence on who was left out."""
    reasons = "; ".join(f"{r}: {n}" for r, n in c["exclusion_reasons"].items())
    parts = [f"{c['started']} started", f"{c['finished']} finished"]
    if c["excluded"] is not None:
        parts.append(
            f"{c['excluded']} excluded by the researcher" + (f" ({reasons})" if reasons else "")
        )
    if c["withdrawn"] is not None:
        parts.append(f"{c['withdrawn']} withdrew (their data were deleted)")
    if c["unfinished"]:
        parts.append(
            f"{c['unfinished']} did not finish"
            + (" (left out)" if completed_only else " (analysed)")
        )
    if c["failed_attention_excluded"]:
        parts.append(f"{c['failed_attention_excluded']} failed the attention check (left out)")
    return (
        "; ".join(parts)
        + f"; {c['analysed']} analysed. Counted from the {c['counted_from']}."
        + (
            ""
            if c["excluded"] is not None
            else " Without participant records nobody is known to be excluded or withdrawn."
        )
    )


def _plain(value: object) -> object:
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


def _source_name(source: object) -> str:
    if isinstance(source, pd.DataFrame | list | tuple):
        return "rows in memory"
    text = str(source)
    if "://" in text and "@" in text:  # never print a password
        scheme, rest = text.split("://", 1)
        return f"{scheme}://***@{rest.split('@', 1)[1]}"
    return text
