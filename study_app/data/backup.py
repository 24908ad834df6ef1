"""Backups of the study database while the app runs, and their restore.

A backup is one consistent copy: every transaction committed before it started is in
it, none that started after it, and nothing half-written (each answer, batch of events
or withdrawal is one transaction, and the copy is read from one snapshot).

Methods (``method=``):

``native``
    SQLite: the online backup API (:meth:`sqlite3.Connection.backup`, all pages in one
    step under one read lock; WAL lets the app keep writing meanwhile). PostgreSQL:
    ``pg_dump --format=custom`` (one repeatable-read snapshot), when ``pg_dump`` is
    installed (``/usr/lib/postgresql/*/bin`` or ``PATH``).
``logical``
    Any database: every table of :data:`study_app.data.database.metadata` read in one
    read-only snapshot transaction (repeatable read on PostgreSQL) and written through
    SQLAlchemy into a new SQLite file with the same schema.
``auto``
    ``native`` when it is available, else ``logical`` (PostgreSQL without ``pg_dump``,
    or a ``pg_dump`` older than the server).

The backup file is therefore a SQLite database (``snapshot export --db FILE`` reads it
as it is) or a ``pg_dump`` archive. :func:`restore` loads either into an *empty*
database: a SQLite backup into any database (rows copied table by table in one
transaction, ids kept, PostgreSQL sequences moved past them), a ``pg_dump`` archive
into PostgreSQL with ``pg_restore``. The pseudonym secrets (``study_secrets``) are part
of the backup, so a restored database exports the same pseudonyms.
"""

from __future__ import annotations

import glob
import os
import secrets
import shutil
import subprocess
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import sqlalchemy as sa
from sqlalchemy import exc as sa_exc

from .database import (
    STUDY_TABLES,
    copy_tables,
    metadata,
    move_sequences,
    normalize_url,
    one_line,
    one_snapshot,
    table_counts,
    table_names,
    upgrade_columns,
)
from .database import _utc as _as_utc
from .errors import StoreError
from .withdrawal_log import (
    BACKUP_LOG_NAME,
    LOG_ENV,
    log_path,
    merge_into,
    read_anonymised,
    read_log,
)

__all__ = [
    "BACKUP_METHODS",
    "BackupResult",
    "backup",
    "restore",
    "verify_backup",
    "find_pg_tool",
    "table_counts",
]

#: Values of ``method``.
BACKUP_METHODS = ("auto", "native", "logical")
#: The first bytes of each kind of backup file.
_SQLITE_MAGIC = b"SQLite format 3\x00"
_PGDUMP_MAGIC = b"PGDMP"
#: Seconds a pg_dump / pg_restore run may take.
_PG_TIMEOUT_S = 600


@dataclass
class BackupResult:
    """What :func:`backup` or :func:`restore` did.

    Attributes
    ----------
    path : Path
        The backup file.
    method : str
        ``"sqlite-backup"``, ``"pg_dump"``, ``"logical"`` (backup) or ``"pg_restore"``,
        ``"logical"`` (restore).
    rows : dict of str to int
        Rows per table in the copy (empty for ``pg_dump``/``pg_restore``, whose
        archive is not read here).
    """

    path: Path
    method: str
    rows: dict = field(default_factory=dict)
    #: Participants whose later withdrawal a restore re-applied (``withdrawals_from``).
    withdrawn: list = field(default_factory=list)
    #: Studies whose secret a restore destroyed again (anonymised after the backup).
    anonymised: list = field(default_factory=list)


def find_pg_tool(name: str) -> Path | None:
    """``pg_dump``/``pg_restore``: the newest ``/usr/lib/postgresql/*/bin`` one, else PATH."""

    def version(p: str) -> list[int]:
        return [int(t) for t in Path(p).parent.parent.name.split(".") if t.isdigit()]

    for path in sorted(glob.glob(f"/usr/lib/postgresql/*/bin/{name}"), key=version, reverse=True):
        if os.access(path, os.X_OK):
            return Path(path)
    found = shutil.which(name)
    return Path(found) if found else None


