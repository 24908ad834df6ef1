"""The study database: its tables and its address (SQLAlchemy Core).

The schema of the study tables (participants, responses, events), of the two tables of
open-data housekeeping (withdrawals, study_secrets) and the parsing of a database URL.
The queries are in :mod:`study_app.data.store`, which documents the study tables and how
they are written; :mod:`study_app.data.withdraw` and :mod:`study_app.data.pseudonym` query
their own table; the backup's copies (:func:`copy_tables`, :func:`table_counts`) are
here too.
"""

from __future__ import annotations

import os
import re
from datetime import UTC, datetime
from pathlib import Path

import sqlalchemy as sa
from sqlalchemy import exc as sa_exc

from .errors import StoreError

__all__ = [
    "one_line",
    "standalone_sqlite",
    "move_sequences",
    "table_counts",
    "one_snapshot",
    "copy_tables",
    "table_names",
    "metadata",
    "participants",
    "responses",
    "events",
    "withdrawals",
    "study_secrets",
    "exclusions",
    "study_controls",
    "STUDY_TABLES",
    "PROLIFIC_INDEX",
    "add_missing_columns",
    "create_tables",
    "upgrade_columns",
    "default_url",
    "mask_url",
    "normalize_url",
    "configure_sqlite",
    "ensure_postgres_database",
    "SQLITE_BUSY_TIMEOUT_MS",
]

#: How long (ms) a SQLite writer waits for another writer's lock before giving up.
SQLITE_BUSY_TIMEOUT_MS = 30_000
#: A bare path with one of these suffixes is accepted as a SQLite database.
SQLITE_SUFFIXES = (".db", ".sqlite", ".sqlite3")

_ID = sa.String(64)
_TEXT = sa.String(200)


# ----------------------------------------------------------------------------- schema
metadata = sa.MetaData()

participants = sa.Table(
    "participants",
    metadata,
    sa.Column("participant_id", _ID, primary_key=True),
    sa.Column("study_id", _TEXT, nullable=False),
    sa.Column("seed", sa.BigInteger, nullable=False),
    sa.Column("prolific_pid", _TEXT),
    sa.Column("prolific_study_id", _TEXT),
    sa.Column("prolific_session_id", _TEXT),
    sa.Column("background", sa.JSON),
    sa.Column("app_version", _TEXT, nullable=False),
    sa.Column("manifest_sha256", sa.String(64), nullable=False),
    sa.Column("simulated", sa.Boolean, nullable=False, default=False),
    sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
    sa.Column("completed_at", sa.DateTime(timezone=True)),
    sa.Column("completion_code", sa.String(64)),
)

responses = sa.Table(
    "responses",
    metadata,
    sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
    sa.Column("participant_id", _ID, sa.ForeignKey("participants.participant_id"), nullable=False),
    sa.Column("trial_index", sa.Integer, nullable=False),
    sa.Column("task", sa.String(16), nullable=False),
    sa.Column("scene", _TEXT, nullable=False),
    sa.Column("stimulus_id", _TEXT, nullable=False),
    sa.Column("chosen_frame", sa.Integer),
    sa.Column("chosen_video_frame", sa.Integer),
    sa.Column("algorithm_frame", sa.Integer),
    sa.Column("fps", sa.Float),
    sa.Column("n_frames", sa.Integer),
    sa.Column("chosen_method", sa.String(32)),
    sa.Column("chosen_position", sa.Integer),
    sa.Column("shown_order", sa.JSON),
    sa.Column("chosen_value", sa.Text),
    sa.Column("correct", sa.Boolean),
    sa.Column("response_time_s", sa.Float, nullable=False),
    sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
    sa.Column("app_version", _TEXT, nullable=False),
    sa.Column("manifest_sha256", sa.String(64), nullable=False),
    # What the answer was given on and how (issue 29); NULL in rows of older versions.
    sa.Column("picked_with", sa.String(16)),
    sa.Column("watched", sa.Float),
    sa.Column("viewport_width", sa.Integer),
    sa.Column("viewport_height", sa.Integer),
    sa.Column("device_pixel_ratio", sa.Float),
    sa.Column("input_type", sa.String(16)),
    sa.Column("active_time_s", sa.Float),
    sa.Column("tab_id", sa.String(32)),
    # The guarantee that a re-sent answer cannot become a second row.
    sa.UniqueConstraint("participant_id", "trial_index", name="uq_responses_participant_trial"),
)

