"""Background questions (paper §4.4): age band, gender, experience with animation/3D/art."""

from __future__ import annotations

import streamlit as st

from study_app.web.screens import answers, context, keys, widgets

#: The gender choice that opens a text box (its text is stored as ``gender_self``).
SELF_DESCRIBE = "Prefer to self-describe"


def render() -> None:
    session = context.current_session()
    choices = session.stimuli.study.background
    st.header("About you")
    st.write("Three short questions before the tasks.")
    widgets.show_flash()
    # Not a form: "Prefer to self-describe" must open its text box as soon as it is
    # chosen. The questions are a fragment (choosing an answer reruns only them); the
    # button is outside it: its callback reads the answers by the widgets' keys and
    # the whole page moves on. Every missing answer is named at the top of the page.
    with st.container(key=keys.KEY_BG_FORM):
        _questions(choices)
        st.button(
            "Continue",
            type="primary",
            key=keys.KEY_BG_SUBMIT,
            on_click=_on_submit,
            args=(session.participant_id,),
        )


@widgets.timed_fragment
def _questions(choices: dict) -> None:
    st.selectbox(
        "Your age",
        choices["age_bands"],
        index=None,
        placeholder="Choose an age band",
        key=keys.KEY_BG_AGE,
    )
    gender = st.radio("Your gender", choices["genders"], index=None, key=keys.KEY_BG_GENDER)
    if gender == SELF_DESCRIBE:
        st.text_input(
            "How do you describe your gender? (optional)",
            max_chars=100,
            key=keys.KEY_BG_GENDER_SELF,
        )
    st.radio(
        "Your experience with animation, 3D graphics or art",
        choices["experience"],
        index=None,
        key=keys.KEY_BG_EXPERIENCE,
    )


def _on_submit(pid: str) -> None:
    """Store the answers before the run the click causes (which shows the next step)."""
    session = context.answering_session(pid)
    if session is None:
        return
    get = st.session_state.get
    given = {
        "age_band": get(keys.KEY_BG_AGE),
        "gender": get(keys.KEY_BG_GENDER),
        "experience": get(keys.KEY_BG_EXPERIENCE),
    }
    self_described = get(keys.KEY_BG_GENDER_SELF) if given["gender"] == SELF_DESCRIBE else None
    if isinstance(self_described, str) and self_described.strip():
        given["gender_self"] = self_described.strip()
    # A refusal is shown at the top of the page, where it is seen without scrolling.
    answers.store_answer(
        session,
        "background",
        lambda: session.submit_background(given),
        lambda err: widgets.flash("warning", str(err)),
    )