def _store(url):
    from .store import Store

    # Store opens with the project's settings (SQLite pragmas, timeouts) and turns a
    # bad URL into one line; the tables are created only where create=True.
    return Store(url, create=False)


def _tmp_beside(path: Path) -> Path:
    return path.with_name(f".{path.name}.{secrets.token_hex(4)}.tmp")


def _check_output(output, force: bool) -> Path:
    path = Path(output)
    if path.exists() and not force:
        raise StoreError(f"{path} already exists (give another name, or --force to replace it)")
    if not path.parent.is_dir():
        raise StoreError(f"{path}: folder {path.parent} does not exist")
    return path


# ----------------------------------------------------------------------------- backup
def backup(url, output, *, method: str = "auto", force: bool = False) -> BackupResult:
    """Copy the database at ``url`` into the file ``output``, consistently, while it is used.

    Parameters
    ----------
    url : str
        Database URL (or a SQLite file path).
    output : str or Path
        The backup file, written atomically (a temp file renamed into place).
    method : {"auto", "native", "logical"}
        See the module notes.
    force : bool
        Replace an existing ``output``.

    Raises
    ------
    StoreError
        Unknown method, output exists or its folder does not, the database cannot be
        read, or ``pg_dump`` fails (its first error line).
    """
    if method not in BACKUP_METHODS:
        raise StoreError(f"unknown backup method {method!r} (expected {', '.join(BACKUP_METHODS)})")
    path = _check_output(output, force)
    parsed = normalize_url(url)
    dialect = parsed.get_backend_name()
    tmp = _tmp_beside(path)
    try:  # the output's folder is tried first: its failure is not the database's
        tmp.touch(exist_ok=False)
    except OSError as err:
        raise StoreError(f"cannot write the backup {path}: {err.strerror or err}") from None
    try:
        store = _store(url)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    engine = store.engine
    try:
        if dialect == "sqlite" and method in ("auto", "native"):
            result = _sqlite_backup(store, tmp)
        elif dialect == "postgresql" and method in ("auto", "native"):
            tool = find_pg_tool("pg_dump")
            dumped = None
            if tool is None and method == "native":
                raise StoreError(
                    "pg_dump is not installed (install postgresql-client, or use --method logical)"
                )
            if tool is not None:
                dumped = _pg_dump(tool, parsed, tmp, fallback=method == "auto")
            result = dumped if dumped is not None else _logical_backup(engine, tmp)
        elif dialect not in ("sqlite", "postgresql") and method == "native":
            raise StoreError(f"no native backup for {dialect} databases (use --method logical)")
        else:
            result = _logical_backup(engine, tmp)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    finally:
        store.close()
    result.path = path
    _list_withdrawals_beside(url, path)
    return result


def _list_withdrawals_beside(url, path: Path) -> None:
    """Merge the database's withdrawals into ``withdrawals.jsonl`` beside the backup,
    so that a folder of backups carries every withdrawal up to its newest backup."""
    beside = path.parent / BACKUP_LOG_NAME
    try:
        merge_into(beside, _withdrawal_records(url))
    except StoreError as err:
        warnings.warn(f"the backup is made, but {err}", stacklevel=3)


def _sqlite_backup(store, tmp: Path) -> BackupResult:
    store.copy_sqlite(tmp)
    eng = sa.create_engine(f"sqlite:///{tmp}")
    try:
        rows = table_counts(eng)
    finally:
        eng.dispose()
    return BackupResult(tmp, "sqlite-backup", rows)


def _libpq(parsed) -> tuple[str, dict]:
    """A libpq connection string for the URL, and the environment with its password
    (never on the command line, where other users could read it)."""
    from psycopg.conninfo import make_conninfo

    params = {
        "host": parsed.host,
        "port": parsed.port,
        "user": parsed.username,
        "dbname": parsed.database,
    }
    params.update({k: v for k, v in parsed.query.items() if isinstance(v, str)})
    env = dict(os.environ)
    if parsed.password is not None:
        env["PGPASSWORD"] = str(parsed.password)
    return make_conninfo(**{k: v for k, v in params.items() if v is not None}), env