events = sa.Table(
    "events",
    metadata,
    sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
    sa.Column("participant_id", _ID, sa.ForeignKey("participants.participant_id"), nullable=False),
    sa.Column("trial_index", sa.Integer),
    sa.Column("kind", sa.String(32), nullable=False),
    sa.Column("payload", sa.JSON),
    sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
)
sa.Index("ix_events_participant", events.c.participant_id, events.c.trial_index)
#: A participant who withdrew: their rows are gone, this says when, who asked and how.
#: It keeps the ids (the link id, so that the link can say the data were withdrawn; the
#: Prolific id, so that a returning Prolific participant is not enrolled again) and
#: nothing they answered. No foreign key: the participant's row no longer exists.
withdrawals = sa.Table(
    "withdrawals",
    metadata,
    sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
    sa.Column("participant_id", _ID, nullable=False, unique=True),
    sa.Column("study_id", _TEXT, nullable=False),
    sa.Column("prolific_pid", _TEXT),
    sa.Column("requested_by", sa.String(16), nullable=False),
    sa.Column("withdrawn_at", sa.DateTime(timezone=True), nullable=False),
    # A finisher's code and finishing time, kept for payment only (issue 37): someone
    # who finished and then withdrew is still owed; NULL for the others.
    sa.Column("completion_code", sa.String(64)),
    sa.Column("completed_at", sa.DateTime(timezone=True)),
)
sa.Index("ix_withdrawals_prolific", withdrawals.c.study_id, withdrawals.c.prolific_pid)

#: The per-study key of the pseudonyms in exports (study_app.data.pseudonym). Backed up with
#: the rest (a restored database pseudonymises exactly as before), never exported.
study_secrets = sa.Table(
    "study_secrets",
    metadata,
    sa.Column("study_id", _TEXT, primary_key=True),
    sa.Column("secret", sa.String(64), nullable=False),
    sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
    # When `snapshot anonymise` destroyed the secret (then the empty string); NULL before.
    sa.Column("anonymised_at", sa.DateTime(timezone=True)),
)

#: A participant the researcher excluded from the analysis (an attention failure, a
#: bot...): their data stay, with the reason. No foreign key, like withdrawals: a
#: withdrawal deletes the participant and this row with them (study_app.data.monitor).
exclusions = sa.Table(
    "exclusions",
    metadata,
    sa.Column("participant_id", _ID, primary_key=True),
    sa.Column("study_id", _TEXT, nullable=False),
    sa.Column("reason", sa.String(500), nullable=False),
    sa.Column("excluded_at", sa.DateTime(timezone=True), nullable=False),
)

#: Recruitment switches of a study (study_app.data.monitor): closed to new
#: participants, and a cap on how many may start. One row per study, absent = open.
study_controls = sa.Table(
    "study_controls",
    metadata,
    sa.Column("study_id", _TEXT, primary_key=True),
    sa.Column("closed", sa.Boolean, nullable=False, default=False),
    sa.Column("cap", sa.Integer),
    sa.Column("updated_at", sa.DateTime(timezone=True), nullable=False),
)

#: The tables a study database must have; the others are added to an older database
#: when it is opened (never dropped or altered).
STUDY_TABLES = ("participants", "responses", "events")

#: One Prolific id, one participant per study: a returning participant resumes their
#: record from any browser (NULLs, i.e. no Prolific id, do not collide).
PROLIFIC_INDEX = sa.Index(
    "uq_participants_study_prolific",
    participants.c.study_id,
    participants.c.prolific_pid,
    unique=True,
)


# ----------------------------------------------------------------------------- URLs
def default_url() -> str:
    """``$SNAPSHOT_DB`` if set, else SQLite at ``<repo>/var/study.db`` (repo = parent of study_app)."""
    env = os.environ.get("SNAPSHOT_DB", "").strip()
    if env:
        return env
    path = Path(__file__).resolve().parents[2] / "var" / "study.db"
    return f"sqlite:///{path}"


