"""``snapshot serve``: the study on N Streamlit replicas behind nginx, on one PostgreSQL."""

from __future__ import annotations

from pathlib import Path

import click

__all__ = ["serve"]

REPO = Path(__file__).resolve().parents[2]


@click.command()
@click.option(
    "--replicas",
    "n",
    type=click.IntRange(1, 32),
    default=2,
    show_default=True,
    help="Streamlit processes (each uses about one core under load).",
)
@click.option(
    "--config",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="Study config (default: the embedded demo).",
)
@click.option(
    "--stimuli",
    "stimuli_dir",
    type=click.Path(file_okay=False, path_type=Path),
    default=None,
    help="Stimuli folder. Default: var/stimuli/<study id>.",
)
@click.option(
    "--db",
    default=None,
    help="Database URL for all replicas. Default: a PostgreSQL of the set's own "
    "under <run-dir>/pg (initdb once, data kept between runs).",
)
@click.option(
    "--port",
    type=click.IntRange(1024, 65535),
    default=8600,
    show_default=True,
    help="nginx's port: the participants' address.",
)
@click.option(
    "--run-dir",
    type=click.Path(file_okay=False, path_type=Path),
    default=REPO / "var" / "replicas",
    show_default=True,
    help="Folder of the set: nginx.conf, logs, pid files, timings, the database.",
)
def serve(n, config, stimuli_dir, db, port, run_dir):
    """Serve the study on several processes: N Streamlit replicas behind nginx, all on
    one PostgreSQL database, so a Prolific launch is not limited to one process.

    nginx pins each browser to a replica with a cookie (participants sharing an IP are
    spread), upgrades the websocket, caches the stimuli, and moves the participants of
    a replica that dies to another one, which resumes them from the pid in their URL.
    Everything runs as the current user with files under --run-dir; Ctrl-C stops it
    all. The stimuli are checked like `snapshot study` does.

    Example (the demo, two replicas, http://127.0.0.1:8600/):

    \b
      snapshot serve --replicas 2 --port 8600
      snapshot loadtest --url http://127.0.0.1:8600 -n 200 --timings var/replicas/timings.jsonl
    """
    from study_app.design.protocol import DEMO_CONFIG, load_study
    from study_app.design.stimuli import StimuliError, default_stimuli_dir, load_stimuli
    from study_app.ops.replicas import ReplicaSet, main_loop

    if stimuli_dir is None:
        study_cfg = load_study(config or DEMO_CONFIG)
        stimuli_dir = default_stimuli_dir(study_cfg.id)
    if not (stimuli_dir / "manifest.json").exists():
        raise StimuliError(
            f"no stimuli at {stimuli_dir}: build them with `snapshot stimuli "
            f"build` (or run `snapshot study` once for the demo)"
        )
    stim = load_stimuli(stimuli_dir)  # verified file by file before anyone is served
    if db is not None:
        from study_app.data.store import Store

        Store(db).close()  # a wrong URL stops here, in one line, before any process starts
    rs = ReplicaSet(root=run_dir, n=n, port=port, stimuli=stimuli_dir.resolve(), db_url=db)
    rs.start()
    click.echo(
        f"study '{stim.study.id}' on {n} replica(s) "
        f"({', '.join(str(p) for p in rs.replica_ports)}) behind nginx; database "
        f"{rs.db_url.split('@')[-1]}",
        err=True,
    )
    click.echo(f"participants: {rs.url}   state: {run_dir / 'state.json'}", err=True)
    main_loop(rs)