def _first_error(text: str) -> str:
    lines = [ln.strip() for ln in text.splitlines() if ln.strip()]
    return next((ln for ln in lines if "error" in ln.lower()), lines[0] if lines else "failed")


def _pg_dump(tool: Path, parsed, tmp: Path, *, fallback: bool) -> BackupResult | None:
    conninfo, env = _libpq(parsed)
    proc = subprocess.run(
        [
            str(tool),
            "--format=custom",
            "--no-owner",
            "--no-privileges",
            f"--file={tmp}",
            f"--dbname={conninfo}",
        ],
        capture_output=True,
        text=True,
        env=env,
        timeout=_PG_TIMEOUT_S,
    )
    if proc.returncode == 0:
        return BackupResult(tmp, "pg_dump")
    message = _first_error(proc.stderr)
    if fallback and "version mismatch" in proc.stderr:
        warnings.warn(f"{tool}: {message}; taking a logical copy instead", stacklevel=3)
        tmp.unlink(missing_ok=True)
        return None
    raise StoreError(f"pg_dump failed: {message}")


def _logical_backup(engine, tmp: Path) -> BackupResult:
    dst = sa.create_engine(f"sqlite:///{tmp}")
    try:
        metadata.create_all(dst)
        src_conn = engine.connect()
        try:
            src_conn = one_snapshot(src_conn)
            with src_conn.begin(), dst.begin() as dst_conn:
                names = table_names(src_conn)
                rows = copy_tables(src_conn, dst_conn, names)
        finally:
            src_conn.close()
    except sa_exc.SQLAlchemyError as err:
        raise StoreError(f"cannot copy the database: {one_line(err)}") from None
    finally:
        dst.dispose()
    return BackupResult(tmp, "logical", rows)


# ----------------------------------------------------------------------------- restore
def _kind(path: Path) -> str:
    try:
        with open(path, "rb") as f:
            head = f.read(len(_SQLITE_MAGIC))
    except OSError as err:
        raise StoreError(f"cannot read {path}: {err.strerror or err}") from None
    if head.startswith(_SQLITE_MAGIC):
        return "sqlite"
    if head.startswith(_PGDUMP_MAGIC):
        return "pg_dump"
    raise StoreError(f"{path}: not a backup (neither a SQLite file nor a pg_dump archive)")


def _first_problem(report) -> str:
    """The first problem of an integrity report, as one short line (SQLite may give
    one row per problem, or one row of many lines, headed ``*** in database main ***``)."""
    lines = [ln.strip() for row in report for ln in str(row).splitlines() if ln.strip()]
    lines = [ln for ln in lines if not ln.startswith("***")] or lines or ["unknown"]
    more = f"; {len(lines) - 1} more problems" if len(lines) > 1 else ""
    return lines[0][:200] + more


