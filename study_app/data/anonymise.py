"""Anonymisation: destroy a study's pseudonym secret, on purpose and for good.

A pseudonymised dataset stays pseudonymous while anybody holds the secret that made
its pseudonyms (:mod:`study_app.data.pseudonym`): with it, ``p-…`` leads back to a
participant row, its Prolific id and its completion code. :func:`anonymise` ends that:

- the study's row of ``study_secrets`` keeps an empty secret and ``anonymised_at``
  (so that no new secret is ever made for it, and the time is on record);
- the old value is scrubbed from the database's storage, not only from its table:
  SQLite runs with ``secure_delete`` and is then rebuilt (``VACUUM``) with its
  write-ahead log truncated; PostgreSQL rewrites the table (``VACUUM FULL``), whose old
  file the server then deletes;
- exports made afterwards get a fresh secret per export that is never stored: the files
  of one export still agree with each other, but no pseudonym can be traced, not even by
  the researcher.

The anonymisation is logged outside the database too (the withdrawal log,
:mod:`study_app.data.withdrawal_log`): restoring a backup made before it destroys the
restored secret again (:func:`reapply_anonymisations`).

What it costs: a withdrawal can no longer be asked by pseudonym (by link id or Prolific
id it still can, while the database keeps them), and two exports made after it give
the same person different pseudonyms. Backups made *before* it still hold the secret:
delete them (the command says so). PostgreSQL's own write-ahead log keeps the old row
until the server recycles its segments (a checkpoint is requested; minutes on a busy
server).
"""

from __future__ import annotations

import sqlite3
from dataclasses import dataclass
from datetime import UTC, datetime

import sqlalchemy as sa
from sqlalchemy import exc as sa_exc

from .database import one_line, participants, study_secrets
from .errors import StoreError

__all__ = ["Anonymisation", "anonymise", "anonymised_studies", "reapply_anonymisations"]


@dataclass(frozen=True)
class Anonymisation:
    """One study whose secret :func:`anonymise` destroyed.

    Attributes
    ----------
    study_id : str
    anonymised_at : datetime
        When (UTC); for a study anonymised earlier, that earlier time.
    already : bool
        The study had been anonymised before this call (nothing changed).
    """

    study_id: str
    anonymised_at: datetime
    already: bool = False


def _utc(value) -> datetime:
    if isinstance(value, str):
        value = datetime.fromisoformat(value)
    return value.replace(tzinfo=UTC) if value.tzinfo is None else value.astimezone(UTC)


def anonymised_studies(store) -> dict[str, datetime]:
    """Study id → when its secret was destroyed, for every anonymised study."""
    with store.transaction(write=False) as conn:
        columns = {c["name"] for c in sa.inspect(conn).get_columns("study_secrets")}
        if "anonymised_at" not in columns:  # a database older than anonymise
            return {}
        rows = conn.execute(
            sa.select(study_secrets.c.study_id, study_secrets.c.anonymised_at).where(
                study_secrets.c.secret == ""
            )
        ).all()
    return {sid: _utc(at) for sid, at in rows if at is not None}


def anonymise(store, *, study_id: str | None = None) -> list[Anonymisation]:
    """Destroy the pseudonym secret of ``study_id`` (or of every study in the database).

    The anonymisation is also appended to the withdrawal log outside the database
    (:mod:`study_app.data.withdrawal_log`), so that restoring a backup made before it
    destroys the restored secret again.

    Parameters
    ----------
    store : study_app.data.store.Store
    study_id : str, optional
        One study; every study with participants or a secret when None.

    Returns
    -------
    list of Anonymisation
        One per study, by study id.

    Raises
    ------
    StoreError
        An unknown study (no participant, no secret), nothing to anonymise, the log
        cannot be written (nothing is changed then), or the database cannot be
        rewritten (another process holds it: stop the app first).
    """
    return _anonymise(store, None if study_id is None else {study_id: None}, log=True)


