"""The one attention check."""

from __future__ import annotations

import streamlit as st

from study_app.web.picker import answer_button, pressed
from study_app.web.screens import answers, context, keys, widgets


def render() -> None:
    session = context.current_session()
    trial = session.current_trial
    att = session.stimuli.study.attention
    st.header("One more question")
    widgets.show_flash()
    widgets.trial_clock(session, trial)
    _choice(att["question"], tuple(att["options"]))
    answer_button(
        "Continue",
        key=keys.KEY_ATTENTION_SUBMIT,
        tab_key=f"{session.participant_id}:{trial.index}",
        on_press=_on_submit,
        args=(session.participant_id, trial.index),
        testid="attention-submit",
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
    client = (pressed(keys.KEY_ATTENTION_SUBMIT) or {}).get("client")
    answers.store_answer(
        session,
        trial.index,
        lambda: session.submit_attention(
            trial.index, choice, response_time_s=widgets.elapsed_s(session, trial), client=client
        ),
        lambda err: widgets.flash("warning", str(err)),
    )
