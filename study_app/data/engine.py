"""Opening a study database and running transactions on it: the base of :class:`Store`.

:class:`StoreEngine` turns a URL into a SQLAlchemy engine (pool sizes, SQLite's pragmas and
shared in-memory connection, PostgreSQL's connect timeout), creates missing tables and
indexes (never drops or alters anything), runs one transaction per call (database failures
become a one-line :class:`StoreError`), queues SQLite writes in-process and lets them share
a transaction (:mod:`study_app.data.group_commit`), and checks a participant id before any
query. Also here: the UTC timestamp helpers and the participant look-up every part of the
store uses. The queries themselves are in the modules :class:`Store` is made of
(:mod:`.participant_records`, :mod:`.response_records`, :mod:`.event_records`,
:mod:`.researcher_queries`).
"""

from __future__ import annotations

import re
import sqlite3
import threading
import warnings
from collections.abc import Callable, Iterator
from contextlib import contextmanager, nullcontext
from datetime import UTC, datetime
from functools import partial
from pathlib import Path
from typing import Any, Self, TypeVar

import sqlalchemy as sa
from sqlalchemy import exc as sa_exc

from .database import (
    PROLIFIC_INDEX,
    STUDY_TABLES,
    configure_sqlite,
    create_tables,
    metadata,
    normalize_url,
    one_line,
    participants,
    standalone_sqlite,
    upgrade_columns,
)
from .errors import StoreError
from .group_commit import GroupCommit

__all__ = ["StoreEngine", "CONNECT_TIMEOUT_S", "PARTICIPANT_ID_RE"]

#: Seconds to wait for a database server to answer the first connection.
CONNECT_TIMEOUT_S = 10
#: Participant ids are ``secrets.token_urlsafe(16)``: 22 characters of [A-Za-z0-9_-].
#: Anything else (much shorter/longer, other characters) is refused before any query.
PARTICIPANT_ID_RE = re.compile(r"^[A-Za-z0-9_-]{16,64}$")
#: Retries of a write that lost a race on the (participant, trial) unique key.
_DUPLICATE_RETRIES = 3
_T = TypeVar("_T")


def _utcnow() -> datetime:
    return datetime.now(UTC)


def _utc(value: datetime | str | None) -> datetime | None:
    """A stored timestamp as an aware UTC datetime (SQLite gives naive UTC ones back,
    sometimes as text)."""
    if value is None:
        return None
    if isinstance(value, str):
        value = datetime.fromisoformat(value)
    if value.tzinfo is None:
        value = value.replace(tzinfo=UTC)
    return value.astimezone(UTC)


def _iso(value: datetime | str | None) -> str | None:
    """A stored timestamp as ISO 8601 in UTC."""
    value = _utc(value)
    return None if value is None else value.isoformat(timespec="microseconds")


# -- statements of every script run, built once -----------------------------------------
# SQLAlchemy derives a cache key from a statement every time it is built; a statement
# built once keeps it.
_PARTICIPANT = sa.select(participants).where(participants.c.participant_id == sa.bindparam("pid"))


