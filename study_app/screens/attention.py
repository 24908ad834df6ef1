"""The one attention check."""

from __future__ import annotations

import streamlit as st

from study_app.screens import common
from study_app.session import InvalidAnswer


def render() -> None:
    session = common.current_session()
    trial = session.current_trial
    att = session.stimuli.study.attention
    st.header("One more question")
    common.show_flash()
    common.trial_clock(session, trial)
    choice = st.radio(att["question"], att["options"], index=None,
                      key=common.KEY_ATTENTION_CHOICE)
    if st.button("Continue", key=common.KEY_ATTENTION_SUBMIT, type="primary"):
        if choice is None:
            st.warning("Please choose one of the options.")
            return
        try:
            stored = session.submit_attention(trial.index, choice,
                                              response_time_s=common.elapsed_s(session, trial))
            common.answer_outcome(stored)
        except InvalidAnswer as err:
            st.warning(str(err))
            return
        st.rerun()
