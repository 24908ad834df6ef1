"""The one attention check."""

from __future__ import annotations

import streamlit as st

from study_app.web.screens import answers, context, keys, widgets


def render() -> None:
    session = context.current_session()
    trial = session.current_trial
    att = session.stimuli.study.attention
    st.header("One more question")
    widgets.show_flash()
    widgets.trial_clock(session, trial)
    _choice(att["question"], tuple(att["options"]))
    st.button(
        "Continue",
        key=keys.KEY_ATTENTION_SUBMIT,
        type="primary",
        on_click=_on_submit,
        args=(session.participant_id, trial.index),
    )


@widgets.timed_fragment
def _choice(question: str, options: tuple) -> None:
    """The options, a fragment: choosing one reruns only them; Continue (outside) moves
    the page on."""
    st.radio(question, options, index=None, key=keys.KEY_ATTENTION_CHOICE)


def _on_submit(pid: str, trial_index: int) -> None:
    """Store the answer before the run the click causes (which shows the next step)."""
    session = context.answering_session(pid)
    if session is None:
        return
    trial = session.plan[trial_index]
    choice = st.session_state.get(keys.KEY_ATTENTION_CHOICE)
    if choice is None:
        widgets.flash("warning", "Please choose one of the options.")
        return
    answers.store_answer(
        session,
        trial.index,
        lambda: session.submit_attention(
            trial.index, choice, response_time_s=widgets.elapsed_s(session, trial)
        ),
        lambda err: widgets.flash("warning", str(err)),
    )
