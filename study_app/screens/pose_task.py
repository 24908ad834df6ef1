"""Pose task: watch the animation, pick the frame that best tells the action, confirm."""

from __future__ import annotations

import streamlit as st

from study_app.picker import frame_picker
from study_app.screens import common
from study_app.session import InvalidAnswer


def render() -> None:
    session = common.current_session()
    trial = session.current_trial
    sc = session.stimuli.scenes[trial.scene]
    n_pose = sum(t.task == "pose" for t in session.plan)
    st.header(f"Animation {trial.index + 1} of {n_pose}")
    st.markdown(
        "Watch the animation (press **Play**; you can replay it). Then find the **one "
        "moment that best shows what the figure is doing** — pause there, use the "
        "**◀ 1 / 1 ▶** buttons (or the arrow keys) to step frame by frame — and press "
        "**Confirm this frame**.")
    common.show_flash()
    common.trial_clock(session, trial)
    use_frames = (session.stimuli.study.picker == "frames"
                  or st.session_state.get(common.KEY_FRAMES_FALLBACK, False))
    if use_frames:
        answer = _frames_picker(sc, trial)
    else:
        answer = frame_picker(sc.video, fps=sc.video_fps, n_frames=sc.n_video_frames,
                              trial=trial.index, key=common.widget_key(common.KEY_PICKER, trial))
        if answer and "error" in answer:
            # This browser cannot play the video: offer the frames instead.
            st.session_state[common.KEY_FRAMES_FALLBACK] = True
            st.rerun()
    if answer is None:
        return
    try:
        session.submit_pose(answer.get("trial"), answer.get("frame"),
                            response_time_s=common.elapsed_s(session, trial),
                            events=answer.get("events") or ())
    except InvalidAnswer as err:
        common.next_attempt(trial)
        common.flash("error", str(err))
    st.rerun()


def _frames_picker(sc, trial):
    """Fallback picker: a slider over the pre-extracted frames (pure Streamlit)."""
    n = sc.n_video_frames
    k = st.slider("Frame", min_value=1, max_value=n, value=1,
                  key=common.widget_key(common.KEY_FRAME_SLIDER, trial))
    st.image(str(sc.frames[k - 1]), caption=f"Frame {k} / {n}", width="stretch")
    if st.button("Confirm this frame", key=common.widget_key(common.KEY_FRAME_CONFIRM, trial),
                 type="primary"):
        return {"trial": trial.index, "frame": k - 1, "events": []}
    return None
