"""Shown for a participant link that is malformed, unknown or from another study, or
whose participant withdrew (their data were deleted: the page says so), or whose
stimuli are gone (their answers so far are stored: the page says so)."""

from __future__ import annotations

import streamlit as st

from study_app.web.screens import keys


def render() -> None:
    if st.session_state.get(keys.KEY_WITHDRAWN):
        st.header("Your data were withdrawn")
        st.info(st.session_state.get(keys.KEY_PROBLEM))
        return
    if st.session_state.get(keys.KEY_ANSWERS_KEPT):
        st.header("This session cannot continue")
        st.warning(st.session_state.get(keys.KEY_PROBLEM))
        return
    st.header("This link does not work")
    st.error(st.session_state.get(keys.KEY_PROBLEM) or "Unknown participant.")
    st.write(
        "Nothing was recorded. If you were given a personal link, please use it "
        "exactly as you received it."
    )
    # Only a bad personal id can be dropped for a fresh start; a malformed Prolific
    # link must be opened again from Prolific (starting without it would lose who
    # the participant is).
    if keys.QUERY_PID in st.query_params and st.button("Start a new session", key=keys.KEY_RESTART):
        del st.query_params[keys.QUERY_PID]
        st.rerun()
