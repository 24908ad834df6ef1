"""The study's data as a Psych-DS dataset (https://psych-ds.github.io/).

Layout written by :func:`write_psych_ds` (one set of data files per study in the
database)::

    DIR/
      dataset_description.json                       schema.org Dataset (JSON-LD)
      data/
        study-<id>_data.csv                          one row per response
        study-<id>_description-participants_data.csv one row per participant
        study-<id>_description-events_data.csv       one row per interaction event
      materials/
        manifest.json                                the stimulus manifest they saw

``dataset_description.json`` holds the fields Psych-DS 1.0.0 requires (``@context``,
``@type: Dataset``, ``name``, ``schemaVersion``, ``description``, ``variableMeasured``)
and some it recommends (``keywords``, ``dateCreated``; ``license``, ``author`` and
``citation`` from the study config's ``license``, ``creators`` and ``citation``, with
a warning for each one missing), and ``withdrawals``: study id → how many participants
withdrew (a count only; their data are deleted), so that an analysis of the dataset
says who was left out as one of the database does. ``variableMeasured`` lists every column of the data
files written, no other, as a ``PropertyValue`` whose description comes from the
column's schema (``data_schema/response.schema.json``, ``participant.schema.json``,
``event.schema.json``), so a column cannot be added without being described. A table
without rows for a study (its events, or the stimuli's own study with no participant)
gets no file. The folder is written beside and renamed into place at the end: a
failed export leaves nothing. File
names are Psych-DS keyword names (official keywords ``study`` and ``description``;
values only letters and digits, so a study id's ``-``, ``_`` and ``.`` are dropped, and
two ids that then coincide are told apart by a hash, :func:`study_file_keys`).
Identifiers are pseudonymised (:mod:`study_app.data.pseudonym`) unless asked otherwise.
"""

from __future__ import annotations

import json
import os
import re
import secrets
import shutil
from datetime import UTC, datetime
from pathlib import Path

from snapcore.errors import SchemaError
from snapcore.schema import load_schema
from study_app.design.protocol import Study, study_from_dict

from .errors import StoreError
from .export import (
    _write_atomic,
    events_columns,
    export_columns,
    participants_columns,
    write_events,
    write_export,
    write_participants,
)
from .pseudonym import OPEN_DROPPED, Pseudonymiser

__all__ = [
    "DESCRIPTION_NAME",
    "SCHEMA_VERSION",
    "data_file_name",
    "study_file_keys",
    "variable_measured",
    "write_psych_ds",
]

DESCRIPTION_NAME = "dataset_description.json"
#: The Psych-DS version whose rules the dataset follows (its required ``schemaVersion``).
SCHEMA_VERSION = "Psych-DS 1.0.0"
#: The data files of one study: Psych-DS ``description`` keyword value → columns' schema.
_TABLES = {None: "response", "participants": "participant", "events": "event"}
_PSEUDONYM_NOTE = (
    " In this dataset every participant, Prolific and session id and every "
    "per-participant completion code is a pseudonym: p- and 16 hex digits of a "
    "keyed hash (HMAC-SHA256 with a secret the study keeps), the same in every "
    "file and every export of the study; the browser tab ids are pseudonyms too. "
    "Rows are ordered by pseudonym (not by when people took part), durations are "
    "rounded to 0.1 s and shares watched floored to 0.001, so that no file can be "
    "matched to the study's private records by order, time or a technical id."
)


def data_file_name(study_id: str, description: str | None = None) -> str:
    """The Psych-DS name of a data file: ``study-<id>[_description-<what>]_data.csv``.

    Raises
    ------
    StoreError
        The study id has no letter or digit to name the file by.
    """
    value = re.sub(r"[^A-Za-z0-9]", "", study_id)
    if not value:
        raise StoreError(f"study id {study_id!r} has no letters or digits for a Psych-DS file name")
    parts = [f"study-{value}"] + ([f"description-{description}"] if description else [])
    return "_".join(parts) + "_data.csv"


def study_file_keys(study_ids) -> dict[str, str]:
    """Study id → the ``study-`` keyword value of its data files, one per study.

    The value is the id's letters and digits; ids that lose their difference that way
    (``pilot-1`` and ``pilot_1`` both give ``pilot1``) each get ``x`` and the first 8 hex
    digits of the id's SHA-256 appended, so no study's file replaces another's.

    Raises
    ------
    StoreError
        A study id has no letter or digit to name the file by.
    """
    import hashlib

    plain = {sid: re.sub(r"[^A-Za-z0-9]", "", sid) for sid in study_ids}
    for sid, value in plain.items():
        if not value:
            raise StoreError(f"study id {sid!r} has no letters or digits for a Psych-DS file name")
    taken = list(plain.values())
    return {
        sid: value
        if taken.count(value) == 1
        else value + "x" + hashlib.sha256(sid.encode()).hexdigest()[:8]
        for sid, value in plain.items()
    }


