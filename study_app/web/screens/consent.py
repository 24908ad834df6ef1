"""Consent: what the study is, what is recorded; agreeing creates the participant."""

from __future__ import annotations

import streamlit as st

from study_app.design.protocol import consent_text, estimated_minutes
from study_app.session import ParticipantSession, UnknownParticipant
from study_app.web.screens import context, keys
from study_app.web.timing import callback_started


def render() -> None:
    ctx = context.load_context()
    study = ctx.stimuli.study
    st.title(study.title)
    if _refused(ctx):
        return
    if study.description:
        st.markdown(study.description)
    # The duration follows from the stimuli actually served (their animations' lengths).
    minutes = estimated_minutes(
        [sc.n_video_frames / sc.video_fps for sc in ctx.stimuli.scenes.values()]
    )
    st.markdown(consent_text(study, minutes))
    agree = st.checkbox(
        "I have read the information above and agree to take part.", key=keys.KEY_CONSENT_AGREE
    )
    st.button(
        "Start the study",
        key=keys.KEY_CONSENT_START,
        type="primary",
        disabled=not agree,
        on_click=_on_start,
    )


def _on_start() -> None:
    """Register the participant before the run the click causes (which shows the first
    step); a click without the box ticked (a forged one) does nothing."""
    callback_started()
    if st.session_state.get(keys.KEY_CONSENT_AGREE) is not True:
        return
    if st.session_state.get(keys.KEY_PARTICIPANT_ID) and keys.QUERY_PID in st.query_params:
        return  # the second send of a double click: this tab already started
    ctx = context.load_context()
    if _why_closed(ctx) is not None:
        return  # closed (or full) between the page and the click: the next run says so
    # Prolific appends PROLIFIC_PID, STUDY_ID and SESSION_ID to the study link.
    query = {k: st.query_params.get(k) for k in st.query_params.keys()}
    try:
        session = ParticipantSession.start(ctx.store, ctx.stimuli, prolific=query)
    except UnknownParticipant:
        # A Prolific id registered before, whose record cannot go on (withdrawn, or
        # its stimuli gone): the run that follows finds it by the id and says why.
        return
    # The id goes in the URL: a reload, or the same link later, resumes here.
    st.query_params[keys.QUERY_PID] = session.participant_id
    st.session_state[keys.KEY_PARTICIPANT_ID] = session.participant_id


#: What a new participant reads when the researcher closed the study or it is full.
CLOSED_TEXT = {
    "closed": "This study is closed: it is not taking new participants.",
    "full": "This study has all the participants it needs: it is not taking new participants.",
}


def _why_closed(ctx) -> str | None:
    """``"closed"``/``"full"`` for a new participant (study_app.data.monitor), None when
    they may start. A returning Prolific participant is not new: they resume."""
    from study_app.data.monitor import enrolment

    why = enrolment(ctx.store, ctx.stimuli.study.id)
    ppid = st.query_params.get("PROLIFIC_PID")
    if why is not None and ppid and ctx.store.find_prolific(ctx.stimuli.study.id, ppid):
        return None
    return why


def _refused(ctx) -> bool:
    why = _why_closed(ctx)
    if why is not None:
        st.info(CLOSED_TEXT[why])
    return why is not None
