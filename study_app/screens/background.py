"""Background questions (paper §4.4): age band, gender, experience with animation/3D/art."""

from __future__ import annotations

import streamlit as st

from study_app.screens import common
from study_app.session import InvalidAnswer

#: The gender choice that opens a text box (its text is stored as ``gender_self``).
SELF_DESCRIBE = "Prefer to self-describe"


def render() -> None:
    session = common.current_session()
    choices = session.stimuli.study.background
    st.header("About you")
    st.write("Three short questions before the tasks.")
    common.show_flash()
    # Not a form: "Prefer to self-describe" must open its text box as soon as it is
    # chosen. Every missing answer is named at the top of the page, where it is seen.
    with st.container(key=common.KEY_BG_FORM):
        age = st.selectbox("Your age", choices["age_bands"], index=None,
                           placeholder="Choose an age band", key=common.KEY_BG_AGE)
        gender = st.radio("Your gender", choices["genders"], index=None,
                          key=common.KEY_BG_GENDER)
        self_described = None
        if gender == SELF_DESCRIBE:
            self_described = st.text_input("How do you describe your gender? (optional)",
                                           max_chars=100, key=common.KEY_BG_GENDER_SELF)
        exp = st.radio("Your experience with animation, 3D graphics or art",
                       choices["experience"], index=None, key=common.KEY_BG_EXPERIENCE)
        sent = st.button("Continue", type="primary", key=common.KEY_BG_SUBMIT)
    if sent:
        answers = {"age_band": age, "gender": gender, "experience": exp}
        if self_described and self_described.strip():
            answers["gender_self"] = self_described.strip()
        try:
            common.answer_outcome(session.submit_background(answers))
        except InvalidAnswer as err:
            # Shown at the top on the next run, where it is seen without scrolling.
            common.flash("warning", str(err))
        st.rerun()
