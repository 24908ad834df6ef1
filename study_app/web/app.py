"""The study app's Streamlit entry: ``streamlit run study_app/web/app.py`` (or ``snapshot study``).

Each run: load the verified stimuli and the store once per server process (a missing
or altered stimulus file stops the app here, before anyone starts), find the
participant — from the ``pid`` in the URL, else the one this browser tab already
started, else the one registered for the URL's ``PROLIFIC_PID`` — ask
:class:`~study_app.session.ParticipantSession` which step they are on, and show that
step's page. Navigation is hidden and explicit: the study's own flow (every step at one
address, so Back/Forward never land on an earlier step without the participant) and
the researcher page (``/researcher``) are the only pages, whatever URL comes first;
the page modules live in ``study_app/web/screens/`` (a ``pages/`` folder beside this script
would be listed by Streamlit itself).

Configuration comes from the environment (``snapshot study`` sets it):
``SNAPSHOT_STIMULI`` (stimuli folder), ``SNAPSHOT_DB`` (database URL),
``SNAPSHOT_ADMIN_TOKEN`` (opens the researcher page).
"""

from __future__ import annotations

import functools
import logging
import sys
from pathlib import Path

import streamlit as st

# `streamlit run study_app/web/app.py` puts study_app/web/ (not the repo) on sys.path; make
# the package importable when the project is not installed.
_REPO = str(Path(__file__).resolve().parents[2])
if _REPO not in sys.path:
    sys.path.insert(0, _REPO)

from snapcore.errors import SnapshotError  # noqa: E402
from study_app.session import (  # noqa: E402
    MaterialsChanged,
    ParticipantSession,
    Stage,
    UnknownParticipant,
    Withdrawn,
    describe_value,
    prolific_problems,
)
from study_app.web.screens import (  # noqa: E402
    answers,
    attention,
    background,
    consent,
    context,
    done,
    invalid,
    keys,
    pose_task,
    researcher,
    view_task,
    widgets,
)
from study_app.web.timing import RunClock  # noqa: E402

#: The page shown at each stage: (render function, title).
STAGE_PAGES = {
    Stage.CONSENT: (consent.render, "Welcome"),
    Stage.BACKGROUND: (background.render, "About you"),
    Stage.POSE: (pose_task.render, "Animation"),
    Stage.VIEW: (view_task.render, "Pictures"),
    Stage.ATTENTION: (attention.render, "One more question"),
    Stage.DONE: (done.render, "Thank you"),
}
#: One address for every step of the flow: a step change is not a new history entry,
#: so Back leaves the study page instead of stepping to a stale earlier step.
FLOW_PATH = "study"
RESEARCHER_PATH = "researcher"
log = logging.getLogger("study_app")


def _query() -> dict:
    """The URL's query: one value per key, or the list when a key is repeated."""
    return {
        k: (v[0] if len(v) == 1 else v)
        for k in st.query_params.keys()
        if (v := st.query_params.get_all(k))
    }


def _participant(ctx):
    """(session or None, problem text or None) for this run.

    The participant is, in order: the ``pid`` of the URL; the one this browser tab
    started (Back to the study link before the id was added); the one registered for
    the URL's ``PROLIFIC_PID`` (the same study link opened again, in any browser). The
    last two put the ``pid`` back into the URL, so a reload keeps them.
    """
    query = _query()
    fresh = context.take_fresh_session(query.get(keys.QUERY_PID))  # taken on every run
    st.session_state[keys.KEY_WITHDRAWN] = False
    st.session_state[keys.KEY_ANSWERS_KEPT] = False
    problems = prolific_problems(query)
    if problems:
        # Refused before anything is stored, and logged for the researcher.
        log.warning(
            "refused a study link with malformed Prolific parameters: %s",
            ", ".join(
                f"{k}={describe_value(query.get(k))}"
                for k in ("PROLIFIC_PID", "STUDY_ID", "SESSION_ID")
                if k in query
            ),
        )
        return None, " ".join(problems) + " Please open the study again from Prolific."
    if "PROLIFIC_PID" in query and not ctx.stimuli.study.completion_code:
        _no_completion_code(ctx.stimuli.study.id)
    pid = query.get(keys.QUERY_PID)
    if fresh is not None:  # read (and updated) by this run's answer callback just now
        st.session_state[keys.KEY_PARTICIPANT_ID] = fresh.participant_id
        return fresh, None
    if pid:
        try:
            session = ParticipantSession.resume(ctx.store, ctx.stimuli, pid)
        except UnknownParticipant as err:
            log.warning("refused participant link pid=%s: %s", describe_value(pid), err)
            return None, _refused(err)
        st.session_state[keys.KEY_PARTICIPANT_ID] = session.participant_id
        return session, None
    session = None
    remembered = st.session_state.get(keys.KEY_PARTICIPANT_ID)
    if remembered:
        try:
            session = ParticipantSession.resume(ctx.store, ctx.stimuli, remembered)
        except UnknownParticipant:
            session = None
    if session is None:
        try:
            session = ParticipantSession.for_prolific(ctx.store, ctx.stimuli, query)
        except UnknownParticipant as err:  # withdrew, or their stimuli are gone
            log.warning("refused Prolific participant: %s", err)
            return None, _refused(err)
    if session is not None:
        st.session_state[keys.KEY_PARTICIPANT_ID] = session.participant_id
        st.query_params[keys.QUERY_PID] = session.participant_id
    return session, None


