"""Done: thanks, the completion code, and the way back (e.g. to Prolific)."""

from __future__ import annotations

import streamlit as st

from study_app.screens import common


def render() -> None:
    session = common.current_session()
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
