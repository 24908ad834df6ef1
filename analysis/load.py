"""Study responses → tidy pandas frames, one row per choice.

Sources (all give the same frame):

- the study store, by SQLAlchemy URL (``sqlite:///var/study.db``,
  ``postgresql+psycopg://...``), read through ``study_app.data.store.Store(url).export_rows``;
- an export file written by ``snapshot export``: CSV (``shown_order`` as a JSON string,
  empty cells = null) or JSON lines (``.jsonl``/``.ndjson``; a ``.json`` file holding a
  list of rows is accepted too), read by the study's own codec,
  :func:`study_app.data.export.read_export`;
- rows already in memory (a list of dicts or a DataFrame).

Who took part beside the responses — every participant record with its completion and
exclusion, and the withdrawals — comes from :func:`load_participants`: the store's
records and withdrawal log, or an export's participants file (for a Psych-DS data file
``study-<id>_data.csv``, ``study-<id>_description-participants_data.csv`` beside it and the
withdrawals in ``../dataset_description.json``). Only documented column names are read
(``participant_id``, ``study_id``, ``completed_at``, ``excluded``, ``simulated``), never
row order or the form of the ids.

Every row follows ``data_schema/response.schema.json``; rows are validated
(:func:`study_app.data.export.validate_rows`) and a bad row raises :class:`LoadError` naming
the file, the row and the field. Column types come from the schema
(:func:`study_app.data.export.export_types`). Simulated
participants (``simulated`` true, written by ``snapshot simulate``) are dropped unless
``include_simulated=True``.

Columns of the frame returned by :func:`load_responses` (dtypes in brackets) — the
schema's fields plus derived ones:

- every schema field (durations rounded to 0.1 s and ``watched`` floored to 0.001, as
  open exports give them: :func:`study_app.data.pseudonym.open_value`); integers as
  nullable ``Int64``, ``correct`` as nullable ``boolean``, ``shown_order`` as a tuple of
  method names (or None), ``shown_groups`` as a tuple of such tuples (or None),
  ``created_at`` as UTC datetimes;
- ``chosen_s``, ``algorithm_s`` [float]: the chosen and the algorithm's frame in seconds
  (frame / fps), pose task only;
- ``error_s`` [float]: ``chosen_s - algorithm_s`` (negative = the person chose earlier);
- ``abs_error_s`` [float]: ``|error_s|``.
"""

from __future__ import annotations

import json
import os
import re
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TypeAlias

import numpy as np
import pandas as pd

from snapcore.errors import SnapshotError
from study_app.data.answer import ResponseRow
from study_app.data.export import export_columns, export_types, read_export, validate_rows
from study_app.data.pseudonym import DURATION_COLUMNS, open_value
from study_app.data.store import Store
from study_app.session.events import WATCHED_ENOUGH  # the study's own bar: one home

__all__ = [
    "LoadError",
    "ResponseSource",
    "SceneOrder",
    "load_responses",
    "Participants",
    "load_participants",
    "participants_file",
    "rows_from_store",
    "ANALYSIS_COLUMNS",
    "tidy_responses",
    "pose_choices",
    "view_choices",
    "attention_summary",
    "completed_participants",
    "PAPER_SCENES",
    "ordered_scenes",
    "exclude_unverified",
    "WATCHED_ENOUGH",
]

#: What responses are loaded from: a store URL (``...://...``), an export file, or the
#: answer records (or a frame of them) in memory.
ResponseSource: TypeAlias = str | os.PathLike[str] | Sequence[ResponseRow] | pd.DataFrame

#: An order of scene ids to put first (:func:`ordered_scenes`), or None.
SceneOrder: TypeAlias = Iterable[str] | None

#: The paper's six animations (Table 2's columns), in its order (a)–(f).
PAPER_SCENES = (
    "dancing",
    "running",
    "soccer_kicking",
    "basketball_shooting",
    "two_person_arguing",
    "two_person_boxing",
)


class LoadError(SnapshotError):
    """Responses that cannot be read (bad file, bad row, unreachable store)."""


# ----------------------------------------------------------------- sources


#: Columns the analysis reads: an export file without one of them cannot be analysed
#: (a report would silently lack the section that needs it).
ANALYSIS_COLUMNS = (
    "participant_id",
    "task",
    "scene",
    "chosen_frame",
    "algorithm_frame",
    "fps",
    "n_frames",
    "chosen_method",
    "shown_order",
    "correct",
)


