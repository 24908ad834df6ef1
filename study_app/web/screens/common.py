"""What every page shares: session-state keys, the app context, small UI helpers.

Pages are thin: they read the participant's :class:`~study_app.session.ParticipantSession`
(made by ``app.py`` for this run), show one step, and hand answers to it. Every
``st.session_state`` key the app uses is a named constant here.
"""

from __future__ import annotations

import functools
import os
import threading
import time
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import streamlit as st

from snapcore.errors import SnapshotError
from study_app.session import STALE_TAB_TEXT, InvalidAnswer
from study_app.timing import RunClock, callback_started, in_fragment_run

__all__ = [
    "QUERY_PID",
    "KEY_SESSION",
    "KEY_PROBLEM",
    "KEY_WITHDRAWN",
    "KEY_PARTICIPANT_ID",
    "KEY_BG_GENDER_SELF",
    "KEY_ON_SCREEN",
    "KEY_TRIAL_SHOWN",
    "KEY_PICKER_START",
    "KEY_ATTEMPT",
    "KEY_ANSWERED_HERE",
    "KEY_FLASH",
    "KEY_FRAMES_FALLBACK",
    "KEY_CONSENT_AGREE",
    "KEY_CONSENT_START",
    "KEY_BG_AGE",
    "KEY_BG_GENDER",
    "KEY_BG_EXPERIENCE",
    "KEY_BG_FORM",
    "KEY_BG_SUBMIT",
    "KEY_ATTENTION_CHOICE",
    "KEY_ATTENTION_SUBMIT",
    "KEY_PICKER",
    "KEY_CHOOSER",
    "KEY_FRAME_SLIDER",
    "KEY_FRAME_CONFIRM",
    "KEY_ADMIN_TOKEN",
    "KEY_DOWNLOAD",
    "KEY_WITHDRAW_KIND",
    "KEY_WITHDRAW_ID",
    "KEY_WITHDRAW_CONFIRM",
    "KEY_WITHDRAW_BUTTON",
    "KEY_RESTART",
    "ENV_STIMULI",
    "ENV_DB",
    "ENV_ADMIN_TOKEN",
    "AppContext",
    "load_context",
    "answering_session",
    "take_fresh_session",
    "claim_step",
    "release_step",
    "store_answer",
    "retry_trial",
    "current_session",
    "current_stage",
    "timed_fragment",
    "leave_fragment_if_moved_on",
    "trial_clock",
    "elapsed_s",
    "next_attempt",
    "one_line",
    "flash",
    "show_flash",
    "widget_key",
    "page_style",
    "resume_link",
    "answer_outcome",
    "stale_tab_notice",
    "answered_here",
]

#: URL query parameter carrying the participant id.
QUERY_PID = "pid"

# -- session-state keys (one place, named) --------------------------------------------
#: The run's ParticipantSession (or None before consent), set by app.py.
KEY_SESSION = "snapshot.session"
#: The participant id this browser tab started or resumed: Back to the study link
#: (an address without ``pid``) resumes them instead of showing the consent page.
KEY_PARTICIPANT_ID = "snapshot.participant_id"
#: (participant id, step) this browser tab showed on its previous run; a step that
#: moved on without this tab answering was answered in another tab or browser.
KEY_ON_SCREEN = "snapshot.on_screen"
#: Why the participant id in the URL was refused (shown by the invalid-link page).
KEY_PROBLEM = "snapshot.problem"
#: True when the refused link is that of a participant who withdrew.
KEY_WITHDRAWN = "snapshot.withdrawn"
#: {(participant id, trial index): wall-clock time the trial was first shown}.
KEY_TRIAL_SHOWN = "snapshot.trial_shown"
#: {(participant id, player widget key): (frame, share watched)} the player starts
#: from in this browser session (read from the stored log once per mount).
KEY_PICKER_START = "snapshot.picker_start"
#: {trial index: attempt number}; a rejected answer remounts the widget fresh.
KEY_ATTEMPT = "snapshot.attempt"
#: {(participant id, step)} this browser tab answered itself (see claim_step).
KEY_ANSWERED_HERE = "snapshot.answered_here"
#: The session an answer's callback (or a fragment) read and updated just now, for the
#: full run that follows, which then need not read it again (see take_fresh_session).
KEY_FRESH_SESSION = "snapshot.fresh_session"
#: A message to show once on the next run (kind, text).
KEY_FLASH = "snapshot.flash"
#: True when the browser could not play a video: pose tasks use the frame slider.
KEY_FRAMES_FALLBACK = "snapshot.frames_fallback"
#: Widget keys (AppTest drives widgets by these).
KEY_CONSENT_AGREE = "consent.agree"
KEY_CONSENT_START = "consent.start"
KEY_BG_FORM = "background.form"
KEY_BG_SUBMIT = "background.submit"
KEY_BG_AGE = "background.age_band"
KEY_BG_GENDER = "background.gender"
KEY_BG_EXPERIENCE = "background.experience"
KEY_BG_GENDER_SELF = "background.gender_self"
KEY_ATTENTION_CHOICE = "attention.choice"
KEY_ATTENTION_SUBMIT = "attention.submit"
KEY_PICKER = "pose.picker"
KEY_CHOOSER = "view.chooser"
KEY_FRAME_SLIDER = "pose.slider"
KEY_FRAME_CONFIRM = "pose.confirm"
KEY_ADMIN_TOKEN = "researcher.token"
KEY_DOWNLOAD = "researcher.download"
#: Withdrawal on the researcher page: which id, the id, the confirmation (its key ends
#: with the id, so a confirmation never carries over to another id), the button.
KEY_WITHDRAW_KIND = "researcher.withdraw.kind"
KEY_WITHDRAW_ID = "researcher.withdraw.id"
KEY_WITHDRAW_CONFIRM = "researcher.withdraw.confirm"
KEY_WITHDRAW_BUTTON = "researcher.withdraw.button"
KEY_RESTART = "invalid.restart"

