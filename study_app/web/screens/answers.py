"""Storing a participant's answer once per browser tab: a double click's second send
changes nothing, an answer another tab gave first is said so, and a fragment whose step
was answered hands the page back to a full run.
"""

from __future__ import annotations

import threading

import streamlit as st

from study_app.session import STALE_TAB_TEXT, InvalidAnswer
from study_app.web.timing import in_fragment_run

from .context import current_session, read_session
from .keys import (
    KEY_ANSWERED_HERE,
    KEY_FLASH,
    KEY_FRESH_SESSION,
    KEY_ON_SCREEN,
)
from .widgets import flash, next_attempt

__all__ = [
    "claim_step",
    "release_step",
    "store_answer",
    "retry_trial",
    "answer_outcome",
    "answered_here",
    "stale_tab_notice",
    "leave_fragment_if_moved_on",
]

_CLAIM_LOCK = threading.Lock()


def claim_step(session, step) -> bool:
    """Mark ``step`` of ``session`` as answered by this tab; False when this tab already
    did (or is doing) it: a double click's second send, which must change nothing and
    say nothing. Its callback can run while the first one's is still storing (the
    second send interrupts the first run), so the mark is set before storing, under a
    lock; :func:`release_step` takes it back when nothing was stored."""
    key = (session.participant_id, step)
    with _CLAIM_LOCK:
        mine = st.session_state.setdefault(KEY_ANSWERED_HERE, set())
        if key in mine:
            return False
        mine.add(key)
        return True


def release_step(session, step) -> None:
    """Undo :func:`claim_step` (the answer was refused or failed: the tab may answer again)."""
    with _CLAIM_LOCK:
        st.session_state.get(KEY_ANSWERED_HERE, set()).discard((session.participant_id, step))


def store_answer(session, step, submit, refused, *, resend: bool = False) -> None:
    """Store one answer of this tab: ``submit()`` (a ``ParticipantSession.submit_*``
    call, True if stored) runs once per tab and step (see :func:`claim_step`); a
    refusal (:class:`~study_app.session.InvalidAnswer`) goes to ``refused(err)`` and
    frees the step for another try.

    ``resend``: the widget sent this answer again because the page had not moved on
    (the connection dropped, or the server restarted: a new browser session). If its
    first send was stored, the trial is answered and the page moves on without the
    other-tab notice."""
    if not claim_step(session, step):
        return  # the second send of a double click: this tab answers it, nothing to say
    stored = False
    try:
        stored = submit()
        answer_outcome(stored or resend)
    except InvalidAnswer as err:
        refused(err)
    finally:
        if not stored:
            release_step(session, step)


def retry_trial(trial, err) -> None:
    """A refused trial answer: remount the trial's widget fresh, the reason above it."""
    next_attempt(trial)
    flash("error", str(err))


def _claimed(participant_id: str, step) -> bool:
    return (participant_id, step) in st.session_state.get(KEY_ANSWERED_HERE, set())


def answer_outcome(stored: bool) -> None:
    """After a submit: remember this tab answered; tell it if its answer came second."""
    if stored:
        answered_here()
    else:
        flash("warning", STALE_TAB_TEXT)


def answered_here() -> None:
    """This tab moved the participant on itself (no stale-tab notice on the next run)."""
    st.session_state[KEY_ON_SCREEN] = None


def stale_tab_notice(session) -> None:
    """Warn when the step this tab showed moved on without this tab answering it.

    A second tab (or browser) answered first; whatever this tab sent for the old step —
    a click the new page never reads — was dropped, and it must not move on silently.
    """
    step = session.step_key
    shown = st.session_state.get(KEY_ON_SCREEN)
    # A step this tab answered itself is not stale, even when a run that started
    # before the answer was stored drew that step again (a double click's second send
    # interrupting the first one's run).
    if (
        shown is not None
        and shown[0] == session.participant_id
        and shown[1] != step
        and session.is_done(shown[1])
        and not _claimed(shown[0], shown[1])
    ):
        flash("warning", STALE_TAB_TEXT)
    st.session_state[KEY_ON_SCREEN] = (session.participant_id, step)


def leave_fragment_if_moved_on(participant_id: str, step):
    """The participant's session for a fragment that shows ``step``; in the fragment's
    own run, rerun the whole app instead when the page must change.

    It must when this tab stored an answer to ``step`` (a callback just did: the page
    shows the next step), has a message for the top of the page (a refused answer), or
    the participant moved on elsewhere (another tab answered ``step``: the full run says
    so). The last is read from the store, since a fragment's own run does not run
    app.py; a full run's session is current already.
    """
    if not in_fragment_run():
        return current_session()
    if _claimed(participant_id, step) or KEY_FLASH in st.session_state:
        st.rerun(scope="app")
    session = read_session(participant_id)
    if session is None:
        st.rerun(scope="app")
    if session.step_key != step:
        st.session_state[KEY_FRESH_SESSION] = session
        st.rerun(scope="app")
    return session
