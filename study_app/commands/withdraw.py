"""``snapshot withdraw``: delete one participant's data because they withdrew."""

from __future__ import annotations

import click

from .backup import DB_HELP

__all__ = ["withdraw"]


@click.command()
@click.option("--db", "db_url", metavar="URL", default=None, help=DB_HELP)
@click.option(
    "--pid",
    "participant_id",
    metavar="ID",
    default=None,
    help="The participant's link id (the pid= of their personal link).",
)
@click.option(
    "--prolific-pid",
    "prolific_pid",
    metavar="ID",
    default=None,
    help="Their Prolific id instead (every participant with it).",
)
@click.option(
    "--pseudonym",
    "pseudonym",
    metavar="p-HEX",
    default=None,
    help="Their pseudonym in a shared export instead (p- and 16 hex digits of "
    "their participant, Prolific or session id or completion code).",
)
@click.option(
    "--study",
    "study_id",
    metavar="ID",
    default=None,
    help="Only this study's participants (when one database holds several).",
)
@click.option("-q", "--quiet", is_flag=True, help="Do not print the summary line.")
def withdraw(db_url, participant_id, prolific_pid, pseudonym, study_id, quiet):
    """Delete one participant's data because they withdrew.

    Deletes their responses, interaction events and participant row (background,
    Prolific ids, completion code) in one transaction, and keeps only a withdrawal
    record: when, their link id and Prolific id, and that it was done here (the
    researcher page records "page"). Their personal link then says their data were
    withdrawn. An unknown id is an error and changes nothing.

    Examples: snapshot withdraw --db var/study.db --pid Hq3C0r1yq2cA7FZ0pB1m5w

    snapshot withdraw --db postgresql+psycopg://user@host/db --prolific-pid 5f1e2d3c4b5a69788796a5b4

    snapshot withdraw --db var/study.db --pseudonym p-3f9a0c1d2e4b5a69
    """
    from study_app.data.store import Store
    from study_app.data.withdraw import withdraw as withdraw_participant

    if sum(v is not None for v in (participant_id, prolific_pid, pseudonym)) != 1:
        raise click.UsageError(
            "give exactly one of --pid ID, --prolific-pid ID and --pseudonym p-HEX"
        )
    with Store(db_url, create=False) as store:
        done = withdraw_participant(
            store,
            participant_id=participant_id,
            prolific_pid=prolific_pid,
            study_id=study_id,
            by="cli",
            pseudonym=pseudonym,
        )
        url = store.url
    if not quiet:
        for w in done:
            click.echo(
                f"withdrew participant {w.participant_id} of study {w.study_id} from {url}: "
                f"deleted {w.n_responses} responses, {w.n_events} events and their "
                f"background; withdrawal recorded at "
                f"{w.withdrawn_at.isoformat(timespec='seconds')}",
                err=True,
            )