def verify_backup(backup_file) -> BackupResult:
    """Check that a backup file can be restored, without restoring it.

    A SQLite backup: ``PRAGMA integrity_check`` and ``foreign_key_check`` pass, the
    study tables are there, and every study with participants has its pseudonym secret
    (else its exports would get new pseudonyms). A ``pg_dump`` archive: ``pg_restore
    --list`` reads its table of contents.

    Returns
    -------
    BackupResult
        ``method`` ``"sqlite"`` or ``"pg_dump"``; ``rows`` per table (SQLite).

    Raises
    ------
    StoreError
        Naming the file and the first problem found.
    """
    path = Path(backup_file)
    if not path.is_file():
        raise StoreError(f"{path}: no such backup file")
    if _kind(path) == "pg_dump":
        tool = find_pg_tool("pg_restore")
        if tool is None:
            raise StoreError("pg_restore is not installed (install postgresql-client)")
        proc = subprocess.run(
            [str(tool), "--list", str(path)], capture_output=True, text=True, timeout=_PG_TIMEOUT_S
        )
        if proc.returncode != 0:
            raise StoreError(
                f"{path}: not a readable pg_dump archive ({_first_error(proc.stderr)})"
            )
        return BackupResult(path, "pg_dump")
    import sqlite3

    try:
        # Read-only: verifying must not change the file (no journal, no new tables).
        con = sqlite3.connect(f"file:{path.resolve()}?mode=ro", uri=True)
        try:
            bad = [r[0] for r in con.execute("PRAGMA integrity_check")]
            if bad != ["ok"]:
                raise StoreError(f"{path}: damaged SQLite file ({_first_problem(bad)})")
            names = {r[0] for r in con.execute("SELECT name FROM sqlite_master WHERE type='table'")}
            missing = [t for t in STUDY_TABLES if t not in names]
            if missing:
                raise StoreError(f"{path}: not a study backup ({', '.join(missing)} missing)")
            orphans = con.execute("PRAGMA foreign_key_check").fetchall()
            if orphans:
                raise StoreError(
                    f"{path}: {len(orphans)} rows refer to missing rows (first in "
                    f"table {orphans[0][0]})"
                )
            rows = {
                t: con.execute(f'SELECT count(*) FROM "{t}"').fetchone()[0]
                for t in (t.name for t in metadata.sorted_tables)
                if t in names
            }
            if "study_secrets" in names:
                keyless = [
                    r[0]
                    for r in con.execute(
                        "SELECT DISTINCT study_id FROM participants WHERE study_id NOT IN "
                        "(SELECT study_id FROM study_secrets)"
                    )
                ]
                if keyless:
                    raise StoreError(
                        f"{path}: no pseudonym secret for study "
                        f"{', '.join(map(repr, keyless))} (its exports from this "
                        "backup would get new pseudonyms)"
                    )
        finally:
            con.close()
    except sqlite3.Error as err:
        raise StoreError(f"{path}: damaged SQLite file ({_first_problem([str(err)])})") from None
    return BackupResult(path, "sqlite", rows)


def _withdrawal_records(url) -> list[dict]:
    """The withdrawal records of the database (or SQLite backup) at ``url``, and one
    ``{"study_id", "anonymised_at"}`` record per study whose secret was destroyed."""
    from .anonymise import anonymised_studies
    from .database import withdrawals
    from .store import Store

    with Store(url, create=False) as src:
        with src.transaction(write=False) as conn:
            if not sa.inspect(conn).has_table("withdrawals"):
                return []
            out = [
                {k: _as_utc(v) for k, v in r.items() if k != "id"}
                for r in conn.execute(sa.select(withdrawals)).mappings()
            ]
        gone = anonymised_studies(src) if sa.inspect(src.engine).has_table("study_secrets") else {}
    return out + [{"study_id": sid, "anonymised_at": at} for sid, at in sorted(gone.items())]


def _reapply(conn, records) -> list[str]:
    """Delete the data of every participant of ``records`` that the restored rows hold,
    and copy their withdrawal records; return their link ids."""
    from .database import events, exclusions, participants, responses, withdrawals

    ids = [r["participant_id"] for r in records]
    present = set(
        conn.execute(
            sa.select(participants.c.participant_id).where(participants.c.participant_id.in_(ids))
        ).scalars()
    )
    known = set(
        conn.execute(
            sa.select(withdrawals.c.participant_id).where(withdrawals.c.participant_id.in_(ids))
        ).scalars()
    )
    done = []
    for rec in records:
        pid = rec["participant_id"]
        if pid in present:
            for table in (responses, events, exclusions, participants):
                conn.execute(table.delete().where(table.c.participant_id == pid))
            done.append(pid)
        if pid not in known:
            conn.execute(withdrawals.insert().values({k: v for k, v in rec.items() if k != "id"}))
    return done


