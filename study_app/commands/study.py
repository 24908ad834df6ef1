"""``snapshot study``: serve the user-study app (Streamlit) for one stimuli folder."""

from __future__ import annotations

import os
import sys
import warnings
from pathlib import Path

import click

__all__ = ["study"]


@click.command()
@click.option(
    "--config",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="Study config (TOML/JSON). Default: the embedded demo "
    "(study_app/configs/demo.toml), or the study of --stimuli.",
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
    help="Database URL (SQLAlchemy), e.g. postgresql+psycopg://user@host/db. "
    "Default: $SNAPSHOT_DB, else SQLite at var/study.db.",
)
@click.option("--port", type=click.IntRange(1, 65535), default=8501, show_default=True)
@click.option(
    "--address",
    default="127.0.0.1",
    show_default=True,
    help="Interface to listen on (0.0.0.0 to serve other machines).",
)
@click.option(
    "--build/--no-build",
    "build",
    default=None,
    help="Build missing stimuli first (default: only for the demo, which takes "
    "a minute; other studies: run `snapshot stimuli build`).",
)
@click.option("--quiet", "-q", is_flag=True, help="No progress bar while building.")
def study(config, stimuli_dir, db, port, address, build, quiet):
    """Serve the user-study app in the browser (Streamlit).

    Checks everything before serving: the stimuli folder is verified file by file
    against its manifest (a missing or altered file stops here with its name) and the
    database must answer. With no options it serves the demo study on
    http://127.0.0.1:8501, building its stimuli into var/stimuli/demo the first time.

    Participants open the printed address; with Prolific, append

    \b
      ?PROLIFIC_PID={{%PROLIFIC_PID%}}&STUDY_ID={{%STUDY_ID%}}&SESSION_ID={{%SESSION_ID%}}

    The researcher page is at /researcher and opens with the token in
    $SNAPSHOT_ADMIN_TOKEN (without it the page stays empty).
    """
    from study_app.data.store import Store
    from study_app.design.build import build_stimuli
    from study_app.design.protocol import DEMO_CONFIG, load_study
    from study_app.design.stimuli import StimuliError, default_stimuli_dir, load_stimuli
    from study_app.web.server import streamlit_command

    if config is None and stimuli_dir is not None:
        study_cfg = None  # serve the folder as built; its manifest carries the study
    else:
        config = config or DEMO_CONFIG
        study_cfg = load_study(config)
    folder = stimuli_dir or default_stimuli_dir(study_cfg.id)
    if not (folder / "manifest.json").exists():
        is_demo = config is not None and Path(config).resolve() == DEMO_CONFIG.resolve()
        if not (build if build is not None else is_demo) or study_cfg is None:
            raise StimuliError(
                f"no stimuli at {folder}: build them with `snapshot stimuli build "
                f"{config or 'STUDY.toml'} -o {folder}` (or pass --build)"
            )
        click.echo(f"building the stimuli of '{study_cfg.id}' into {folder} (once)...", err=True)
        build_stimuli(study_cfg, folder, force=True, quiet=quiet)
    stim = load_stimuli(folder)
    if study_cfg is not None and stim.study.id != study_cfg.id:
        raise StimuliError(
            f"{folder} holds the stimuli of study '{stim.study.id}', "
            f"not '{study_cfg.id}' ({config})"
        )
    if study_cfg is not None and stim.manifest["study"] != study_cfg.to_dict():
        warnings.warn(
            f"{folder} was built from another version of {config}; serving it as "
            f"built (rebuild: snapshot stimuli build {config} -o {folder} --force)",
            stacklevel=1,
        )
    if not stim.study.completion_code and "prolific" in (stim.study.redirect_url or "").lower():
        # Flagged before anyone starts: Prolific checks the code a participant brings back.
        warnings.warn(
            f"study '{stim.study.id}' sends participants back to Prolific but has no "
            "completion_code: each gets a random code Prolific cannot accept; set "
            "study.completion_code to your Prolific study's code",
            stacklevel=1,
        )
    store = Store(db)
    url = store.url
    store.close()
    env = dict(os.environ)
    env["SNAPSHOT_STIMULI"] = str(folder.resolve())
    if db:
        env["SNAPSHOT_DB"] = db
    env.setdefault("PYOPENGL_PLATFORM", "egl")
    host = "localhost" if address in ("127.0.0.1", "0.0.0.0") else address
    click.echo(
        f"study '{stim.study.id}': {len(stim.scenes)} scenes, stimuli {folder} "
        f"(verified, manifest {stim.sha256[:12]}), database {url}",
        err=True,
    )
    click.echo(
        f"participants: http://{host}:{port}/   researcher: http://{host}:{port}/researcher"
        + ("" if env.get("SNAPSHOT_ADMIN_TOKEN") else " (set SNAPSHOT_ADMIN_TOKEN to open it)"),
        err=True,
    )
    cmd = streamlit_command(port=port, address=address)
    sys.stdout.flush()
    sys.stderr.flush()
    # Replace this process: Ctrl-C and signals reach Streamlit directly, and the pid a
    # caller started is the server's.
    os.execve(cmd[0], cmd, env)
