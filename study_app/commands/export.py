"""``snapshot export``: the study's responses as CSV or JSON lines, validated."""

from __future__ import annotations

import click

__all__ = ["export"]


@click.command()
@click.option("--db", "db_url", metavar="URL", default=None,
              help="Database URL (sqlite:///path/study.db, postgresql+psycopg://user@host/db) "
                   "or a .db file. Default: $SNAPSHOT_DB, else var/study.db in the project.")
@click.option("-o", "--output", required=True, metavar="PATH",
              help="Output file: .csv, or .jsonl/.json (JSON lines); '-' for stdout.")
@click.option("--format", "fmt", type=click.Choice(["csv", "jsonl"]), default=None,
              help="Output format (default: from the output suffix; csv for stdout).")
@click.option("--include-simulated", is_flag=True,
              help="Also export simulated participants (left out by default).")
@click.option("--participants", "participants_path", metavar="PATH", default=None,
              type=click.Path(dir_okay=False),
              help="Also write one row per participant (background, Prolific ids, "
                   "completion) to this .csv/.jsonl file.")
@click.option("--events", "events_path", metavar="PATH", default=None,
              type=click.Path(dir_okay=False),
              help="Also write the interaction events (plays, seeks...) as JSON lines.")
@click.option("-q", "--quiet", is_flag=True, help="Do not print the summary line.")
def export(db_url, output, fmt, include_simulated, participants_path, events_path, quiet):
    """Export the study responses: one row per trial, validated against
    data_schema/response.schema.json before anything is written.

    Frames are motion frames in source numbering; times are ISO 8601 in UTC. In CSV,
    `shown_order` (the method shown at each screen position, left to right) is a JSON
    array string such as ["ours", "motion_area", "viewpoint_entropy"], booleans are
    true/false and missing values are empty cells (study_app.export.read_export parses
    it back).

    Example: snapshot export --db sqlite:///var/study.db -o responses.csv
    """
    from ..export import write_events, write_export, write_participants
    from ..store import Store

    with Store(db_url, create=False) as store:
        rows = store.export_rows(include_simulated=include_simulated)
        n = write_export(rows, output, fmt=fmt)
        n_part = None
        if participants_path:
            n_part = write_participants(
                store.participants(include_simulated=include_simulated), participants_path)
        n_events = None
        if events_path:
            keep = {r["participant_id"] for r in store.participants(
                include_simulated=include_simulated)}
            n_events = write_events([e for e in store.events() if e["participant_id"] in keep],
                                    events_path)
        url = store.url
        n_simulated_only = 0 if include_simulated else \
            store.progress(include_simulated=True)["responses"] - len(rows)
    if not quiet:
        who = len({r["participant_id"] for r in rows})
        msg = f"exported {n} responses of {who} participants from {url} to {output}"
        if n_part is not None:
            msg += f"; {n_part} participants to {participants_path}"
        if n_events is not None:
            msg += f"; {n_events} events to {events_path}"
        click.echo(msg, err=True)
        if n_simulated_only:
            click.echo(f"note: {n_simulated_only} responses of simulated participants were left "
                       "out (add --include-simulated)", err=True)