@functools.cache
def _no_completion_code(study_id: str) -> None:
    """Say once per server that a Prolific participant arrived on a study without a
    completion code (they will get a random code Prolific cannot check)."""
    log.warning(
        "a participant arrived from Prolific, but study '%s' has no completion_code: "
        "they will get a random code Prolific cannot accept (set study.completion_code)",
        study_id,
    )


def _refused(err: UnknownParticipant) -> str:
    """The invalid-link page's text for ``err`` (and what it must say beside it)."""
    st.session_state[keys.KEY_WITHDRAWN] = isinstance(err, Withdrawn)
    st.session_state[keys.KEY_ANSWERS_KEPT] = isinstance(err, MaterialsChanged)
    return str(err)


#: Stages shown full width (three pictures side by side need the room).
WIDE_STAGES = (Stage.VIEW,)


def main() -> None:
    try:
        ctx = context.load_context()
    except Exception as err:  # noqa: BLE001 - any failure here must stop the app, politely
        st.set_page_config(page_title="Action Snapshot study", layout="centered")
        st.error(f"The study cannot start: {widgets.one_line(err)}")
        st.stop()
    session, problem = _participant(ctx)
    wide = session is not None and session.stage in WIDE_STAGES
    st.set_page_config(
        page_title=ctx.stimuli.study.title, page_icon="🎞️", layout="wide" if wide else "centered"
    )
    st.session_state[keys.KEY_SESSION] = session
    st.session_state[keys.KEY_PROBLEM] = problem
    if problem:
        flow = st.Page(invalid.render, title="Link not valid", url_path=FLOW_PATH, default=True)
    else:
        stage = session.stage if session else Stage.CONSENT
        render, title = STAGE_PAGES[stage]
        flow = st.Page(render, title=title, url_path=FLOW_PATH, default=True)
    # A file page (the module runs itself), so it has an address of its own.
    admin = st.Page(Path(researcher.__file__), title="Researcher", url_path=RESEARCHER_PATH)
    # The explicit list is the whole app: any other address shows the default page.
    page = st.navigation([flow, admin], position="hidden")
    widgets.page_style()
    if session is not None and page.url_path != RESEARCHER_PATH:
        answers.stale_tab_notice(session)
    if page.url_path != RESEARCHER_PATH and not problem:
        n_trials = 2 * len(ctx.stimuli.scene_ids) + 1
        done_steps, total = session.progress() if session else (0, 2 + n_trials)
        st.progress(done_steps / total, text=f"Progress: {done_steps} of {total} steps")
    try:
        page.run()
    except SnapshotError as err:  # e.g. a stimulus file changed on disk: one line
        log.error("page failed: %s", err)
        st.error(f"This page cannot be shown: {widgets.one_line(err)}")
        return
    if page.url_path != RESEARCHER_PATH and session is not None and session.stage is not Stage.DONE:
        widgets.resume_link(session)


def _timed_main() -> None:
    """Run :func:`main`, recording how long this script run took, with the answer
    callbacks before it (st.rerun and st.stop end a run with an exception: they are
    timed too)."""
    with RunClock(context.current_stage):
        main()


_timed_main()