class StoreEngine:
    """The engine and transactions of a :class:`~study_app.data.store.Store`.

    Parameters and errors as :class:`~study_app.data.store.Store`, which adds the queries.
    """

    def __init__(self, url: str | None = None, *, create: bool = True) -> None:
        self._url = normalize_url(url)
        self.url = self._url.render_as_string(hide_password=True)
        self.dialect = self._url.get_backend_name()
        self._create = create
        # SQLite has one writer at a time; threads of this process queue here, woken
        # the moment the writer commits, instead of in SQLite's busy handler, which
        # polls with sleeps of up to 100 ms (under a 100-participant launch half of
        # the script-run time went there). Other processes still wait on busy_timeout.
        self._write_lock = threading.RLock() if self.dialect == "sqlite" else None
        # ... and the writes that queue there share the next transaction (one BEGIN and
        # one COMMIT for many answers under load; see study_app.data.group_commit).
        self._group = (
            GroupCommit(partial(self.transaction, write=True)) if self.dialect == "sqlite" else None
        )
        self.engine = self._make_engine()
        try:
            with self.engine.connect() as conn:
                conn.exec_driver_sql("SELECT 1")
                missing = [t for t in metadata.tables if not sa.inspect(conn).has_table(t)]
            lacking = [t for t in STUDY_TABLES if t in missing]
            if not create and lacking:
                raise StoreError(
                    f"database {self.url} has no study tables "
                    f"({', '.join(lacking)} missing): wrong database?"
                )
            if missing:
                # A new database, or one made before the withdrawals/secrets tables.
                self._create_tables()
            if create:
                self._create_indexes()
        except sa_exc.SQLAlchemyError as err:
            self.engine.dispose()
            raise StoreError(f"cannot open database {self.url}: {one_line(err)}") from None
        except StoreError:
            self.engine.dispose()
            raise

    # -- engine ------------------------------------------------------------------------
    def _make_engine(self) -> sa.engine.Engine:
        url = self._url
        kwargs: dict[str, Any] = {}  # create_engine's options for this dialect
        if self.dialect == "sqlite":
            database = url.database or ""
            in_memory = database in ("", ":memory:") or database.startswith("file::memory:")
            if in_memory:
                # One shared connection, or every checkout would see an empty database.
                kwargs["poolclass"] = sa.pool.StaticPool
                kwargs["connect_args"] = {"check_same_thread": False}
            else:
                if not self._create and not Path(database).expanduser().exists():
                    # Reading (export) must not leave an empty database at a mistyped path.
                    raise StoreError(f"cannot open database {self.url}: no such file")
                folder = Path(database).expanduser().resolve().parent
                try:
                    folder.mkdir(parents=True, exist_ok=True)
                except OSError as err:
                    raise StoreError(
                        f"cannot open database {self.url}: cannot create folder "
                        f"{folder} ({err.strerror or err})"
                    ) from None
                # Threads of the app share the pool; writes queue on the busy timeout.
                kwargs.update(pool_size=10, max_overflow=40, pool_timeout=60)
        elif self.dialect == "postgresql":
            if "connect_timeout" not in url.query:
                kwargs["connect_args"] = {"connect_timeout": CONNECT_TIMEOUT_S}
            kwargs.update(pool_size=10, max_overflow=40, pool_timeout=60, pool_pre_ping=True)
        try:
            engine = sa.create_engine(url, **kwargs)
        except sa_exc.NoSuchModuleError:
            raise StoreError(
                f"cannot open database {self.url}: unknown database type "
                f"{url.drivername!r} (expected sqlite:///PATH or "
                "postgresql+psycopg://USER@HOST:PORT/DB)"
            ) from None
        except ImportError as err:
            raise StoreError(
                f"cannot open database {self.url}: its driver is not installed ({err})"
            ) from None
        except (sa_exc.ArgumentError, TypeError) as err:
            raise StoreError(f"cannot open database {self.url}: {one_line(err)}") from None
        if self.dialect == "sqlite":
            configure_sqlite(engine)
        return engine

    def _create_tables(self) -> None:
        create_tables(self.engine)

    def _create_indexes(self) -> None:
        """Add columns and indexes a database made by an older version lacks (never
        drops anything)."""
        upgrade_columns(self.engine)
        try:
            with self.transaction(write=True) as conn:
                PROLIFIC_INDEX.create(conn, checkfirst=True)
        except StoreError as err:
            # e.g. an old database already holding one Prolific id twice: serve it, and
            # let participant_for_prolific's lookup keep new duplicates out.
            warnings.warn(
                f"database {self.url}: cannot add the one-participant-per-Prolific-id "
                f"index ({err})",
                stacklevel=3,
            )

    def close(self) -> None:
        """Release every pooled connection."""
        self.engine.dispose()

    def copy_sqlite(self, dest: str | Path) -> None:
        """Copy this SQLite database into the new file ``dest`` with SQLite's online
        backup while the app may write, and make the copy standalone (a backup)."""
        database = self.engine.url.database
        if not database:
            raise StoreError(f"cannot back up {self.url}: an in-memory database has no file")
        try:
            src = sqlite3.connect(database, timeout=30)
            dst = sqlite3.connect(dest)
            try:
                # pages=-1: one step, one read snapshot (more steps restart on every write)
                src.backup(dst, pages=-1)
                standalone_sqlite(dst)
            finally:
                dst.close()
                src.close()
        except sqlite3.Error as err:
            raise StoreError(f"cannot back up {self.engine.url.database}: {err}") from None

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"Store({self.url!r})"

    @contextmanager
    def transaction(self, *, write: bool) -> Iterator[sa.Connection]:
        """One transaction; database failures become a one-line :class:`StoreError`."""
        lock = self._write_lock if write and self._write_lock is not None else nullcontext()
        try:
            with lock, self.engine.connect() as conn:
                if write:
                    conn = conn.execution_options(snapshot_write=True)
                with conn.begin():
                    yield conn
        except sa_exc.SQLAlchemyError as err:
            raise StoreError(f"database {self.url}: {one_line(err)}") from err

    def _write(self, work: Callable[[sa.Connection], _T]) -> _T:
        """``work(conn)`` in a committed write transaction (shared with other threads'
        writes on SQLite); its value. ``work`` must touch nothing but ``conn``."""
        if self._group is not None:
            return self._group.run(work)
        with self.transaction(write=True) as conn:
            return work(conn)

    @staticmethod
    def _check_pid(pid: object) -> str:
        if not isinstance(pid, str) or not PARTICIPANT_ID_RE.match(pid):
            raise StoreError(f"unknown participant id {str(pid)[:70]!r}")
        return pid

    def _participant_row(self, conn: sa.Connection, pid: str) -> sa.RowMapping:
        row = conn.execute(_PARTICIPANT, {"pid": self._check_pid(pid)}).mappings().first()
        if row is None:
            raise StoreError(f"unknown participant id {pid!r}")
        return row
