"""``snapshot export``: the study's responses as CSV or JSON lines, or a Psych-DS dataset,
validated and pseudonymised."""

from __future__ import annotations

import click

from snapcore.errors import SnapshotError

__all__ = ["export"]


@click.command()
@click.option(
    "--db",
    "db_url",
    metavar="URL",
    default=None,
    help="Database URL (sqlite:///path/study.db, postgresql+psycopg://user@host/db) "
    "or a .db file. Default: $SNAPSHOT_DB, else var/study.db in the project.",
)
@click.option(
    "-o",
    "--output",
    default=None,
    metavar="PATH",
    help="Output file: .csv, or .jsonl/.json (JSON lines); '-' for stdout.",
)
@click.option(
    "--format",
    "fmt",
    type=click.Choice(["csv", "jsonl"]),
    default=None,
    help="Output format (default: from the output suffix; csv for stdout).",
)
@click.option(
    "--include-simulated",
    is_flag=True,
    help="Also export simulated participants (left out by default).",
)
@click.option(
    "--participants",
    "participants_path",
    metavar="PATH",
    default=None,
    type=click.Path(dir_okay=False),
    help="Also write one row per participant (background, Prolific ids, "
    "completion) to this .csv/.jsonl file.",
)
@click.option(
    "--events",
    "events_path",
    metavar="PATH",
    default=None,
    type=click.Path(dir_okay=False),
    help="Also write the interaction events (plays, seeks...) as JSON lines.",
)
@click.option(
    "--psych-ds",
    "psych_ds",
    metavar="DIR",
    default=None,
    type=click.Path(file_okay=False),
    help="Also (or instead of -o) write a Psych-DS dataset to this new folder: "
    "dataset_description.json, data/study-<id>_data.csv (+ participants, "
    "events), materials/manifest.json.",
)
@click.option(
    "--stimuli",
    "stimuli_dir",
    metavar="DIR",
    default=None,
    type=click.Path(file_okay=False, exists=True),
    help="With --psych-ds: the stimuli folder whose manifest goes to materials/ "
    "(default: $SNAPSHOT_STIMULI when set).",
)
@click.option(
    "--identifiers",
    is_flag=True,
    help="Write the raw participant, Prolific and session ids instead of "
    "pseudonyms (personal data: keep such files private).",
)
@click.option("-q", "--quiet", is_flag=True, help="Do not print the summary line.")
def export(
    db_url,
    output,
    fmt,
    include_simulated,
    participants_path,
    events_path,
    psych_ds,
    stimuli_dir,
    identifiers,
    quiet,
):
    """Export the study responses: one row per trial, validated against
    data_schema/response.schema.json before anything is written.

    Identifiers are pseudonymised by default: participant ids, Prolific ids, session
    ids, per-participant completion codes and browser tab ids become p- and 16 hex
    digits of a keyed hash (HMAC-SHA256 with a secret kept in the database, never
    exported), the same in every export, so an analysis can be re-run and files
    joined. Such shared exports also leave out each participant's seed, give times as
    UTC months, round durations to 0.1 s and order rows by pseudonym (not by arrival),
    so that neither order nor a time nor a technical id matches a row to Prolific's
    records or to an identifiers file (docs/open-data.md). --identifiers gives the
    raw ids, seeds, exact times and arrival order, with a warning. Every file is
    written under a temporary name and renamed at the end: a failed export leaves
    none.

    Frames are motion frames in source numbering; times are ISO 8601 in UTC. In CSV,
    `shown_order` (the method shown at each screen position, left to right) is a JSON
    array string such as ["ours", "motion_area", "viewpoint_entropy"], booleans are
    true/false and missing values are empty cells (study_app.data.export.read_export parses
    it back).

    Examples: snapshot export --db sqlite:///var/study.db -o responses.csv

    snapshot export --db var/study.db --psych-ds dataset/ --stimuli var/stimuli/demo
    """
    import os
    import secrets
    from pathlib import Path

    from study_app.data.errors import StoreError
    from study_app.data.export import write_events, write_export, write_participants
    from study_app.data.pseudonym import IDENTIFIERS_WARNING, OPEN_DROPPED, Pseudonymiser
    from study_app.data.store import Store

    if output is None and psych_ds is None:
        raise click.UsageError("give -o/--output PATH, --psych-ds DIR, or both")
    if output is None and (participants_path or events_path):
        raise click.UsageError("--participants and --events go with -o/--output")
    if identifiers:
        click.echo(IDENTIFIERS_WARNING, err=True)
    staged: list[tuple[Path, Path]] = []  # (temp file, final path)

    def stage(path) -> Path:
        """A temp name beside ``path`` (same suffix, so the format is still told):
        every file is renamed into place only when all are written."""
        final = Path(path)
        tmp = final.with_name(f".{final.stem}.{secrets.token_hex(4)}.tmp{final.suffix}")
        staged.append((tmp, final))
        return tmp

    try:
        with Store(db_url, create=False) as store:
            anon = (lambda records: records) if identifiers else Pseudonymiser(store).records
            rows = store.export_rows(include_simulated=include_simulated)
            n = n_part = n_events = None
            if output is not None:
                target = output if str(output) == "-" else stage(output)
                n = write_export(anon(rows), target, fmt=fmt)
                if participants_path:
                    from study_app.data.monitor import with_exclusions

                    n_part = write_participants(
                        anon(
                            with_exclusions(
                                store, store.participants(include_simulated=include_simulated)
                            )
                        ),
                        stage(participants_path),
                        drop=() if identifiers else OPEN_DROPPED,
                    )
                if events_path:
                    keep = {
                        r["participant_id"]
                        for r in store.participants(include_simulated=include_simulated)
                    }
                    n_events = write_events(
                        anon([e for e in store.events() if e["participant_id"] in keep]),
                        stage(events_path),
                    )
            dataset = None
            if psych_ds is not None:
                from study_app.data.psychds import write_psych_ds

                stimuli_dir = stimuli_dir or os.environ.get("SNAPSHOT_STIMULI") or None
                try:
                    dataset = write_psych_ds(
                        store,
                        psych_ds,
                        stimuli_dir=stimuli_dir,
                        pseudonymise=not identifiers,
                        include_simulated=include_simulated,
                    )
                except SnapshotError as err:
                    raise type(err)(f"--psych-ds {psych_ds}: {err}") from None
            url = store.url
            n_simulated_only = (
                0
                if include_simulated
                else store.progress(include_simulated=True)["responses"] - len(rows)
            )
        for tmp, final in staged:
            os.replace(tmp, final)
        staged.clear()
    except OSError as err:
        raise StoreError(f"cannot write {err.filename or 'the output'}: {err.strerror}") from None
    except SnapshotError as err:  # name the file asked for, not its temp name
        text = str(err)
        for tmp, final in staged:
            text = text.replace(str(tmp), str(final))
        raise type(err)(text) from None
    finally:
        for tmp, _ in staged:  # a failed export leaves no file behind
            try:
                tmp.unlink(missing_ok=True)
            except OSError:
                pass  # its folder is unusable: no file was made there
    if dataset is not None:
        for warning in dataset["warnings"]:
            click.echo(f"warning: {warning}", err=True)
    if not quiet:
        who = len({r["participant_id"] for r in rows})
        if n is not None:
            msg = f"exported {n} responses of {who} participants from {url} to {output}"
            if n_part is not None:
                msg += f"; {n_part} participants to {participants_path}"
            if n_events is not None:
                msg += f"; {n_events} events to {events_path}"
            click.echo(msg, err=True)
        if dataset is not None:
            click.echo(
                f"wrote a Psych-DS dataset of {dataset['responses']} responses of "
                f"{dataset['participants']} participants to {psych_ds} "
                f"({len(dataset['files'])} files"
                + ("" if stimuli_dir else "; no materials/: give --stimuli DIR")
                + ")",
                err=True,
            )
        if n_simulated_only:
            click.echo(
                f"note: {n_simulated_only} responses of simulated participants were left "
                "out (add --include-simulated)",
                err=True,
            )
