"""The study store: participants, their answers and their interaction events, in SQL.

The one place SQL lives (SQLAlchemy 2 Core). SQLite by default, at
``<repo>/var/study.db`` (``$SNAPSHOT_DB`` or an explicit URL override it); any
SQLAlchemy URL works, e.g. PostgreSQL through psycopg
(``postgresql+psycopg://user:password@host:5432/db``; a plain ``postgresql://`` URL is
mapped to psycopg).

Tables
------
``participants``
    One row per participant: an unguessable id (``secrets.token_urlsafe(16)``), the
    study id, the per-participant seed, Prolific's ``PROLIFIC_PID``/``STUDY_ID``/
    ``SESSION_ID`` when present, the background answers (JSON), the app version, the
    stimulus-manifest sha256, the simulated flag, created/completed timestamps and the
    completion code.
``responses``
    Append-only, one row per trial, ``UNIQUE (participant_id, trial_index)``: task,
    scene, stimulus, the chosen motion frame (source numbering) and video frame, the
    algorithm's frame, the chosen method/position and the order the methods were shown
    in, the raw chosen value, response time, timestamp, app version, manifest hash.
``events``
    Interaction events (plays, pauses, seeks, steps...) with a JSON payload.
``withdrawals``, ``study_secrets``
    Who withdrew (:mod:`study_app.data.withdraw`) and the per-study pseudonym keys
    (:mod:`study_app.data.pseudonym`); those modules hold their queries. Opening a database
    made before them adds them.

Safety
------
Every write is one transaction. On SQLite each connection gets WAL journaling, a busy
timeout and foreign keys (a connect event), and write transactions start with
``BEGIN IMMEDIATE`` so that concurrent writers queue on the busy timeout instead of
failing when a read lock cannot be upgraded. A re-sent answer hits the unique key:
:meth:`Store.record_response` returns False and the first row stays. An unknown or
malformed participant id raises :class:`StoreError` and writes nothing. Opening a
store only creates missing tables (never drops or alters anything). A broken URL (bad
scheme, unreachable host, wrong password, unwritable SQLite path) raises a one-line
:class:`StoreError` naming the URL with the password masked.

Timestamps are stored in UTC and returned/exported as ISO 8601 strings with an explicit
``+00:00`` offset (``2025-01-31T12:00:00.123456+00:00``).

Export format
-------------
:meth:`Store.export_rows` gives one dict per response with exactly the fields of
``data_schema/response.schema.json`` (absent optional fields are ``None``); the codec,
:mod:`study_app.data.export`, writes them as CSV or JSON lines and reads them back.
"""

from __future__ import annotations

import re
import secrets
import sqlite3
import threading
import warnings
from contextlib import contextmanager, nullcontext
from datetime import UTC, datetime
from functools import partial
from pathlib import Path

import sqlalchemy as sa
from sqlalchemy import exc as sa_exc

from .database import (
    PROLIFIC_INDEX,
    STUDY_TABLES,
    configure_sqlite,
    create_tables,
    default_url,
    events,
    mask_url,
    metadata,
    normalize_url,
    one_line,
    participants,
    responses,
    standalone_sqlite,
    upgrade_columns,
)
from .errors import StoreError
from .export import BACKGROUND_FIELDS, _background_value, export_columns, validate_rows
from .group_commit import GroupCommit
from .pseudonym import ensure_secret
from .rows import checked_event, checked_response

__all__ = ["Store", "default_url", "mask_url", "normalize_url"]

#: Seconds to wait for a database server to answer the first connection.
CONNECT_TIMEOUT_S = 10
#: Participant ids are ``secrets.token_urlsafe(16)``: 22 characters of [A-Za-z0-9_-].
#: Anything else (much shorter/longer, other characters) is refused before any query.
PARTICIPANT_ID_RE = re.compile(r"^[A-Za-z0-9_-]{16,64}$")
#: Completion codes: 8 characters from an alphabet without look-alikes (0/O, 1/I).
COMPLETION_ALPHABET = "ABCDEFGHJKLMNPQRSTUVWXYZ23456789"
COMPLETION_CODE_LENGTH = 8
#: Seeds are stored as signed 64-bit integers.
MAX_SEED = 2**63 - 1
#: Export formats by file suffix.
#: Background answers joined into every export row.
#: Retries of a write that lost a race on the (participant, trial) unique key.
_DUPLICATE_RETRIES = 3
PROLIFIC_KEYS = {
    "PROLIFIC_PID": "prolific_pid",
    "STUDY_ID": "prolific_study_id",
    "SESSION_ID": "prolific_session_id",
}


