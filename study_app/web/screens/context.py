"""The app context every page shares: the verified stimuli and the store (one per server
process), and this run's participant session.

Pages are thin: they read the participant's :class:`~study_app.session.ParticipantSession`
(made by ``app.py`` for this run), show one step, and hand answers to it.
"""

from __future__ import annotations

import os
import threading
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import TYPE_CHECKING

import streamlit as st

from study_app.web.timing import callback_started

from .keys import ENV_DB, ENV_STIMULI, KEY_FRESH_SESSION, KEY_SESSION

if TYPE_CHECKING:  # imported when the context is first made (see _load_context)
    from study_app.data.store import Store
    from study_app.design.stimuli import Stimuli

__all__ = [
    "AppContext",
    "load_context",
    "answering_session",
    "read_session",
    "take_fresh_session",
    "current_session",
    "current_stage",
]

REPO = Path(__file__).resolve().parents[3]
DEFAULT_STIMULI = REPO / "var" / "stimuli" / "demo"


@dataclass(frozen=True)
class AppContext:
    """What the server holds for every participant: verified stimuli and the store."""

    stimuli: Stimuli
    store: Store


#: {(stimuli folder, database URL): AppContext}, one per server process. A plain dict
#: rather than ``st.cache_resource``: Streamlit's cache inspects the function's
#: signature on every call, and every script run asks for the context (measured: ~5% of
#: the server's time at a 12-participant launch).
_CONTEXTS: dict[tuple, AppContext] = {}
_CONTEXT_LOCK = threading.Lock()


def _load_context(stimuli_dir: str, db_url: str | None) -> AppContext:
    from study_app.data.store import Store
    from study_app.design.stimuli import load_stimuli

    # Verified once per server process, before anyone is served: a missing or altered
    # file stops the app with the reason instead of serving wrong stimuli. A failure
    # is not kept: the next run tries again.
    key = (stimuli_dir, db_url)
    with st.spinner("Checking the study materials…"), _CONTEXT_LOCK:
        if key not in _CONTEXTS:
            from study_app.web.picker import pin_files

            stimuli = load_stimuli(stimuli_dir)
            pin_files(stimuli.file_digests())  # served only with the verified contents
            _CONTEXTS[key] = AppContext(stimuli=stimuli, store=Store(db_url))
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
    session = read_session(pid)
    if session is not None:
        st.session_state[KEY_FRESH_SESSION] = session  # what the answer then changes in it
    return session


def read_session(pid: str):
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
    return session if session is not None and session.participant_id == participant_id else None


def current_session():
    """This run's participant session (None before consent). In a fragment's own run it
    is the session of the last full run."""
    return st.session_state.get(KEY_SESSION)


def current_stage() -> str:
    """The current session's stage name ("none" before consent), for the run timings."""
    session = current_session()
    return session.stage.value if session is not None else "none"