def _records_of(source) -> list[dict]:
    """The withdrawal records of a source: a withdrawal log (JSON lines), a database
    URL, or a SQLite backup."""
    text = str(source)
    candidate = Path(text).expanduser()
    if "://" not in text and candidate.is_file():
        try:
            with open(candidate, "rb") as f:
                head = f.read(len(_SQLITE_MAGIC))
        except OSError as err:
            raise StoreError(f"cannot read {candidate}: {err.strerror or err}") from None
        if head.startswith(_PGDUMP_MAGIC):
            raise StoreError(
                f"{candidate}: a pg_dump archive cannot give withdrawals (restore it into "
                "a database and give that database's URL)"
            )
        if not head.startswith(_SQLITE_MAGIC):
            return read_log(candidate) + [
                {"study_id": sid, "anonymised_at": at}
                for sid, at in read_anonymised(candidate).items()
            ]
    elif "://" not in text and candidate.suffix.lower() == ".jsonl":
        raise StoreError(f"{candidate}: no such withdrawal log")
    return _withdrawal_records(source)


def _unique(records) -> list[dict]:
    """One withdrawal per participant, one anonymisation per study (the first given)."""
    seen, out = set(), []
    for r in records:
        key = ("p", r["participant_id"]) if r.get("participant_id") else ("s", r["study_id"])
        if key not in seen:
            seen.add(key)
            out.append(r)
    return out


def restore(
    backup_file, url, *, withdrawals_from=None, without_withdrawal_log: bool = False
) -> BackupResult:
    """Load a backup made by :func:`backup` into the empty database at ``url``, with
    every withdrawal made since.

    A backup predates the withdrawals made after it. They are taken from the
    withdrawal log (:mod:`study_app.data.withdrawal_log`) of the target (restoring in
    place, or ``$SNAPSHOT_WITHDRAWAL_LOG``), from ``withdrawals.jsonl`` beside the
    backup, and from ``withdrawals_from``, and applied in the restore's transaction;
    the target's log then holds them all.

    Parameters
    ----------
    backup_file : str or Path
        A SQLite backup (restores into any database) or a ``pg_dump`` archive
        (PostgreSQL only, with ``pg_restore``).
    url : str
        The target. Its study tables must be absent or empty: a restore never mixes
        with, or replaces, data already there.
    withdrawals_from : str or list of str, optional
        More sources of withdrawals: a withdrawal log (the lost database's), the
        database the backup was taken from, or any later backup of it.
    without_withdrawal_log : bool
        Restore even when no log made after the backup is found (the researcher
        vouches that nobody withdrew since, or accepts it).

    Raises
    ------
    StoreError
        Not a backup, a target that holds rows, a ``pg_dump`` archive for a database
        that is not PostgreSQL, no withdrawal log (and no waiver), or a failed copy
        (nothing is left half-restored: the copy is one transaction).
    """
    from .store import Store

    path = Path(backup_file)
    if not path.is_file():
        raise StoreError(f"{path}: no such backup file")
    kind = _kind(path)
    target = normalize_url(url)
    if kind == "pg_dump" and target.get_backend_name() != "postgresql":
        raise StoreError(
            f"{path} is a pg_dump archive: it restores only into PostgreSQL, "
            f"not {target.get_backend_name()}"
        )
    verify_backup(path)  # a damaged backup is named before the target is touched
    sources = (
        []
        if withdrawals_from is None
        else [withdrawals_from]
        if isinstance(withdrawals_from, str | Path)
        else list(withdrawals_from)
    )
    _refuse_held(url, target)
    target_log = log_path(target)
    if not sources and not target_log.exists() and not without_withdrawal_log:
        raise StoreError(
            f"{path}: withdrawals made after this backup are unknown (no withdrawal log "
            f"{target_log}); give --withdrawals-from the lost database's log (beside it as "
            f"<db>.withdrawals.jsonl, or ${LOG_ENV}), its database or a later backup, "
            "or --without-withdrawal-log to restore anyway"
        )
    known = [r for src in sources for r in _records_of(src)]
    for extra in (target_log, path.parent / BACKUP_LOG_NAME):
        if extra.is_file():
            known += _records_of(extra)
    known = _unique(known)
    records = [r for r in known if r.get("participant_id")]
    anonymised = {r["study_id"]: r["anonymised_at"] for r in known if not r.get("participant_id")}
    new_file = None
    if target.get_backend_name() == "sqlite" and target.database not in (None, "", ":memory:"):
        new_file = None if Path(target.database).exists() else Path(target.database)
    # The tables are made here (empty) for either kind: pg_restore --clean replaces them.
    store = Store(url)
    try:
        result = _restore_into(store, path, kind, target, records)
        if anonymised:  # a backup made before `snapshot anonymise` brought a secret back
            from .anonymise import reapply_anonymisations

            result.anonymised = [
                a.study_id for a in reapply_anonymisations(store, anonymised) if not a.already
            ]
    except BaseException:
        store.close()
        if new_file is not None:  # a failed restore leaves no empty database behind
            for suffix in ("", "-wal", "-shm", "-journal"):
                Path(f"{new_file}{suffix}").unlink(missing_ok=True)
        raise
    store.close()
    # The restored database's log holds every withdrawal (and anonymisation) it knows
    # of, from here on.
    merge_into(target_log, _unique([*_withdrawal_records(url), *known]))
    return result


