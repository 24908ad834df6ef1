"""Small UI helpers of the pages: one-time messages, widget keys per attempt, the trial
clock, fragments timed like script runs, the page style, the personal link.
"""

from __future__ import annotations

import functools
import time

import streamlit as st

from snapcore.errors import SnapshotError
from study_app.web.timing import RunClock

from .context import current_stage
from .keys import KEY_ATTEMPT, KEY_FLASH, KEY_TRIAL_SHOWN

__all__ = [
    "timed_fragment",
    "widget_key",
    "next_attempt",
    "trial_clock",
    "elapsed_s",
    "flash",
    "show_flash",
    "PAGE_CSS",
    "page_style",
    "resume_link",
    "one_line",
]


def timed_fragment(func):
    """``st.fragment(func)``: a part of a page whose widgets, when they change, rerun
    only that part (not app.py, the other widgets or the page around it), its own runs
    timed like script runs (:mod:`study_app.web.timing`).

    For widgets whose changes only set a value or send a log batch: their runs were 10
    of a participant's 24 full script runs. A fragment's own run knows only what the
    last full run left in the session state; whatever must move the page on calls
    :func:`~study_app.web.screens.answers.leave_fragment_if_moved_on`.
    """

    @functools.wraps(func)
    def run(*args, **kwargs):
        with RunClock(current_stage, fragment=True):
            try:
                return func(*args, **kwargs)
            except SnapshotError as err:  # e.g. a stimulus file changed on disk
                st.error(f"This page cannot be shown: {one_line(err)}")
                return None

    return st.fragment(run)


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
    st.caption(
        "Your personal link: to pause and continue later (in this or another "
        "browser), copy it and open it again."
    )
    link = resume_url(base, session.participant_id)
    st.code(link, language=None, wrap_lines=True)  # whole on a phone, not cut off
    from study_app.web.picker import copy_button

    copy_button(link, key="snapshot.copy_link")


def one_line(err: BaseException) -> str:
    """A participant-facing line for an error (no traceback)."""
    return str(err) if isinstance(err, SnapshotError) else f"{type(err).__name__}: {err}"
