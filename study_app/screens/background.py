"""Background questions (paper §4.4): age band, gender, experience with animation/3D/art."""

from __future__ import annotations

import streamlit as st

from study_app.screens import common
from study_app.session import InvalidAnswer


def render() -> None:
    session = common.current_session()
    choices = session.stimuli.study.background
    st.header("About you")
    st.write("Three short questions before the tasks.")
    common.show_flash()
    with st.form(common.KEY_BG_FORM):
        age = st.selectbox("Your age", choices["age_bands"], index=None,
                           placeholder="Choose an age band", key=common.KEY_BG_AGE)
        gender = st.radio("Your gender", choices["genders"], index=None,
                          key=common.KEY_BG_GENDER)
        exp = st.radio("Your experience with animation, 3D graphics or art",
                       choices["experience"], index=None, key=common.KEY_BG_EXPERIENCE)
        sent = st.form_submit_button("Continue", type="primary")
    if sent:
        try:
            session.submit_background({"age_band": age, "gender": gender, "experience": exp})
        except InvalidAnswer as err:
            st.warning(str(err))
            return
        st.rerun()