_PASSWORD_RE = re.compile(r"(://[^:/@\s]*:)[^@\s]*@")


def mask_url(url) -> str:
    """The URL with its password replaced by ``***`` (works on unparsable strings too)."""
    try:
        return sa.engine.make_url(url).render_as_string(hide_password=True)
    except Exception:  # noqa: BLE001 - any unparsable text: mask by pattern
        return _PASSWORD_RE.sub(r"\1***@", str(url))


def normalize_url(url: str | None) -> sa.engine.URL:
    """Parse a database URL; ``None`` → :func:`default_url`; ``postgresql://`` → psycopg.

    A bare file path ending in ``.db``, ``.sqlite`` or ``.sqlite3`` is taken as a SQLite
    database file.
    """
    text = default_url() if url is None else str(url).strip()
    if not text:
        raise StoreError("empty database URL")
    if "://" not in text and Path(text).suffix.lower() in SQLITE_SUFFIXES:
        text = f"sqlite:///{Path(text).expanduser().resolve()}"
    try:
        parsed = sa.engine.make_url(text)
    except sa_exc.ArgumentError:
        raise StoreError(
            f"{mask_url(text)}: not a database URL "
            "(expected e.g. sqlite:///path/study.db or "
            "postgresql+psycopg://user@host/db)"
        ) from None
    if parsed.drivername in ("postgresql", "postgres"):
        parsed = parsed.set(drivername="postgresql+psycopg")
    return parsed


def one_line(err: BaseException) -> str:
    """A database error as one line: the driver's message, without SQLAlchemy's echo of
    the statement and its parameters."""
    orig = getattr(err, "orig", None) or err
    text = str(orig).split("\n[SQL:")[0]
    return " ".join(text.split()) or type(orig).__name__


def standalone_sqlite(dbapi_conn) -> None:
    """Make a SQLite file a standalone copy: a rollback journal, no WAL beside it (the
    app's databases run in WAL mode, see :func:`configure_sqlite`)."""
    dbapi_conn.execute("PRAGMA journal_mode = DELETE")


def move_sequences(conn) -> None:
    """Set each serial id's PostgreSQL sequence past the ids in its table. Rows copied
    in with explicit ids (a restore) leave the sequences behind, and the app's next
    insert would collide."""
    for table in metadata.sorted_tables:
        for col in table.primary_key.columns:
            if col.autoincrement is True or (
                isinstance(col.type, sa.Integer) and col.autoincrement == "auto"
            ):
                conn.execute(
                    sa.text(
                        f"SELECT setval(pg_get_serial_sequence('{table.name}', '{col.name}'), "
                        f"COALESCE(MAX({col.name}), 1), MAX({col.name}) IS NOT NULL) "
                        f"FROM {table.name}"
                    )
                )


#: Rows per INSERT batch when :func:`copy_tables` copies a table.
COPY_CHUNK = 1000


def _utc(value):
    """A timestamp as an aware UTC datetime (SQLite hands naive UTC ones back): a copy
    must not depend on the server's or the session's time zone."""
    if isinstance(value, datetime):
        return value.replace(tzinfo=UTC) if value.tzinfo is None else value.astimezone(UTC)
    return value


def table_counts(engine) -> dict[str, int]:
    """Rows per study table present in the database."""
    with engine.connect() as conn:
        present = set(sa.inspect(conn).get_table_names())
        return {
            t.name: int(conn.execute(sa.select(sa.func.count()).select_from(t)).scalar())
            for t in metadata.sorted_tables
            if t.name in present
        }


def one_snapshot(conn):
    """``conn`` reading every table from one snapshot (PostgreSQL: a read-only
    repeatable-read transaction, which never blocks the app's writers; SQLite's one
    transaction is a snapshot already)."""
    if conn.dialect.name == "postgresql":
        return conn.execution_options(isolation_level="REPEATABLE READ", postgresql_readonly=True)
    return conn


