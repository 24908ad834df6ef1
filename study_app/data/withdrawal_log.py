"""The withdrawal log: every withdrawal, also outside the database it deleted from.

A withdrawal's record lives in the database (``withdrawals``); a backup taken before it
does not hold it. When the database is lost, the usual reason to restore, that record
is lost with it, and a restore of an older backup would bring the withdrawn people
back. So :func:`study_app.data.withdraw.withdraw` also appends each withdrawal, in its
transaction and before it commits, as one JSON line to a log file outside the database:

- ``$SNAPSHOT_WITHDRAWAL_LOG`` when set (put it on another disk than the database);
- else, for a SQLite database ``study.db``, ``study.db.withdrawals.jsonl`` beside it;
- else (PostgreSQL) ``var/<database>.withdrawals.jsonl`` in the project.

Every ``snapshot backup`` also writes the withdrawals it copied into
``withdrawals.jsonl`` beside the backup file (merged with what is there), so that a
folder of backups carries every withdrawal up to its newest backup.
:func:`study_app.data.backup.restore` applies the log of the target, the list beside
the backup and any ``withdrawals_from`` source, and refuses when it has no log made
after the backup (one line), unless the researcher waives it.

A line: ``{"participant_id", "study_id", "prolific_pid", "requested_by",
"withdrawn_at", "completion_code", "completed_at"}`` (times ISO 8601, UTC; the code and
finishing time only for someone who had finished, for payment). It holds the ids the
``withdrawals`` table holds and nothing the participant answered. ``snapshot
anonymise`` appends ``{"study_id", "anonymised_at"}``: a restore of a backup made
before it destroys the restored secret again (:func:`read_anonymised`).
"""

from __future__ import annotations

import json
import os
from datetime import UTC, datetime
from pathlib import Path

from .database import normalize_url
from .errors import StoreError

__all__ = [
    "LOG_ENV",
    "LOG_SUFFIX",
    "BACKUP_LOG_NAME",
    "log_path",
    "append_log",
    "read_log",
    "read_anonymised",
    "merge_into",
]

#: Environment variable naming the log file (overrides the default place).
LOG_ENV = "SNAPSHOT_WITHDRAWAL_LOG"
#: The default log of a SQLite database: its file name with this suffix.
LOG_SUFFIX = ".withdrawals.jsonl"
#: The list of withdrawals beside a backup file (one per folder of backups).
BACKUP_LOG_NAME = "withdrawals.jsonl"
_FIELDS = (
    "participant_id",
    "study_id",
    "prolific_pid",
    "requested_by",
    "withdrawn_at",
    "completion_code",
    "completed_at",
)
_TIMES = ("withdrawn_at", "completed_at", "anonymised_at")


def log_path(url) -> Path:
    """The withdrawal log of the database at ``url`` (see the module notes)."""
    env = os.environ.get(LOG_ENV, "").strip()
    if env:
        return Path(env).expanduser()
    parsed = normalize_url(url)
    if parsed.get_backend_name() == "sqlite" and parsed.database not in (None, "", ":memory:"):
        return Path(parsed.database).expanduser().resolve().parent / (
            Path(parsed.database).name + LOG_SUFFIX
        )
    name = parsed.database or "database"
    return Path(__file__).resolve().parents[2] / "var" / f"{name}{LOG_SUFFIX}"


def _iso(value):
    if isinstance(value, datetime):
        value = value.replace(tzinfo=UTC) if value.tzinfo is None else value.astimezone(UTC)
        return value.isoformat()
    return value


def _line(record: dict) -> str:
    """One log line: a withdrawal, or (no ``participant_id``) an anonymisation."""
    keys = _FIELDS if record.get("participant_id") else ("study_id", "anonymised_at")
    out = {k: _iso(record.get(k)) for k in keys}
    return json.dumps(out, ensure_ascii=False) + "\n"


def _time(value):
    if value in (None, ""):
        return None
    at = datetime.fromisoformat(str(value))
    return at.replace(tzinfo=UTC) if at.tzinfo is None else at


def append_log(path, records) -> None:
    """Append ``records`` (dicts with the fields of a ``withdrawals`` row) to the log at
    ``path``, flushed to disk before returning.

    Raises
    ------
    StoreError
        The log cannot be written (the caller's transaction then rolls back).
    """
    path = Path(path)
    text = "".join(_line(r) for r in records)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with open(path, "a", encoding="utf-8") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
    except OSError as err:
        raise StoreError(
            f"cannot write the withdrawal log {path}: {err.strerror or err} "
            f"(set ${LOG_ENV} to a writable file); nothing was changed"
        ) from None


def _entries(path) -> list[dict]:
    """Every line of the log at ``path``, times as aware datetimes.

    Raises
    ------
    StoreError
        The file cannot be read, or a line is neither a withdrawal nor an
        anonymisation record (file:line).
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as err:
        raise StoreError(f"cannot read the withdrawal log {path}: {err.strerror or err}") from None
    out = []
    for lineno, line in enumerate(text.splitlines(), start=1):
        if not line.strip():
            continue
        try:
            rec = json.loads(line)
            if not isinstance(rec, dict):
                raise ValueError("not an object")
            if rec.get("participant_id"):
                rec = {k: rec.get(k) for k in _FIELDS}
                if rec["withdrawn_at"] is None:
                    raise ValueError("no withdrawn_at")
                rec["study_id"] = rec["study_id"] or ""
                rec["requested_by"] = rec["requested_by"] or "cli"
            elif rec.get("study_id") and rec.get("anonymised_at"):
                rec = {"study_id": rec["study_id"], "anonymised_at": rec["anonymised_at"]}
            else:
                raise ValueError("neither a participant_id nor an anonymised study")
            for k in _TIMES:
                if k in rec:
                    rec[k] = _time(rec[k])
        except (ValueError, TypeError) as err:
            msg = getattr(err, "msg", None) or str(err)
            raise StoreError(f"{path}:{lineno}: not a withdrawal record ({msg})") from None
        out.append(rec)
    return out


def read_log(path) -> list[dict]:
    """The withdrawal records of a log (times as aware datetimes; missing fields None).

    Raises
    ------
    StoreError
        See :func:`_entries`.
    """
    return [r for r in _entries(path) if r.get("participant_id")]


def read_anonymised(path) -> dict:
    """Study id → when ``snapshot anonymise`` destroyed its secret, from a log."""
    return {r["study_id"]: r["anonymised_at"] for r in _entries(path) if "anonymised_at" in r}


def merge_into(path, records) -> int:
    """Add to the log at ``path`` the records it lacks (a withdrawal per participant, an
    anonymisation per study); return how many were added. The file is rewritten
    atomically (a temp file renamed)."""
    from .export import _write_atomic

    path = Path(path)
    have = _entries(path) if path.exists() else []

    def key(r):
        return ("p", r["participant_id"]) if r.get("participant_id") else ("s", r["study_id"])

    known = {key(r) for r in have}
    new = []
    for r in records:
        if key(r) not in known:
            known.add(key(r))
            new.append(r)
    if new:
        _write_atomic(path, "".join(_line(r) for r in [*have, *new]))
    return len(new)