def reapply_anonymisations(store, studies: dict) -> list[Anonymisation]:
    """Destroy again, with their first time kept, the secrets of ``studies`` (study id →
    when it was anonymised) that a restored backup brought back; the studies the
    database does not know are skipped."""
    with store.transaction(write=False) as conn:
        known = set(conn.execute(sa.select(study_secrets.c.study_id)).scalars()) | set(
            conn.execute(sa.select(participants.c.study_id).distinct()).scalars()
        )
    wanted = {sid: at for sid, at in studies.items() if sid in known}
    return _anonymise(store, wanted, log=False) if wanted else []


def _anonymise(store, wanted: dict | None, *, log: bool) -> list[Anonymisation]:
    """Blank the secrets of ``wanted`` (study id → time, None for now; None: every
    study), log them, then scrub the storage."""
    from .withdrawal_log import append_log, log_path

    now = datetime.now(UTC)
    done = []
    with store.transaction(write=True) as conn:
        if conn.dialect.name == "sqlite":
            # Deleted and overwritten cells are zeroed, not left in free space.
            conn.exec_driver_sql("PRAGMA secure_delete = ON")
        held = {
            sid: (secret, at)
            for sid, secret, at in conn.execute(
                sa.select(
                    study_secrets.c.study_id, study_secrets.c.secret, study_secrets.c.anonymised_at
                )
            ).all()
        }
        studies = set(conn.execute(sa.select(participants.c.study_id).distinct()).scalars())
        if wanted is None:
            wanted = dict.fromkeys(sorted(set(held) | studies))
        for sid in wanted:
            if sid not in held and sid not in studies:
                raise StoreError(
                    f"unknown study {sid!r}: no participant and no pseudonym secret "
                    "in this database; nothing was changed"
                )
        if not wanted:
            raise StoreError("the database holds no study to anonymise; nothing was changed")
        for sid, when in sorted(wanted.items()):
            when = _utc(when) if when is not None else now
            secret, at = held.get(sid, (None, None))
            if secret == "" and at is not None:
                done.append(Anonymisation(sid, _utc(at), already=True))
                continue
            if secret is None:  # no participant yet: keep any later one from making one
                conn.execute(
                    study_secrets.insert().values(
                        study_id=sid, secret="", created_at=when, anonymised_at=when
                    )
                )
            else:
                conn.execute(
                    study_secrets.update()
                    .where(study_secrets.c.study_id == sid)
                    .values(secret="", anonymised_at=when)
                )
            done.append(Anonymisation(sid, when))
        new = [
            {"study_id": a.study_id, "anonymised_at": a.anonymised_at}
            for a in done
            if not a.already
        ]
        if log and new:  # before the commit, like a withdrawal
            append_log(log_path(store._url), new)
    _scrub(store)  # also after an earlier run whose scrub failed
    return done


def _scrub(store) -> None:
    """Rewrite the storage so that the old secret survives in no page or log."""
    try:
        if store.dialect == "sqlite":
            raw = store.engine.raw_connection()  # in autocommit (configure_sqlite)
            try:
                db = raw.driver_connection
                db.execute("PRAGMA secure_delete = ON")
                db.execute("VACUUM")
                db.execute("PRAGMA wal_checkpoint(TRUNCATE)")
            finally:
                raw.close()
        elif store.dialect == "postgresql":
            with store.engine.connect() as conn:
                conn = conn.execution_options(isolation_level="AUTOCOMMIT")
                conn.exec_driver_sql("VACUUM FULL study_secrets")
                try:
                    conn.exec_driver_sql("CHECKPOINT")
                except sa_exc.SQLAlchemyError:
                    pass  # needs pg_checkpoint rights; the server checkpoints on its own
    except (sa_exc.SQLAlchemyError, sqlite3.Error) as err:  # e.g. the file is locked
        raise StoreError(
            "the secret is destroyed, but its old copy could not be scrubbed from the "
            f"database's storage ({one_line(err)}); stop the app and run anonymise again"
        ) from None
