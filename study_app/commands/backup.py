"""``snapshot backup``, ``snapshot restore``: a copy of the study database, and back."""

from __future__ import annotations

import click

__all__ = ["backup", "restore", "DB_HELP"]

DB_HELP = (
    "Database URL (sqlite:///path/study.db, postgresql+psycopg://user@host/db) or a .db "
    "file. Default: $SNAPSHOT_DB, else var/study.db in the project."
)


@click.command()
@click.option("--db", "db_url", metavar="URL", default=None, help=DB_HELP)
@click.option(
    "-o",
    "--output",
    default=None,
    metavar="FILE",
    type=click.Path(dir_okay=False),
    help="The backup file (a SQLite database, or a pg_dump archive).",
)
@click.option(
    "--verify",
    "verify",
    metavar="FILE",
    default=None,
    type=click.Path(dir_okay=False),
    help="Instead of backing up: check that FILE, a backup, can be restored "
    "(integrity, study tables, references, pseudonym secrets); exit 2 if not.",
)
@click.option(
    "--method",
    type=click.Choice(["auto", "native", "logical"]),
    default="auto",
    show_default=True,
    help="native: SQLite's online backup API or pg_dump; logical: a copy of every "
    "table through SQLAlchemy into a SQLite file; auto: native when available.",
)
@click.option("--force", is_flag=True, help="Replace FILE if it exists.")
@click.option("-q", "--quiet", is_flag=True, help="Do not print the summary line.")
def backup(db_url, output, verify, method, force, quiet):
    """Back up the study database while the app runs: one consistent copy.

    Every answer committed before the backup starts is in it, none that starts after,
    and nothing half-written. SQLite is copied with its online backup API; PostgreSQL
    with pg_dump when installed, else (or with --method logical) through SQLAlchemy
    from one repeatable-read snapshot into a SQLite file. The pseudonym secrets are
    included, so a restored database exports the same pseudonyms. A SQLite backup can
    be read directly (snapshot export --db FILE) or restored with snapshot restore.

    Example: snapshot backup --db var/study.db -o backups/study-2025-01-31.db

    snapshot backup --verify backups/study-2025-01-31.db
    """
    from study_app.data.backup import backup as backup_database
    from study_app.data.backup import verify_backup
    from study_app.data.store import mask_url

    if (output is None) == (verify is None):
        raise click.UsageError("give -o/--output FILE (back up) or --verify FILE (check a backup)")
    if verify is not None:
        checked = verify_backup(verify)
        if not quiet:
            rows = ", ".join(f"{n} {t}" for t, n in checked.rows.items())
            click.echo(
                f"{verify}: a sound {checked.method} backup" + (f" ({rows})" if rows else ""),
                err=True,
            )
        return

    result = backup_database(db_url, output, method=method, force=force)
    if not quiet:
        rows = ", ".join(f"{n} {t}" for t, n in result.rows.items())
        click.echo(
            f"backed up {mask_url(db_url) if db_url else 'the default database'} to "
            f"{result.path} ({result.method}{': ' + rows if rows else ''})",
            err=True,
        )


@click.command()
@click.argument("backup_file", metavar="FILE", type=click.Path(dir_okay=False))
@click.option("--db", "db_url", metavar="URL", required=True, help=DB_HELP.split(" Default")[0])
@click.option(
    "--withdrawals-from",
    "withdrawals_from",
    metavar="LOG|URL",
    multiple=True,
    help="Where the withdrawals made after the backup are: the lost database's "
    "withdrawal log (<db>.withdrawals.jsonl beside it, or $SNAPSHOT_WITHDRAWAL_LOG), "
    "the database itself, or a later backup. Repeatable.",
)
@click.option(
    "--without-withdrawal-log",
    "without_log",
    is_flag=True,
    help="Restore even though no withdrawal log made after the backup is found "
    "(only if you know that nobody withdrew since).",
)
@click.option("-q", "--quiet", is_flag=True, help="Do not print the summary line.")
def restore(backup_file, db_url, withdrawals_from, without_log, quiet):
    """Restore a backup made by snapshot backup into an empty database, keeping
    everybody who withdrew since out.

    A SQLite backup restores into SQLite or PostgreSQL (every row, ids kept, in one
    transaction); a pg_dump archive into PostgreSQL (pg_restore). A database that
    already holds data is refused: a restore never mixes with or replaces data.
    The backup is verified first (snapshot backup --verify).

    Withdrawals made after the backup are applied in the same transaction, from the
    withdrawal log (written outside the database by every withdrawal: beside a SQLite
    database as <db>.withdrawals.jsonl, or at $SNAPSHOT_WITHDRAWAL_LOG), from
    withdrawals.jsonl beside the backup (every backup updates it) and from
    --withdrawals-from. Without any log made after the backup the restore refuses,
    unless --without-withdrawal-log.

    Example: snapshot restore backups/study-2025-01-31.db --db sqlite:///var/study.db

    snapshot restore backups/b.db --db sqlite:///var/new.db --withdrawals-from var/study.db.withdrawals.jsonl
    """
    from study_app.data.backup import restore as restore_database
    from study_app.data.store import mask_url

    result = restore_database(
        backup_file,
        db_url,
        withdrawals_from=list(withdrawals_from),
        without_withdrawal_log=without_log,
    )
    if not quiet:
        rows = ", ".join(f"{n} {t}" for t, n in result.rows.items())
        click.echo(
            f"restored {backup_file} into {mask_url(db_url)} "
            f"({result.method}{': ' + rows if rows else ''})",
            err=True,
        )
        if result.anonymised:
            click.echo(
                f"destroyed again the pseudonym secret of {', '.join(result.anonymised)}, "
                "anonymised after the backup",
                err=True,
            )
        if result.withdrawn:
            click.echo(
                f"re-applied {len(result.withdrawn)} withdrawals recorded after the "
                f"backup: deleted participants {', '.join(result.withdrawn)}",
                err=True,
            )
    if without_log:
        # Always said (also with -q): the restored data may hold people who withdrew.
        click.echo(
            "warning: --without-withdrawal-log: anybody who withdrew after this backup "
            "and is in no withdrawal log is back in the restored data",
            err=True,
        )