def _utcnow() -> datetime:
    return datetime.now(UTC)


def _utc(value) -> datetime | None:
    """A stored timestamp as an aware UTC datetime (SQLite gives naive UTC ones back,
    sometimes as text)."""
    if value is None:
        return None
    if isinstance(value, str):
        value = datetime.fromisoformat(value)
    if value.tzinfo is None:
        value = value.replace(tzinfo=UTC)
    return value.astimezone(UTC)


def _iso(value) -> str | None:
    """A stored timestamp as ISO 8601 in UTC."""
    value = _utc(value)
    return None if value is None else value.isoformat(timespec="microseconds")


# -- statements of every script run, built once -----------------------------------------
# SQLAlchemy derives a cache key from a statement every time it is built; a statement
# built once keeps it.
_PARTICIPANT = sa.select(participants).where(participants.c.participant_id == sa.bindparam("pid"))
_ANSWERED = sa.select(responses.c.trial_index).where(
    responses.c.participant_id == sa.bindparam("pid")
)
_PARTICIPANT_EVENTS = (
    sa.select(events).where(events.c.participant_id == sa.bindparam("pid")).order_by(events.c.id)
)
_FIRST_EVENT = sa.select(sa.func.min(events.c.created_at)).where(
    events.c.participant_id == sa.bindparam("pid"),
    events.c.kind == sa.bindparam("kind"),
    events.c.trial_index == sa.bindparam("trial"),
)
_TRIAL_EVENT_COUNT = (
    sa.select(sa.func.count())
    .select_from(events)
    .where(
        events.c.participant_id == sa.bindparam("pid"),
        events.c.trial_index == sa.bindparam("trial"),
    )
)