def rows_from_store(url: str | None, *, include_simulated: bool = False) -> list[ResponseRow]:
    """Export rows from the study store at ``url`` (None: the store's default URL).

    The store is opened as a reader: a missing SQLite file or folder, or a database
    without the study tables, is an error, never created. Participants excluded on the
    researcher page (:mod:`study_app.data.monitor`) are left out."""
    from study_app.data.monitor import excluded_ids

    with Store(url, create=False) as store:
        left_out = excluded_ids(store)  # excluded on the researcher page, with a reason
        return [
            r
            for r in store.export_rows(include_simulated=include_simulated)
            if r["participant_id"] not in left_out
        ]


@dataclass(frozen=True)
class Participants:
    """Who took part, from the same source as the responses.

    Attributes
    ----------
    records : list of dict or None
        One per participant with a record (started), with ``participant_id``,
        ``study_id``, ``completed_at`` and ``excluded`` (the reason or None); None when
        the source has no participant records (a bare responses file).
    withdrawn : dict or None
        Study id → participants who withdrew (their data are deleted); None when the
        source does not say.
    source : str
        Where they were read from (for the report).
    """

    records: list[dict] | None
    withdrawn: dict[str, int] | None
    source: str


#: A Psych-DS responses file: ``<keywords>_data.csv`` without a ``description`` keyword.
_PSYCHDS_DATA = re.compile(r"^(?P<stem>(?:[a-z]+-[A-Za-z0-9]+_)*[a-z]+-[A-Za-z0-9]+)_data\.csv$")


def participants_file(path: str | os.PathLike[str]) -> Path | None:
    """The participants file of an export: beside a Psych-DS responses file
    ``study-<id>_data.csv``, its ``study-<id>_description-participants_data.csv``."""
    path = Path(path)
    m = _PSYCHDS_DATA.match(path.name)
    if m is None or "description-" in m["stem"]:
        return None
    candidate = path.with_name(f"{m['stem']}_description-participants_data.csv")
    return candidate if candidate.is_file() else None


def _dataset_withdrawals(data_file: Path) -> dict[str, int] | None:
    """The ``withdrawals`` a Psych-DS ``dataset_description.json`` records (the dataset
    folder holds ``data/``), or None."""
    desc = data_file.parent.parent / "dataset_description.json"
    if data_file.parent.name != "data" or not desc.is_file():
        return None
    try:
        doc = json.loads(desc.read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError) as err:
        raise LoadError(f"{desc}: cannot read it ({err})") from None
    value = doc.get("withdrawals") if isinstance(doc, dict) else None
    if value is None:
        return None
    if not isinstance(value, dict) or not all(
        isinstance(n, int) and not isinstance(n, bool) and n >= 0 for n in value.values()
    ):
        raise LoadError(f"{desc}: withdrawals: expected study id → count, got {value!r}")
    return {str(k): int(n) for k, n in value.items()}


def load_participants(
    source: ResponseSource,
    *,
    participants: str | os.PathLike[str] | None = None,
    include_simulated: bool = False,
) -> Participants:
    """The participant records and withdrawals of ``source`` (as :func:`load_responses`).

    Parameters
    ----------
    source : str, Path, list or DataFrame
        A store URL, an export file, or rows in memory (no records).
    participants : str or Path, optional
        The participants export (``snapshot export --participants``) of an export file;
        default: the Psych-DS participants file beside it (:func:`participants_file`).
    include_simulated : bool
        Keep simulated participants' records.
    """
    if isinstance(source, pd.DataFrame | list | tuple):
        if participants is None:
            return Participants(None, None, "")
        records, withdrawn, where = _read_participants(Path(participants)), None, str(participants)
    elif "://" in str(source):
        from study_app.data.monitor import with_exclusions
        from study_app.data.withdraw import withdrawal_counts

        with Store(str(source), create=False) as store:
            records = with_exclusions(store, store.participants(include_simulated=True))
            withdrawn = withdrawal_counts(store)
        where = "the store"
    else:
        found = Path(participants) if participants is not None else participants_file(str(source))
        if found is None:
            return Participants(None, None, "")
        records, where = _read_participants(found), str(found)
        withdrawn = _dataset_withdrawals(Path(str(source)))
    if not include_simulated:
        records = [r for r in records if not r.get("simulated")]
    return Participants(records, withdrawn, where)


def _read_participants(path: Path) -> list[dict]:
    try:
        records = read_export(path, schema="participant")
    except SnapshotError as err:
        raise LoadError(str(err)) from err
    return records


def _check_columns(rows: Sequence[Mapping[str, object]], source: str) -> None:
    missing = [c for c in ANALYSIS_COLUMNS if rows and not any(c in r for r in rows)]
    if missing:
        raise LoadError(
            f"{source}: no {', '.join(missing)} column (a `snapshot export` file "
            "has every column of data_schema/response.schema.json)"
        )