def table_names(conn) -> set[str]:
    """The tables a database holds (a backup may predate some of the study's tables)."""
    return set(sa.inspect(conn).get_table_names())


def copy_tables(src_conn, dst_conn, names) -> dict[str, int]:
    """Copy the study tables named in ``names`` row for row, ids included, parents before
    children (foreign keys); return rows per table."""
    rows = {}
    for table in metadata.sorted_tables:
        if table.name not in names:
            continue
        n = 0
        result = src_conn.execute(sa.select(table).order_by(*table.primary_key.columns))
        while chunk := result.mappings().fetchmany(COPY_CHUNK):
            dst_conn.execute(table.insert(), [{k: _utc(v) for k, v in r.items()} for r in chunk])
            n += len(chunk)
        rows[table.name] = n
    return rows


def ensure_postgres_database(*, host: str, port: int, user: str, password: str, name: str) -> None:
    """Create the database ``name`` on a PostgreSQL server unless it exists.

    Parameters
    ----------
    host, port, user, password
        How to reach the server (its maintenance database ``postgres``).
    name : str
        The database to create (the replicas' ``study``).
    """
    import psycopg

    with psycopg.connect(
        host=host, port=port, user=user, password=password, dbname="postgres", autocommit=True
    ) as conn:
        if not conn.execute("SELECT 1 FROM pg_database WHERE datname = %s", (name,)).fetchone():
            conn.execute(f'CREATE DATABASE "{name}"')


def configure_sqlite(engine: sa.engine.Engine) -> None:
    """WAL, busy timeout, foreign keys; ``BEGIN IMMEDIATE`` for write transactions."""

    @sa.event.listens_for(engine, "connect")
    def _on_connect(dbapi_conn, _record):
        # Let SQLAlchemy's "begin" event emit BEGIN itself (pysqlite would defer it).
        dbapi_conn.isolation_level = None
        cur = dbapi_conn.cursor()
        cur.execute(f"PRAGMA busy_timeout = {SQLITE_BUSY_TIMEOUT_MS}")
        cur.execute("PRAGMA foreign_keys = ON")
        cur.execute("PRAGMA journal_mode = WAL")
        # synchronous stays FULL (the default): a committed answer survives power loss.
        cur.close()

    @sa.event.listens_for(engine, "begin")
    def _on_begin(conn):
        # A deferred transaction that reads and then writes cannot wait for a
        # concurrent writer (SQLITE_BUSY at once); IMMEDIATE takes the write lock first
        # and waits on the busy timeout.
        immediate = conn.get_execution_options().get("snapshot_write", False)
        conn.exec_driver_sql("BEGIN IMMEDIATE" if immediate else "BEGIN")


def add_missing_columns(engine) -> list[str]:
    """Add the nullable columns a study table of an older version lacks (``ALTER TABLE
    ... ADD COLUMN``; nothing is dropped or changed); return ``table.column`` added."""
    added = []
    with engine.begin() as conn:
        present = set(sa.inspect(conn).get_table_names())
        for table in metadata.sorted_tables:
            if table.name not in present:
                continue
            have = {c["name"] for c in sa.inspect(conn).get_columns(table.name)}
            for col in table.columns:
                if col.name in have or not col.nullable:
                    continue
                kind = col.type.compile(dialect=conn.dialect)
                conn.execute(sa.text(f"ALTER TABLE {table.name} ADD COLUMN {col.name} {kind}"))
                added.append(f"{table.name}.{col.name}")
    return added


def create_tables(engine) -> None:
    """Create the tables a database lacks (the columns: :func:`upgrade_columns`)."""
    try:
        metadata.create_all(engine, checkfirst=True)
    except (sa_exc.IntegrityError, sa_exc.ProgrammingError):
        # Two processes creating the same tables at once (PostgreSQL): the loser
        # retries and now finds them.
        metadata.create_all(engine, checkfirst=True)


def upgrade_columns(engine) -> list[str]:
    """:func:`add_missing_columns`, once more if another process added one meanwhile."""
    try:
        return add_missing_columns(engine)
    except (sa_exc.ProgrammingError, sa_exc.OperationalError):
        return add_missing_columns(engine)