def variable_measured(columns: dict | None = None) -> list[dict]:
    """The ``variableMeasured`` list: every column of the data files, described.

    Parameters
    ----------
    columns : dict of str to list of str, optional
        Schema name (``"response"``, ``"participant"``, ``"event"``) → the columns its
        files have; only these are listed. All of each schema's columns when None.

    Returns
    -------
    list of dict
        One ``PropertyValue`` per column name, in the order responses, participants,
        events, with the description its schema gives it; a name shared by several
        files (``participant_id``) is listed once, with the first schema's description.

    Raises
    ------
    SchemaError
        A column without a description in its schema (Psych-DS needs each described).
    """
    out, seen = [], set()
    for schema_name in _TABLES.values():
        if columns is not None and schema_name not in columns:
            continue
        wanted = None if columns is None else set(columns[schema_name])
        for name, spec in load_schema(schema_name)["properties"].items():
            if name in seen or (wanted is not None and name not in wanted):
                continue
            if not spec.get("description"):
                raise SchemaError(
                    f"data_schema/{schema_name}.schema.json: {name} has no "
                    "description (the Psych-DS variableMeasured needs one)"
                )
            seen.add(name)
            out.append({"@type": "PropertyValue", "name": name, "description": spec["description"]})
    return out


def _manifest(stimuli_dir) -> tuple[Path, Study] | None:
    """The stimulus manifest's path and the study it was built from."""
    if stimuli_dir is None:
        return None
    from study_app.design.stimuli import MANIFEST_NAME

    path = Path(stimuli_dir) / MANIFEST_NAME
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
        if not isinstance(doc, dict) or not isinstance(doc.get("study"), dict):
            raise StoreError(f"{path}: not a stimulus manifest (no study)")
        return path, study_from_dict(doc["study"], source=f"{path}: study")
    except OSError as err:
        raise StoreError(
            f"cannot read the stimulus manifest {path}: {err.strerror or err}"
        ) from None
    except json.JSONDecodeError as err:
        raise StoreError(f"{path}:{err.lineno}: not valid JSON ({err.msg})") from None


def write_psych_ds(
    store,
    folder,
    *,
    stimuli_dir=None,
    pseudonymise: bool = True,
    include_simulated: bool = False,
    force: bool = False,
) -> dict:
    """Write the store's data as a Psych-DS dataset in ``folder``.

    Parameters
    ----------
    store : study_app.data.store.Store
    folder : str or Path
        The dataset folder: created; if it exists it must be empty (or ``force``).
    stimuli_dir : str or Path, optional
        The stimuli folder: its ``manifest.json`` goes to ``materials/`` and names the
        dataset (the study's title and description, licence, creators, citation).
    pseudonymise : bool
        Replace identifiers by pseudonyms (default). False: the raw ids.
    include_simulated : bool
        Keep simulated participants (left out by default).
    force : bool
        Write into a non-empty folder (files of the same names are replaced).

    Returns
    -------
    dict
        ``{"folder", "files": [relative paths], "responses", "participants", "events",
        "warnings": [text]}``; the warnings name the recommended metadata missing
        (licence, creators, citation).

    Raises
    ------
    StoreError
        The folder is not empty, the manifest cannot be read, there is no response to
        export (Psych-DS treats a dataset without data as an error), or a row breaks its
        schema. Nothing is written then.
    """
    root = Path(folder)
    if root.exists() and (not root.is_dir() or (any(root.iterdir()) and not force)):
        raise StoreError(f"{root}: not an empty folder (choose a new one)")
    manifest = _manifest(stimuli_dir)
    from .monitor import with_exclusions

    people = with_exclusions(store, store.participants(include_simulated=include_simulated))
    keep = {p["participant_id"] for p in people}
    rows = store.export_rows(include_simulated=include_simulated)
    events = [e for e in store.events() if e["participant_id"] in keep]
    if pseudonymise:
        anon = Pseudonymiser(store)
        rows, people, events = anon.records(rows), anon.records(people), anon.records(events)
    study_of = {p["participant_id"]: p["study_id"] for p in people}
    studies = sorted({p["study_id"] for p in people})
    if not rows:
        # Psych-DS requires at least one data file with rows: an empty export is an error.
        raise StoreError(
            "no responses to export"
            + (
                ""
                if include_simulated
                else " (simulated participants are left out: --include-simulated)"
            )
        )
    file_keys = study_file_keys(studies)
    # Written in a folder beside, renamed into place at the end: a failure leaves nothing.
    work = root.parent / f".{root.name}.{secrets.token_hex(4)}.tmp"
    try:
        files, columns = _write_data(
            work, studies, file_keys, rows, people, events, study_of, pseudonymise
        )
        if manifest is not None:
            (work / "materials").mkdir()
            shutil.copyfile(manifest[0], work / "materials" / manifest[0].name)
            files.append(f"materials/{manifest[0].name}")
        study = manifest[1] if manifest is not None else None
        doc, warnings = _description(study, studies, columns, pseudonymise)
        # Who withdrew is part of who was left out (snapshot analyze --input reports it
        # as --db does): per study, a count only; their data are deleted, none is here.
        from .withdraw import withdrawal_counts

        gone = withdrawal_counts(store)
        doc["withdrawals"] = {sid: gone.get(sid, 0) for sid in studies}
        _write_atomic(work / DESCRIPTION_NAME, json.dumps(doc, indent=2, ensure_ascii=False) + "\n")
        files.insert(0, DESCRIPTION_NAME)
        _move_into(work, root)
    except BaseException:
        shutil.rmtree(work, ignore_errors=True)
        raise
    return {
        "folder": root,
        "files": files,
        "responses": len(rows),
        "participants": len(people),
        "events": len(events),
        "warnings": warnings,
    }