# -- environment (set by `snapshot study`) -------------------------------------------
#: Stimuli folder to serve (default: the demo's, ``var/stimuli/demo``).
ENV_STIMULI = "SNAPSHOT_STIMULI"
#: Database URL (read by the store; default SQLite under ``var/``).
ENV_DB = "SNAPSHOT_DB"
#: Token that opens the researcher page; without it the page shows nothing.
ENV_ADMIN_TOKEN = "SNAPSHOT_ADMIN_TOKEN"

REPO = Path(__file__).resolve().parents[2]
DEFAULT_STIMULI = REPO / "var" / "stimuli" / "demo"


@dataclass(frozen=True)
class AppContext:
    """What the server holds for every participant: verified stimuli and the store."""

    stimuli: object
    store: object


#: {(stimuli folder, database URL): AppContext}, one per server process. A plain dict
#: rather than ``st.cache_resource``: Streamlit's cache inspects the function's
#: signature on every call, and every script run asks for the context (measured: ~5% of
#: the server's time at a 12-participant launch).
_CONTEXTS: dict[tuple, AppContext] = {}
_CONTEXT_LOCK = threading.Lock()
_CLAIM_LOCK = threading.Lock()


def _load_context(stimuli_dir: str, db_url: str | None) -> AppContext:
    from study_app.stimuli import load_stimuli
    from study_app.store import Store

    # Verified once per server process, before anyone is served: a missing or altered
    # file stops the app with the reason instead of serving wrong stimuli. A failure
    # is not kept: the next run tries again.
    key = (stimuli_dir, db_url)
    with st.spinner("Checking the study materials…"), _CONTEXT_LOCK:
        if key not in _CONTEXTS:
            _CONTEXTS[key] = AppContext(stimuli=load_stimuli(stimuli_dir), store=Store(db_url))
    return _CONTEXTS[key]


@lru_cache(maxsize=16)
def _absolute(folder: str) -> str:
    return str(Path(folder).resolve())


def load_context() -> AppContext:
    """The app context for the configured stimuli folder and database.

    Raises
    ------
    SnapshotError
        Stimuli missing or altered, or the database unreachable (one line).
    """
    folder = os.environ.get(ENV_STIMULI) or str(DEFAULT_STIMULI)
    key = (_absolute(folder), os.environ.get(ENV_DB) or None)
    return _CONTEXTS.get(key) or _load_context(*key)


def answering_session(pid: str):
    """In an answer's callback: the participant's session as the store holds it now, or
    None when the id is no longer valid (the run that follows says why).

    Answers are stored in widget callbacks, which Streamlit runs before the script run
    the click causes, so that run already shows the next step (a run fewer per answer
    than storing in the page and calling ``st.rerun()``). The session is read afresh:
    another tab may have answered since this page was drawn.
    """
    callback_started()
    session = _read_session(pid)
    if session is not None:
        st.session_state[KEY_FRESH_SESSION] = session  # what the answer then changes in it
    return session


def _read_session(pid: str):
    """The participant's session as the store holds it now, or None for an id that is
    no longer valid."""
    from study_app.session import ParticipantSession, UnknownParticipant

    ctx = load_context()
    try:
        return ParticipantSession.resume(ctx.store, ctx.stimuli, pid)
    except UnknownParticipant:
        return None


def take_fresh_session(participant_id: str):
    """The session of ``participant_id`` a callback or fragment of this browser session
    read from the store (and updated with what it stored) just before this run, or
    None; taken once. It saves the run reading the participant again."""
    session = st.session_state.pop(KEY_FRESH_SESSION, None)
    return session if session is not None and session.participant_id == participant_id \
        else None


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