class Store:
    """Participants, responses and events in one SQL database.

    Parameters
    ----------
    url : str, optional
        SQLAlchemy URL (or a path to a SQLite file). Default: ``$SNAPSHOT_DB``, else
        ``sqlite:///<repo>/var/study.db`` (its folder is created).
    create : bool
        Create missing tables (never drops or changes existing ones). Default True.
        With False (readers such as ``snapshot export``) a missing SQLite file or
        missing tables are an error instead.

    Raises
    ------
    StoreError
        One line naming the (password-masked) URL when the database cannot be opened.

    Notes
    -----
    Thread-safe: one ``Store`` (one connection pool) is meant to be shared by every
    session of the app. Each method is one transaction.
    """

    def __init__(self, url: str | None = None, *, create: bool = True):
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
        url, kwargs = self._url, {}
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

    def copy_sqlite(self, dest) -> None:
        """Copy this SQLite database into the new file ``dest`` with SQLite's online
        backup while the app may write, and make the copy standalone (a backup)."""
        try:
            src = sqlite3.connect(self.engine.url.database, timeout=30)
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

    def __enter__(self) -> Store:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"Store({self.url!r})"

    @contextmanager
    def transaction(self, *, write: bool):
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

    def _write(self, work):
        """``work(conn)`` in a committed write transaction (shared with other threads'
        writes on SQLite); its value. ``work`` must touch nothing but ``conn``."""
        if self._group is not None:
            return self._group.run(work)
        with self.transaction(write=True) as conn:
            return work(conn)

    @staticmethod
    def _check_pid(pid) -> str:
        if not isinstance(pid, str) or not PARTICIPANT_ID_RE.match(pid):
            raise StoreError(f"unknown participant id {str(pid)[:70]!r}")
        return pid

    def _participant_row(self, conn, pid: str):
        row = conn.execute(_PARTICIPANT, {"pid": self._check_pid(pid)}).mappings().first()
        if row is None:
            raise StoreError(f"unknown participant id {pid!r}")
        return row

    # -- participants ------------------------------------------------------------------
    def create_participant(
        self,
        study_id: str,
        manifest_sha256: str,
        *,
        app_version: str,
        seed: int,
        prolific: dict | None = None,
        simulated: bool = False,
    ) -> str:
        """Register a participant; return their new unguessable id.

        Parameters
        ----------
        study_id : str
            The study config's id.
        manifest_sha256 : str
            sha256 (64 hex digits) of the stimuli manifest the participant sees.
        app_version : str
            Version of the app serving them.
        seed : int
            Their trial-order seed, 0 <= seed < 2**63.
        prolific : dict, optional
            ``{"PROLIFIC_PID": ..., "STUDY_ID": ..., "SESSION_ID": ...}`` (any subset;
            empty values are dropped).
        simulated : bool
            True for simulated observers (excluded from exports unless asked).
        """
        self._check_new(study_id, manifest_sha256, app_version, seed)
        values = self._prolific_values(prolific)
        pid = secrets.token_urlsafe(16)
        self._write(
            lambda conn: (
                ensure_secret(conn, study_id),
                conn.execute(
                    participants.insert().values(
                        participant_id=pid,
                        study_id=study_id,
                        seed=seed,
                        app_version=app_version,
                        manifest_sha256=manifest_sha256,
                        simulated=bool(simulated),
                        created_at=_utcnow(),
                        **values,
                    )
                ),
            )
        )
        return pid

    @staticmethod
    def _check_new(study_id, manifest_sha256, app_version, seed) -> None:
        if not isinstance(study_id, str) or not study_id or len(study_id) > 200:
            raise StoreError(f"study_id must be a non-empty string, got {study_id!r}")
        if not isinstance(manifest_sha256, str) or not re.fullmatch(
            r"[0-9a-f]{64}", manifest_sha256
        ):
            raise StoreError(
                f"manifest_sha256 must be 64 lowercase hex digits, got {manifest_sha256!r}"
            )
        if not isinstance(app_version, str) or not app_version:
            raise StoreError(f"app_version must be a non-empty string, got {app_version!r}")
        if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed <= MAX_SEED:
            raise StoreError(f"seed must be an integer in [0, 2**63), got {seed!r}")

    @staticmethod
    def _prolific_values(prolific: dict | None) -> dict:
        values = {v: None for v in PROLIFIC_KEYS.values()}
        for key, value in (prolific or {}).items():
            if key not in PROLIFIC_KEYS:
                raise StoreError(
                    f"unknown Prolific parameter {key!r} (expected {', '.join(PROLIFIC_KEYS)})"
                )
            if value not in (None, ""):
                values[PROLIFIC_KEYS[key]] = str(value)[:200]
        return values

    def find_prolific(self, study_id: str, prolific_pid: str) -> str | None:
        """The participant id registered for a Prolific id in a study, or None."""
        with self.transaction(write=False) as conn:
            return (
                conn.execute(
                    sa.select(participants.c.participant_id)
                    .where(
                        participants.c.study_id == study_id,
                        participants.c.prolific_pid == str(prolific_pid),
                    )
                    .order_by(participants.c.created_at)
                )
                .scalars()
                .first()
            )

    def participant_for_prolific(
        self, study_id: str, manifest_sha256: str, *, app_version: str, seed: int, prolific: dict
    ) -> tuple[str, bool]:
        """The participant of a Prolific id in this study, registered if new.

        One Prolific id is one participant per study: the same study link opened again,
        in any browser, finds the first record instead of starting a second one.

        Parameters
        ----------
        study_id, manifest_sha256, app_version, seed
            As :meth:`create_participant` (used only when the id is new).
        prolific : dict
            Must hold ``PROLIFIC_PID``; ``STUDY_ID``/``SESSION_ID`` are stored if given.

        Returns
        -------
        (participant_id, created) : tuple of (str, bool)
        """
        ppid = (prolific or {}).get("PROLIFIC_PID")
        if not ppid:
            raise StoreError("participant_for_prolific needs a PROLIFIC_PID")
        self._check_new(study_id, manifest_sha256, app_version, seed)
        values = self._prolific_values(prolific)
        for attempt in range(_DUPLICATE_RETRIES + 1):
            try:
                # Look-up and insert in one write transaction: on SQLite it holds the
                # write lock (BEGIN IMMEDIATE), so two browsers cannot both insert; on
                # PostgreSQL the unique index refuses the loser, who retries and finds
                # the winner's row.
                return self._write(
                    partial(
                        self._find_or_insert_prolific,
                        study_id=study_id,
                        seed=seed,
                        app_version=app_version,
                        manifest_sha256=manifest_sha256,
                        values=values,
                    )
                )
            except StoreError as err:
                if (
                    not isinstance(err.__cause__, sa_exc.IntegrityError)
                    or attempt == _DUPLICATE_RETRIES
                ):
                    raise
        raise AssertionError("unreachable")  # pragma: no cover

    @staticmethod
    def _find_or_insert_prolific(
        conn, *, study_id, seed, app_version, manifest_sha256, values
    ) -> tuple[str, bool]:
        found = (
            conn.execute(
                sa.select(participants.c.participant_id)
                .where(
                    participants.c.study_id == study_id,
                    participants.c.prolific_pid == values["prolific_pid"],
                )
                .order_by(participants.c.created_at)
            )
            .scalars()
            .first()
        )
        if found is not None:
            return found, False
        pid = secrets.token_urlsafe(16)
        ensure_secret(conn, study_id)  # the pseudonym key exists from the first participant
        conn.execute(
            participants.insert().values(
                participant_id=pid,
                study_id=study_id,
                seed=seed,
                app_version=app_version,
                manifest_sha256=manifest_sha256,
                simulated=False,
                created_at=_utcnow(),
                **values,
            )
        )
        return pid, True

    def get_participant(self, pid: str) -> dict | None:
        """The participant's record as a dict, or None if the id is unknown or malformed.

        Keys: participant_id, study_id, seed, created_at, completed_at (ISO 8601 UTC or
        None), completion_code, background (dict or None), prolific_pid,
        prolific_study_id, prolific_session_id, simulated, manifest_sha256, app_version.
        """
        if not isinstance(pid, str) or not PARTICIPANT_ID_RE.match(pid):
            return None
        with self.transaction(write=False) as conn:
            row = conn.execute(_PARTICIPANT, {"pid": pid}).mappings().first()
        return None if row is None else _participant_dict(row)

    def participants(self, *, include_simulated: bool = False) -> list[dict]:
        """Every participant (as :meth:`get_participant`) with ``n_responses``, oldest first."""
        n = (
            sa.select(sa.func.count())
            .where(responses.c.participant_id == participants.c.participant_id)
            .scalar_subquery()
            .label("n_responses")
        )
        query = sa.select(participants, n).order_by(
            participants.c.created_at, participants.c.participant_id
        )
        if not include_simulated:
            query = query.where(participants.c.simulated.is_(False))
        with self.transaction(write=False) as conn:
            rows = conn.execute(query).mappings().all()
        return [{**_participant_dict(r), "n_responses": int(r["n_responses"])} for r in rows]

    def set_background(self, pid: str, answers: dict) -> bool:
        """Store the background answers (``{"age_band", "gender", "experience", ...}``).

        The first answers stay (nothing stored is overwritten): a second call returns
        False and changes nothing. Unknown participant → :class:`StoreError`.
        """
        if not isinstance(answers, dict) or not all(isinstance(k, str) for k in answers):
            raise StoreError(f"background answers must be a dict with string keys, got {answers!r}")
        for key, value in answers.items():
            if not (
                value is None
                or isinstance(value, (str, int, float, bool))
                or (isinstance(value, list) and all(isinstance(v, str) for v in value))
            ):
                raise StoreError(
                    f"background answer {key!r} must be text, a number or a "
                    f"list of text, got {value!r}"
                )

        def work(conn) -> bool:
            if self._participant_row(conn, pid)["background"] is not None:
                return False
            conn.execute(
                participants.update()
                .where(participants.c.participant_id == pid)
                .values(background=dict(answers))
            )
            return True

        return self._write(work)

    def complete(self, pid: str, *, code: str | None = None) -> str:
        """Mark the participant done and return their completion code (idempotent).

        Parameters
        ----------
        code : str, optional
            The code to hand out (e.g. the study's Prolific completion code); default a
            fresh random 8-character code. Once completed, later calls return the stored
            code whatever ``code`` says.
        """
        if code is not None and (not isinstance(code, str) or not code or len(code) > 64):
            raise StoreError(f"completion code must be 1-64 characters, got {code!r}")
        new = code or "".join(
            secrets.choice(COMPLETION_ALPHABET) for _ in range(COMPLETION_CODE_LENGTH)
        )

        def work(conn) -> str:
            row = self._participant_row(conn, pid)
            if row["completed_at"] is not None:
                return row["completion_code"]
            conn.execute(
                participants.update()
                .where(participants.c.participant_id == pid)
                .where(participants.c.completed_at.is_(None))
                .values(completed_at=_utcnow(), completion_code=new)
            )
            return new

        return self._write(work)

    # -- responses ---------------------------------------------------------------------
    def record_response(
        self, pid: str, row: dict, *, with_events=(), at: datetime | None = None
    ) -> bool:
        """Append one trial's answer; False (and nothing changed) if that trial is stored.

        Parameters
        ----------
        pid : str
            Participant id.
        row : dict
            The trial fields of ``data_schema/response.schema.json``: ``trial_index``,
            ``task``, ``scene``, ``stimulus_id``, ``response_time_s`` and any of
            ``chosen_frame``, ``chosen_video_frame``, ``algorithm_frame``, ``fps``,
            ``n_frames``, ``chosen_method``, ``chosen_position``, ``shown_order``,
            ``chosen_value``, ``correct`` (frames in source numbering). The store adds
            participant, study, app version, manifest hash, simulated flag and time.
        with_events : iterable of (int, str, dict), optional
            ``(trial_index, kind, payload)`` events stored with the answer, in the same
            transaction, if the answer is new (e.g. the picker's log of this trial, the
            next trial's ``shown`` event).
        at : datetime, optional
            The time stored with the answer and its events (default: now, UTC).

        Returns
        -------
        bool
            True if stored, False if this participant already answered this trial (the
            first answer stays).

        Raises
        ------
        StoreError
            Unknown participant id, or a row that does not follow the schema (the
            message names the field). Nothing is written.
        """
        return self.record_responses(pid, [row], with_events=with_events, at=at) == 1

    def record_responses(
        self, pid: str, rows: list[dict], *, with_events=(), at: datetime | None = None
    ) -> int:
        """Append several trials of one participant in one transaction; return how many were new.

        Already-answered trials are skipped (their first answer stays). Every row is
        checked before anything is written. ``with_events`` (with one row only) and
        ``at`` as in :meth:`record_response`.
        """
        checked = [checked_response(r) for r in rows]
        indices = [r["trial_index"] for r in checked]
        if len(set(indices)) != len(indices):
            raise StoreError(f"participant {pid!r}: the same trial_index twice in one batch")
        with_events = list(with_events)
        if with_events and len(checked) != 1:
            raise StoreError("events go with one response at a time")
        event_rows = [checked_event(t, kind, payload) for t, kind, payload in with_events]
        if at is not None and (not isinstance(at, datetime) or at.tzinfo is None):
            raise StoreError(f"the time of an answer must be an aware datetime, got {at!r}")

        def work(conn) -> int:
            part = self._participant_row(conn, pid)
            stored = self._answered(conn, pid)
            new = [r for r in checked if r["trial_index"] not in stored]
            now = at or _utcnow()
            if new:
                conn.execute(
                    responses.insert(),
                    [
                        {
                            **r,
                            "participant_id": pid,
                            "created_at": now,
                            "app_version": part["app_version"],
                            "manifest_sha256": part["manifest_sha256"],
                        }
                        for r in new
                    ],
                )
                if event_rows:
                    conn.execute(
                        events.insert(),
                        [{**e, "participant_id": pid, "created_at": now} for e in event_rows],
                    )
            return len(new)

        attempt = 0
        while True:
            try:
                return self._write(work)
            except StoreError as err:
                # The same participant and trial sent by two requests at once (possible
                # on PostgreSQL, where readers do not wait): one insert hit the unique
                # key and rolled back. Retry: the answered-trials check now sees the
                # winner's row and skips it.
                if (
                    not isinstance(err.__cause__, sa_exc.IntegrityError)
                    or attempt == _DUPLICATE_RETRIES
                ):
                    raise
                attempt += 1

    @staticmethod
    def _answered(conn, pid: str) -> set[int]:
        return set(conn.execute(_ANSWERED, {"pid": pid}).scalars())

    def participant_state(self, pid: str) -> tuple[dict | None, set[int]]:
        """``(record, answered trial indices)`` of a participant, read together.

        What resuming a participant needs on every script run, in one transaction: the
        record as :meth:`get_participant` (None if the id is unknown or malformed, with
        an empty set) and the trial indices as :meth:`answered_trials`.
        """
        if not isinstance(pid, str) or not PARTICIPANT_ID_RE.match(pid):
            return None, set()
        with self.transaction(write=False) as conn:
            row = conn.execute(_PARTICIPANT, {"pid": pid}).mappings().first()
            if row is None:
                return None, set()
            return _participant_dict(row), self._answered(conn, pid)

    def answered_trials(self, pid: str) -> set[int]:
        """Trial indices this participant has answered (to resume at the first gap)."""
        with self.transaction(write=False) as conn:
            self._participant_row(conn, pid)
            return self._answered(conn, pid)

    def responses(self, pid: str) -> list[dict]:
        """This participant's stored responses (export rows), by trial index."""
        self._check_pid(pid)
        with self.transaction(write=False) as conn:
            self._participant_row(conn, pid)
            rows = (
                conn.execute(self._export_query().where(responses.c.participant_id == pid))
                .mappings()
                .all()
            )
        return [_export_row(r) for r in rows]

    # -- events ------------------------------------------------------------------------
    def record_event(
        self, pid: str, trial_index: int | None, kind: str, payload: dict | None = None
    ) -> None:
        """Append an interaction event (``kind`` like "play", "pause", "seek", "step").

        ``trial_index`` None is an event outside a trial (a page view); ``payload`` is
        any plain-JSON dict (no NaN/inf). Unknown participant → :class:`StoreError`.
        """
        self.record_events(pid, trial_index, [(kind, payload)])

    def record_events(
        self, pid: str, trial_index: int | None, items, *, limit: int | None = None
    ) -> int:
        """Append several events of one trial in one transaction; return how many.

        ``items``: ``(kind, payload)`` pairs, e.g. the picker's log of one trial. All are
        checked before anything is written. ``limit``: most events the trial may hold
        (counted in the same transaction); the items beyond it are dropped.
        """
        rows = [checked_event(trial_index, kind, payload) for kind, payload in items]
        if not rows:
            return 0
        if limit is not None and trial_index is None:
            raise StoreError("an event limit counts the events of one trial")
        now = _utcnow()

        def work(conn) -> int:
            self._participant_row(conn, pid)
            room = (
                len(rows)
                if limit is None
                else max(
                    0,
                    limit
                    - conn.execute(_TRIAL_EVENT_COUNT, {"pid": pid, "trial": trial_index}).scalar(),
                )
            )
            if room:
                conn.execute(
                    events.insert(),
                    [{**r, "participant_id": pid, "created_at": now} for r in rows[:room]],
                )
            return min(room, len(rows))

        return self._write(work)

    def first_event_or_record(
        self, pid: str, trial_index: int | None, kind: str, payload: dict | None = None
    ) -> datetime:
        """When the participant's first ``kind`` event of ``trial_index`` was stored (UTC);
        if there is none, store one now (with ``payload``) and return its time.

        One read when the event exists (a reload, a second tab); else one write
        transaction that inserts and reads back the earliest, so two tabs showing the
        trial at once agree on the first.
        """
        at = self.first_event_at(pid, trial_index, kind)
        if at is not None:
            return at
        row = checked_event(trial_index, kind, payload)

        def work(conn):
            self._participant_row(conn, pid)
            conn.execute(events.insert().values(participant_id=pid, created_at=_utcnow(), **row))
            return self._first_event(conn, pid, trial_index, kind)

        return _utc(self._write(work))

    def _first_event(self, conn, pid: str, trial_index: int | None, kind: str):
        if trial_index is not None:  # the common case: one statement, built once
            return conn.execute(
                _FIRST_EVENT, {"pid": self._check_pid(pid), "kind": kind, "trial": trial_index}
            ).scalar()
        return conn.execute(
            sa.select(sa.func.min(events.c.created_at)).where(
                events.c.participant_id == self._check_pid(pid),
                events.c.kind == kind,
                events.c.trial_index.is_(None),
            )
        ).scalar()

    def first_event_at(self, pid: str, trial_index: int | None, kind: str) -> datetime | None:
        """When the participant's first ``kind`` event of ``trial_index`` was stored (UTC),
        or None if there is none."""
        checked_event(trial_index, kind, None)
        with self.transaction(write=False) as conn:
            value = self._first_event(conn, pid, trial_index, kind)
        return _utc(value)

    def events(self, pid: str | None = None) -> list[dict]:
        """Stored events (all, or one participant's), oldest first."""
        with self.transaction(write=False) as conn:
            if pid is None:
                rows = conn.execute(sa.select(events).order_by(events.c.id)).mappings().all()
            else:
                rows = (
                    conn.execute(_PARTICIPANT_EVENTS, {"pid": self._check_pid(pid)})
                    .mappings()
                    .all()
                )
        return [
            {
                "participant_id": r["participant_id"],
                "trial_index": r["trial_index"],
                "kind": r["kind"],
                "payload": r["payload"],
                "created_at": _iso(r["created_at"]),
            }
            for r in rows
        ]

    # -- export and progress -----------------------------------------------------------
    @staticmethod
    def _export_query():
        return (
            sa.select(
                responses,
                participants.c.study_id,
                participants.c.simulated,
                participants.c.background,
                participants.c.prolific_pid,
            )
            .join(participants, responses.c.participant_id == participants.c.participant_id)
            .order_by(
                participants.c.created_at, responses.c.participant_id, responses.c.trial_index
            )
        )

    def export_rows(self, *, include_simulated: bool = False, validate: bool = False) -> list[dict]:
        """Every response as a ``response.schema.json`` row (background joined in).

        Ordered by participant (oldest first) then trial index. Every schema field is a
        key (``None`` where absent). ``validate=True`` checks each row against the
        schema (:func:`validate_rows`).
        """
        query = self._export_query()
        if not include_simulated:
            query = query.where(participants.c.simulated.is_(False))
        with self.transaction(write=False) as conn:
            rows = [_export_row(r) for r in conn.execute(query).mappings()]
        if validate:
            validate_rows(rows)
        return rows

    def progress(self, *, include_simulated: bool = False) -> dict:
        """Counts for the researcher page.

        ``{"participants", "completed", "responses", "by_task": {task: n}, "simulated"}``;
        the first four count real participants only unless ``include_simulated``;
        ``simulated`` is always the number of simulated participants.
        """
        p, r = participants, responses
        real = sa.true() if include_simulated else p.c.simulated.is_(False)
        with self.transaction(write=False) as conn:
            n_part = conn.execute(sa.select(sa.func.count()).select_from(p).where(real)).scalar()
            n_done = conn.execute(
                sa.select(sa.func.count()).select_from(p).where(real, p.c.completed_at.is_not(None))
            ).scalar()
            n_sim = conn.execute(
                sa.select(sa.func.count()).select_from(p).where(p.c.simulated.is_(True))
            ).scalar()
            by_task = dict(
                conn.execute(
                    sa.select(r.c.task, sa.func.count())
                    .select_from(r.join(p, r.c.participant_id == p.c.participant_id))
                    .where(real)
                    .group_by(r.c.task)
                ).all()
            )
        return {
            "participants": int(n_part),
            "completed": int(n_done),
            "responses": int(sum(by_task.values())),
            "by_task": {k: int(v) for k, v in sorted(by_task.items())},
            "simulated": int(n_sim),
        }


def _participant_dict(row) -> dict:
    return {
        "participant_id": row["participant_id"],
        "study_id": row["study_id"],
        "seed": int(row["seed"]),
        "created_at": _iso(row["created_at"]),
        "completed_at": _iso(row["completed_at"]),
        "completion_code": row["completion_code"],
        "background": row["background"],
        "prolific_pid": row["prolific_pid"],
        "prolific_study_id": row["prolific_study_id"],
        "prolific_session_id": row["prolific_session_id"],
        "simulated": bool(row["simulated"]),
        "manifest_sha256": row["manifest_sha256"],
        "app_version": row["app_version"],
    }


def _export_row(r) -> dict:
    out = {}
    for name in export_columns():
        if name in BACKGROUND_FIELDS:
            out[name] = _background_value((r["background"] or {}).get(name))
        elif name == "created_at":
            out[name] = _iso(r[name])
        elif name in ("simulated",):
            out[name] = bool(r[name])
        elif name == "correct":
            out[name] = None if r[name] is None else bool(r[name])
        else:
            out[name] = r[name]
    return out
