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
"withdrawn_at"}`` (ISO 8601, UTC). It holds the ids the ``withdrawals`` table holds
and nothing the participant answered.
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
    "merge_into",
]

#: Environment variable naming the log file (overrides the default place).
LOG_ENV = "SNAPSHOT_WITHDRAWAL_LOG"
#: The default log of a SQLite database: its file name with this suffix.
LOG_SUFFIX = ".withdrawals.jsonl"
#: The list of withdrawals beside a backup file (one per folder of backups).
BACKUP_LOG_NAME = "withdrawals.jsonl"
_FIELDS = ("participant_id", "study_id", "prolific_pid", "requested_by", "withdrawn_at")


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


def _line(record: dict) -> str:
    out = {k: record.get(k) for k in _FIELDS}
    at = out["withdrawn_at"]
    if isinstance(at, datetime):
        at = at.replace(tzinfo=UTC) if at.tzinfo is None else at.astimezone(UTC)
        out["withdrawn_at"] = at.isoformat()
    return json.dumps(out, ensure_ascii=False) + "\n"


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
            f"(set ${LOG_ENV} to a writable file); nothing was deleted"
        ) from None


def read_log(path) -> list[dict]:
    """The records of a withdrawal log (``withdrawn_at`` as an aware datetime).

    Raises
    ------
    StoreError
        The file cannot be read, or a line is not a withdrawal record (file:line).
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
            if not isinstance(rec, dict) or not rec.get("participant_id"):
                raise ValueError("no participant_id")
            at = datetime.fromisoformat(str(rec["withdrawn_at"]))
        except (ValueError, KeyError, TypeError) as err:
            msg = getattr(err, "msg", None) or str(err)
            raise StoreError(f"{path}:{lineno}: not a withdrawal record ({msg})") from None
        rec["withdrawn_at"] = at.replace(tzinfo=UTC) if at.tzinfo is None else at
        rec.setdefault("study_id", "")
        rec.setdefault("requested_by", "cli")
        out.append({k: rec.get(k) for k in _FIELDS})
    return out


def merge_into(path, records) -> int:
    """Add to the log at ``path`` the records whose participant it lacks; return how
    many were added. The file is rewritten atomically (a temp file renamed)."""
    from .export import _write_atomic

    path = Path(path)
    have = read_log(path) if path.exists() else []
    known = {r["participant_id"] for r in have}
    new = []
    for r in records:
        if r["participant_id"] not in known:
            known.add(r["participant_id"])
            new.append(r)
    if new:
        _write_atomic(path, "".join(_line(r) for r in [*have, *new]))
    return len(new)