def store_answer(session, step, submit, refused) -> None:
    """Store one answer of this tab: ``submit()`` (a ``ParticipantSession.submit_*``
    call, True if stored) runs once per tab and step (see :func:`claim_step`); a
    refusal (:class:`~study_app.session.InvalidAnswer`) goes to ``refused(err)`` and
    frees the step for another try."""
    if not claim_step(session, step):
        return  # the second send of a double click: this tab answers it, nothing to say
    stored = False
    try:
        stored = submit()
        answer_outcome(stored)
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


def current_session():
    """This run's participant session (None before consent). In a fragment's own run it
    is the session of the last full run."""
    return st.session_state.get(KEY_SESSION)


def current_stage() -> str:
    """The current session's stage name ("none" before consent), for the run timings."""
    session = current_session()
    return session.stage.value if session is not None else "none"


def timed_fragment(func):
    """``st.fragment(func)``: a part of a page whose widgets, when they change, rerun
    only that part (not app.py, the other widgets or the page around it), its own runs
    timed like script runs (:mod:`study_app.timing`).

    For widgets whose changes only set a value or send a log batch: their runs were 10
    of a participant's 24 full script runs. A fragment's own run knows only what the
    last full run left in the session state; whatever must move the page on calls
    :func:`leave_fragment_if_moved_on`.
    """
    @functools.wraps(func)
    def run(*args, **kwargs):
        with RunClock(current_stage, fragment=True):
            return func(*args, **kwargs)

    return st.fragment(run)


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
    session = _read_session(participant_id)
    if session is None:
        st.rerun(scope="app")
    if session.step_key != step:
        st.session_state[KEY_FRESH_SESSION] = session
        st.rerun(scope="app")
    return session


def widget_key(base: str, trial) -> str:
    """A widget key unique to a trial and to the current attempt at it."""
    attempt = st.session_state.get(KEY_ATTEMPT, {}).get(trial.index, 0)
    return f"{base}.{trial.index}.{attempt}"


def next_attempt(trial) -> None:
    """Remount the trial's widgets fresh (after a rejected answer)."""
    attempts = dict(st.session_state.get(KEY_ATTEMPT, {}))
    attempts[trial.index] = attempts.get(trial.index, 0) + 1
    st.session_state[KEY_ATTEMPT] = attempts


def trial_clock(session, trial) -> float:
    """When this trial was first shown to this participant, in any browser session
    (seconds since the epoch; stored, so a reload does not restart the clock)."""
    shown = st.session_state.setdefault(KEY_TRIAL_SHOWN, {})
    key = (session.participant_id, trial.index)
    if key not in shown:  # one query per trial and browser session, not per rerun
        shown[key] = session.trial_shown_at(trial.index)
    return shown[key]


def elapsed_s(session, trial) -> float:
    """Seconds since the trial was first shown (the stored response time)."""
    return max(0.0, time.time() - trial_clock(session, trial))


def flash(kind: str, text: str) -> None:
    """Show ``text`` once, on the next run (``kind``: success, info, warning, error)."""
    st.session_state[KEY_FLASH] = (kind, text)


def show_flash() -> None:
    """Show and clear the pending one-time message."""
    item = st.session_state.pop(KEY_FLASH, None)
    if item:
        getattr(st, item[0])(item[1])


#: Page CSS: Streamlit's default top padding (6rem) pushed the player's controls below
#: the fold at 1280×720; the header bar it makes room for is hidden anyway.
PAGE_CSS = """
<style>
.stMainBlockContainer, .block-container { padding-top: 2.5rem; padding-bottom: 2rem; }
</style>
"""


def page_style() -> None:
    """Apply the study's page CSS (once per run, before the page renders)."""
    st.html(PAGE_CSS)


def resume_link(session) -> None:
    """The participant's personal link, shown so they can copy it (the consent page
    tells them to come back with it; the address bar alone is easy to lose)."""
    from study_app.session import resume_url

    base = st.context.url or ""
    st.divider()
    st.caption("Your personal link: to pause and continue later (in this or another "
               "browser), copy it and open it again.")
    st.code(resume_url(base, session.participant_id), language=None)




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
    if shown is not None and shown[0] == session.participant_id and shown[1] != step \
            and session.is_done(shown[1]) and not _claimed(shown[0], shown[1]):
        flash("warning", STALE_TAB_TEXT)
    st.session_state[KEY_ON_SCREEN] = (session.participant_id, step)


def one_line(err: BaseException) -> str:
    """A participant-facing line for an error (no traceback)."""
    return str(err) if isinstance(err, SnapshotError) else f"{type(err).__name__}: {err}"