# ----------------------------------------------------------------- tidy frames


def tidy_responses(
    rows: Iterable[ResponseRow] | Iterable[Mapping[str, object]] | pd.DataFrame,
    *,
    include_simulated: bool = False,
    validate: bool = True,
    source: str = "rows",
) -> pd.DataFrame:
    """Rows (dicts following the response schema) → the tidy frame described above.

    Parameters
    ----------
    rows : iterable of dict, or DataFrame
        Export rows.
    include_simulated : bool
        Keep rows of simulated participants (default: drop them).
    validate : bool
        Check each row against ``response.schema.json`` first (default True).
    source : str
        Where the rows came from, for error messages.
    """
    if isinstance(rows, pd.DataFrame):
        records = rows.replace({np.nan: None}).to_dict(orient="records")
    else:
        records = [dict(r) for r in rows]
    for r in records:  # JSON has lists; a DataFrame may already hold tuples
        if isinstance(r.get("shown_order"), tuple):
            r["shown_order"] = list(r["shown_order"])
        if isinstance(r.get("shown_groups"), tuple):
            r["shown_groups"] = [list(g) for g in r["shown_groups"]]
        for k in list(r):
            if isinstance(r[k], np.generic):
                r[k] = r[k].item()
        for k in ("created_at",):
            if isinstance(r.get(k), pd.Timestamp):
                r[k] = r[k].isoformat()
        # Durations and shares watched at the precision an open export gives them (0.1 s,
        # 0.001): all the analysis needs, and the same numbers from the store and from
        # its published dataset.
        for k in (*DURATION_COLUMNS, "watched"):
            if k in r:
                r[k] = open_value(k, r[k])
    if validate:
        try:
            validate_rows(records, source=source)
        except SnapshotError as err:
            raise LoadError(str(err)) from err
    types = export_types()
    df = pd.DataFrame.from_records(records, columns=export_columns())
    for c in (c for c, t in types.items() if t == "integer"):
        df[c] = pd.array(df[c].to_numpy(dtype=object), dtype="Int64")
    for c in (c for c, t in types.items() if t == "number"):
        df[c] = pd.to_numeric(df[c], errors="coerce").astype(float)
    for c in (c for c, t in types.items() if t == "string"):
        # An all-empty text column (e.g. picked_with in view-only rows) reads back from
        # CSV as floats: text columns hold text or None, whatever the source.
        df[c] = pd.Series(
            [v if isinstance(v, str) else None for v in df[c]], index=df.index, dtype=object
        )
    df["correct"] = pd.array(df["correct"].to_numpy(dtype=object), dtype="boolean")
    df["simulated"] = df["simulated"].fillna(False).astype(bool)
    df["shown_order"] = [
        tuple(v) if isinstance(v, list | tuple) else None for v in df["shown_order"]
    ]
    # Which methods each shown picture stood for (merged candidates): tuples, or None
    # in rows before merging, whatever the source (an all-empty CSV column reads as NaN).
    df["shown_groups"] = pd.Series(
        [
            tuple(tuple(g) for g in v) if isinstance(v, list | tuple) else None
            for v in df["shown_groups"]
        ],
        index=df.index,
        dtype=object,
    )
    df["created_at"] = pd.to_datetime(df["created_at"], utc=True, errors="coerce", format="ISO8601")
    if not include_simulated:
        df = df[~df["simulated"]]
    df = df.sort_values(["participant_id", "trial_index"], kind="stable").reset_index(drop=True)
    chosen = df["chosen_frame"].astype("Float64").to_numpy(dtype=float, na_value=np.nan)
    algo = df["algorithm_frame"].astype("Float64").to_numpy(dtype=float, na_value=np.nan)
    fps = df["fps"].to_numpy(dtype=float)
    with np.errstate(invalid="ignore", divide="ignore"):
        df["chosen_s"] = chosen / fps
        df["algorithm_s"] = algo / fps
    df["error_s"] = df["chosen_s"] - df["algorithm_s"]
    df["abs_error_s"] = df["error_s"].abs()
    return df


