"""The study app's Streamlit entry: ``streamlit run study_app/app.py`` (or ``snapshot study``).

Each run: load the verified stimuli and the store once per server process (a missing
or altered stimulus file stops the app here, before anyone starts), find the
participant from the ``pid`` in the URL, ask :class:`~study_app.session.ParticipantSession`
which step they are on, and show that step's page. Navigation is hidden: participants
cannot skip steps, only the researcher page has its own address (``/researcher``).

Configuration comes from the environment (``snapshot study`` sets it):
``SNAPSHOT_STIMULI`` (stimuli folder), ``SNAPSHOT_DB`` (database URL),
``SNAPSHOT_ADMIN_TOKEN`` (opens the researcher page).
"""

from __future__ import annotations

import sys
from pathlib import Path

import streamlit as st

# `streamlit run study_app/app.py` puts study_app/ (not the repo) on sys.path; make the
# package importable when the project is not installed.
_REPO = str(Path(__file__).resolve().parents[1])
if _REPO not in sys.path:
    sys.path.insert(0, _REPO)

from study_app.screens import (  # noqa: E402
    attention,
    background,
    common,
    consent,
    done,
    invalid,
    pose_task,
    researcher,
    view_task,
)
from study_app.session import ParticipantSession, Stage, UnknownParticipant  # noqa: E402

#: The page shown at each stage: (render function, title, url path).
STAGE_PAGES = {
    Stage.CONSENT: (consent.render, "Welcome", "welcome"),
    Stage.BACKGROUND: (background.render, "About you", "about-you"),
    Stage.POSE: (pose_task.render, "Animation", "animation"),
    Stage.VIEW: (view_task.render, "Pictures", "pictures"),
    Stage.ATTENTION: (attention.render, "One more question", "question"),
    Stage.DONE: (done.render, "Thank you", "done"),
}
RESEARCHER_PATH = "researcher"


def _participant(ctx):
    """(session or None, problem text or None) for the id in the URL."""
    pid = st.query_params.get(common.QUERY_PID)
    if not pid:
        return None, None
    try:
        return ParticipantSession.resume(ctx.store, ctx.stimuli, pid), None
    except UnknownParticipant as err:
        return None, str(err)


#: Stages shown full width (three pictures side by side need the room).
WIDE_STAGES = (Stage.VIEW,)


def main() -> None:
    try:
        ctx = common.load_context()
    except Exception as err:  # noqa: BLE001 - any failure here must stop the app, politely
        st.set_page_config(page_title="Action Snapshot study", layout="centered")
        st.error(f"The study cannot start: {common.one_line(err)}")
        st.stop()
    session, problem = _participant(ctx)
    wide = session is not None and session.stage in WIDE_STAGES
    st.set_page_config(page_title=ctx.stimuli.study.title, page_icon="🎞️",
                       layout="wide" if wide else "centered")
    st.session_state[common.KEY_SESSION] = session
    st.session_state[common.KEY_PROBLEM] = problem
    if problem:
        flow = st.Page(invalid.render, title="Link not valid", url_path="link", default=True)
    else:
        stage = session.stage if session else Stage.CONSENT
        render, title, path = STAGE_PAGES[stage]
        flow = st.Page(render, title=title, url_path=path, default=True)
    # A file page (the module runs itself), so it has an address of its own.
    admin = st.Page(Path(researcher.__file__), title="Researcher", url_path=RESEARCHER_PATH)
    page = st.navigation([flow, admin], position="hidden")
    if page.url_path != RESEARCHER_PATH and not problem:
        n_trials = 2 * len(ctx.stimuli.scene_ids) + 1
        done_steps, total = session.progress() if session else (0, 2 + n_trials)
        st.progress(done_steps / total, text=f"Progress: {done_steps} of {total} steps")
    page.run()


main()
