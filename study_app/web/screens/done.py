"""Done: thanks, the completion code, the way back (e.g. to Prolific), how to withdraw."""

from __future__ import annotations

import streamlit as st

from study_app.design.protocol import DEFAULT_CONTACT
from study_app.web.screens import context


def render() -> None:
    session = context.current_session()
    code = session.finish()
    st.header("Thank you!")
    st.success("All your answers are saved. You have finished the study.")
    st.markdown("Your completion code:")
    st.code(code, language=None)
    url = session.redirect(code)
    if url:
        st.link_button("Return to complete your submission", url, type="primary")
    else:
        st.write("You can close this page now.")
    # The consent promised withdrawal after the end too: say whom to write to, with what.
    contact = session.stimuli.study.contact or DEFAULT_CONTACT
    st.caption(
        f"To withdraw later and have your answers deleted, write to {contact} with "
        f"your participant id `{session.participant_id}` (or your Prolific ID)."
    )