def load_responses(
    source: ResponseSource, *, include_simulated: bool = False, validate: bool = True
) -> pd.DataFrame:
    """Load responses from a store URL, an export file, or rows in memory.

    Parameters
    ----------
    source : str, Path, list of dict or DataFrame
        A SQLAlchemy URL (contains ``://``), a path to an export file, or rows.
    include_simulated : bool
        Keep simulated participants (default False: real analyses exclude them).
    validate : bool
        Validate each row against the response schema.

    Returns
    -------
    DataFrame
        One row per choice; columns in the module docstring.
    """
    if isinstance(source, pd.DataFrame) or (isinstance(source, list | tuple)):
        return tidy_responses(source, include_simulated=include_simulated, validate=validate)
    text = str(source)
    if "://" in text:
        # The store's own filter is the first line of defence; tidy_responses filters again.
        rows = rows_from_store(text, include_simulated=include_simulated)
        return tidy_responses(
            rows, include_simulated=include_simulated, validate=validate, source=text.split("@")[-1]
        )
    try:
        rows = read_export(text, validate=False)  # tidy_responses validates, if asked
    except SnapshotError as err:
        raise LoadError(str(err)) from err
    _check_columns(rows, text)
    return tidy_responses(rows, include_simulated=include_simulated, validate=validate, source=text)


# ----------------------------------------------------------------- task views


def ordered_scenes(scenes: Iterable[str], order: SceneOrder = None) -> list[str]:
    """Distinct scene ids in a stable order: ``order`` first (e.g. the stimuli manifest's),
    then the paper's order for its scene ids, then the rest alphabetically."""
    distinct = list(dict.fromkeys(str(s) for s in scenes))
    pref = [s for s in (list(order or ()) + list(PAPER_SCENES)) if s in distinct]
    pref = list(dict.fromkeys(pref))
    return pref + sorted(set(distinct) - set(pref))


def pose_choices(df: pd.DataFrame) -> pd.DataFrame:
    """The pose-task rows with a chosen frame (Fig. 13's data)."""
    out = df[(df["task"] == "pose") & df["chosen_frame"].notna()]
    return out.reset_index(drop=True)


def view_choices(df: pd.DataFrame) -> pd.DataFrame:
    """The view-task rows with a chosen method (Table 2's data)."""
    out = df[(df["task"] == "view") & df["chosen_method"].notna()]
    return out.reset_index(drop=True)


def attention_summary(df: pd.DataFrame) -> pd.DataFrame:
    """Attention checks per participant.

    Returns
    -------
    DataFrame
        Columns ``participant_id``, ``n_checks``, ``n_correct``, ``passed`` (all checks
        right). Participants without attention checks are absent.
    """
    att = df[df["task"] == "attention"]
    if att.empty:
        return pd.DataFrame(
            {
                "participant_id": pd.Series(dtype=str),
                "n_checks": pd.Series(dtype=int),
                "n_correct": pd.Series(dtype=int),
                "passed": pd.Series(dtype=bool),
            }
        )
    g = att.groupby("participant_id")["correct"]
    out = pd.DataFrame(
        {"n_checks": g.size(), "n_correct": g.apply(lambda s: int(s.fillna(False).sum()))}
    )
    out["passed"] = out["n_correct"] == out["n_checks"]
    return out.reset_index()


def completed_participants(df: pd.DataFrame) -> set:
    """Participants who answered the study's last trial, the attention check (every plan
    ends with it, ``study_app.design.protocol.trial_plan``): who finished, as far as
    responses alone can tell. With participant records, finished is
    :func:`study_app.data.monitor.participant_state` (the store's completion)."""
    return set(df.loc[df["task"] == "attention", "participant_id"])


def exclude_unverified(
    df: pd.DataFrame, *, watch_min: float = WATCHED_ENOUGH
) -> tuple[pd.DataFrame, dict[str, int]]:
    """Leave out the pose answers nobody can vouch were given on the animation.

    Dropped: answers picked on the frame slider (``picked_with == "slider"``: the
    fallback when the video did not play, nothing was watched) and answers in the
    player whose ``watched`` share is below ``watch_min``. Answers of versions that did
    not record these fields (null ``picked_with``) are kept; other tasks are kept.

    Returns
    -------
    (DataFrame, dict)
        The kept rows, and ``{"slider": n, "not_watched": n}``, how many were dropped
        for each reason.
    """
    if df.empty or "picked_with" not in df:
        return df, {"slider": 0, "not_watched": 0}
    pose = df["task"] == "pose"
    slider = pose & (df["picked_with"] == "slider")
    watched = pd.to_numeric(df.get("watched"), errors="coerce")
    unwatched = pose & (df["picked_with"] == "player") & ~(watched >= watch_min)
    drop = (slider | unwatched).fillna(False).astype(bool)
    return df[~drop], {
        "slider": int(slider.fillna(False).sum()),
        "not_watched": int(unwatched.fillna(False).sum()),
    }
