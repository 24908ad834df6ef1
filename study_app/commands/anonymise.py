"""``snapshot anonymise``: destroy a study's pseudonym secret, so that shared data become
anonymous."""

from __future__ import annotations

import click

from .backup import DB_HELP

__all__ = ["anonymise"]


@click.command()
@click.option("--db", "db_url", metavar="URL", default=None, help=DB_HELP)
@click.option(
    "--study",
    "study_id",
    metavar="ID",
    default=None,
    help="Only this study (default: every study in the database).",
)
@click.option(
    "--yes",
    is_flag=True,
    help="Do not ask for confirmation (it cannot be undone).",
)
@click.option("-q", "--quiet", is_flag=True, help="Do not print the summary line.")
def anonymise(db_url, study_id, yes, quiet):
    """Destroy the pseudonym secret of a study, for good: its shared exports become
    anonymous.

    Every shared export replaces ids by pseudonyms made with a secret kept in the
    database; while it exists, a pseudonym leads back to a participant. Run this once
    the data are published and every participant is paid: the secret is erased from
    the database and its storage (SQLite: rebuilt, write-ahead log truncated;
    PostgreSQL: the table rewritten), and the time is recorded. Afterwards nobody can
    withdraw by pseudonym (by link id or Prolific id still), and each new export gets
    new pseudonyms from a secret that is never stored. Backups made before still hold
    the secret: delete them.

    Example: snapshot anonymise --db var/study.db --study demo
    """
    from study_app.data.anonymise import anonymise as anonymise_study
    from study_app.data.store import Store

    if not yes:
        click.confirm(
            "Destroy the pseudonym secret"
            + (f" of study {study_id}" if study_id else " of every study")
            + "? Withdrawal by pseudonym ends, for good",
            abort=True,
            err=True,
        )
    with Store(db_url) as store:
        done = anonymise_study(store, study_id=study_id)
        url = store.url
    if not quiet:
        for a in done:
            when = a.anonymised_at.isoformat(timespec="seconds")
            click.echo(
                f"study {a.study_id} of {url}: "
                + (
                    f"already anonymised on {when}"
                    if a.already
                    else f"pseudonym secret destroyed at {when}"
                ),
                err=True,
            )
    if any(not a.already for a in done):
        # Always said (also with -q): the old copies are the researcher's to delete.
        click.echo(
            "warning: backups made before now still hold the secret: delete them, or "
            "they can trace the published pseudonyms",
            err=True,
        )