def _held_error(url, counts) -> StoreError | None:
    held = {t: n for t, n in counts.items() if n}
    if not held:
        return None
    return StoreError(
        f"database {url} already holds data ("
        + ", ".join(f"{n} {t}" for t, n in held.items())
        + "); restore only into an empty database"
    )


def _refuse_held(url, target) -> None:
    """Refuse, before anything else is asked or made, a target that holds rows."""
    if target.get_backend_name() == "sqlite" and (
        target.database in (None, "", ":memory:") or not Path(target.database).exists()
    ):
        return
    engine = sa.create_engine(target)
    try:
        err = _held_error(target.render_as_string(hide_password=True), table_counts(engine))
    except sa_exc.SQLAlchemyError:
        return  # unreachable or odd: opening the store names the problem
    finally:
        engine.dispose()
    if err is not None:
        raise err


def _restore_into(store, path, kind, target, records) -> BackupResult:
    """Refuse a target with rows, then load the backup (and the later withdrawals)."""
    counts = table_counts(store.engine)
    err = _held_error(store.url, counts)
    if err is not None:
        raise err
    if kind == "pg_dump":
        result = _pg_restore(path, target, clean=bool(counts))
        upgrade_columns(store.engine)  # an archive of an older version lacks new columns
        if records:
            with store.transaction(write=True) as conn:
                result.withdrawn = _reapply(conn, records)
        return result
    return _logical_restore(path, store, records)


def _pg_restore(path: Path, target, *, clean: bool) -> BackupResult:
    tool = find_pg_tool("pg_restore")
    if tool is None:
        raise StoreError("pg_restore is not installed (install postgresql-client)")
    conninfo, env = _libpq(target)
    # --clean only replaces the empty tables checked above.
    args = [
        str(tool),
        "--no-owner",
        "--no-privileges",
        "--single-transaction",
        "--exit-on-error",
        f"--dbname={conninfo}",
        str(path),
    ]
    if clean:
        args[1:1] = ["--clean", "--if-exists"]
    proc = subprocess.run(args, capture_output=True, text=True, env=env, timeout=_PG_TIMEOUT_S)
    if proc.returncode != 0:
        raise StoreError(f"pg_restore failed: {_first_error(proc.stderr)}")
    return BackupResult(path, "pg_restore")


def _logical_restore(path: Path, store, records=None) -> BackupResult:
    src = sa.create_engine(f"sqlite:///{path}")
    try:
        with src.connect() as src_conn:
            names = table_names(src_conn)
            missing = [t for t in STUDY_TABLES if t not in names]
            if missing:
                raise StoreError(f"{path}: not a study backup ({', '.join(missing)} missing)")
            with store.transaction(write=True) as dst_conn:
                rows = copy_tables(src_conn, dst_conn, names)
                withdrawn = _reapply(dst_conn, records) if records else []
                if store.dialect == "postgresql":
                    move_sequences(dst_conn)
    except sa_exc.SQLAlchemyError as err:
        raise StoreError(f"cannot read {path}: {one_line(err)}") from None
    finally:
        src.dispose()
    return BackupResult(path, "logical", rows, withdrawn)