def _write_data(work, studies, file_keys, rows, people, events, study_of, pseudonymise):
    """The data files of every study in ``work/data``; their paths and columns."""
    try:
        (work / "data").mkdir(parents=True)
    except OSError as err:
        raise StoreError(f"cannot write {work.parent}: {err.strerror or err}") from None
    dropped = OPEN_DROPPED if pseudonymise else ()
    files: list[str] = []
    columns: dict[str, list[str]] = {}
    for sid in studies:
        for description, records, write, schema_name, names in (
            (
                None,
                [r for r in rows if r["study_id"] == sid],
                write_export,
                "response",
                export_columns(),
            ),
            (
                "participants",
                [p for p in people if p["study_id"] == sid],
                lambda recs, path: write_participants(recs, path, drop=dropped),
                "participant",
                [c for c in participants_columns() if c not in dropped],
            ),
            (
                "events",
                [e for e in events if study_of.get(e["participant_id"]) == sid],
                lambda recs, path: write_events(recs, path, fmt="csv"),
                "event",
                events_columns(),
            ),
        ):
            if not records:  # Psych-DS: no header-only files
                continue
            rel = Path("data") / data_file_name(file_keys[sid], description)
            write(records, work / rel)
            files.append(rel.as_posix())
            columns.setdefault(schema_name, names)
    return files, columns


def _description(study, studies, columns, pseudonymise) -> tuple[dict, list[str]]:
    """``dataset_description.json`` and the warnings about missing metadata."""
    title = study.title if study else f"Action Snapshot study {', '.join(studies)}"
    # The dataset's own description; the study's description is the text participants read.
    description = (
        "Responses of an Action Snapshot user study: for each animation, participants picked "
        "the frame that best tells the action (pose task) and the clearest of three views of "
        "the selected pose (view task), plus one attention check. data/ holds one CSV per "
        "table (responses; participants with their background answers; interaction events "
        "with the video player); materials/ the stimulus manifest (scenes, frame maps, "
        "file checksums). Frames are 0-based in the source motion's numbering; times are "
        + (
            "UTC months (YYYY-MM; the seed of each participant's trial order is left out, "
            "so that no column links a row to the study's private records)"
            if pseudonymise
            else "ISO 8601 in UTC"
        )
        + "; in CSV, lists and objects are JSON strings and empty cells are "
        "missing values. Participants who withdrew are not in any file (their data were "
        "deleted); `withdrawals` counts them per study. The participants file's "
        "`excluded` column names those the researcher left out of the analysis, with "
        "the reason." + (_PSEUDONYM_NOTE if pseudonymise else "")
    )
    doc = {
        "@context": "https://schema.org/",
        "@type": "Dataset",
        "name": title,
        "schemaVersion": SCHEMA_VERSION,
        "description": description,
        "keywords": ["motion perception", "key poses", "viewpoint selection", "user study"],
        "dateCreated": datetime.now(UTC).isoformat(timespec="seconds"),
        "variableMeasured": variable_measured(columns),
    }
    missing = []
    if study is not None and study.license:
        doc["license"] = study.license
    else:
        missing.append("license")
    if study is not None and study.creators:
        doc["author"] = [{"@type": "Person", "name": n} for n in study.creators]
    else:
        missing.append("creators")
    if study is not None and study.citation:
        doc["citation"] = study.citation
    else:
        missing.append("citation")
    warnings = []
    if missing:
        where = (
            "the study config's [study] table"
            if study is not None
            else "the study config (give --stimuli to use it)"
        )
        warnings.append(
            f"dataset_description.json has no {', '.join(missing)}: set "
            f"{', '.join(missing)} in {where} (Psych-DS recommends them; a repository "
            "needs the licence to publish the data)"
        )
    return doc, warnings


def _move_into(work: Path, root: Path) -> None:
    """Rename the finished folder ``work`` to ``root`` (which is absent or empty), or,
    with ``force`` into a non-empty ``root``, move its entries over."""
    try:
        if root.exists() and any(root.iterdir()):
            for src in sorted(work.rglob("*")):
                dst = root / src.relative_to(work)
                if src.is_dir():
                    dst.mkdir(exist_ok=True)
                else:
                    os.replace(src, dst)
            shutil.rmtree(work, ignore_errors=True)
            return
        if root.exists():
            root.rmdir()
        os.replace(work, root)
    except OSError as err:
        raise StoreError(f"cannot write {root}: {err.strerror or err}") from None
