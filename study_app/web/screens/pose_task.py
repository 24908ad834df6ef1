"""Pose task: watch the animation, pick the frame that best tells the action, confirm."""

from __future__ import annotations

import streamlit as st

from study_app.session import WATCHED_ENOUGH
from study_app.web.picker import answer_button, confirmed, frame_picker, pressed
from study_app.web.screens import answers, context, keys, widgets

#: Instructions for the video player, and for the frame slider (the fallback when the
#: browser cannot play the video, or the study's ``picker = "frames"``).
PLAYER_TEXT = (
    "Watch the animation (press **Play** or the space bar; you can replay it){watch}. Then "
    "find the **one moment that best shows what the figure is doing** — pause there, use "
    "the **◀ 1 / 1 ▶** buttons (or the ← → arrow keys) to step frame by frame — and press "
    "**Confirm this frame**."
)
WATCH_TEXT = " — **Confirm** opens once you have seen it to the end"
SLIDER_TEXT = (
    "Move the **Frame** slider to go through the animation picture by picture. Find the "
    "**one moment that best shows what the figure is doing** and press **Confirm this "
    "frame**."
)
#: Said before the slider's instructions when it stands in for a video the browser
#: could not play (one paragraph: the frame and Confirm below keep their room).
VIDEO_FAILED_TEXT = (
    "⚠️ **The animation could not be played in your browser**, so here it is picture by "
    "picture instead. "
)


def render() -> None:
    session = context.current_session()
    trial = session.current_trial
    sc = session.stimuli.scenes[trial.scene]
    n_pose = sum(t.task == "pose" for t in session.plan)
    st.header(f"Animation {trial.index + 1} of {n_pose}")
    study = session.stimuli.study
    failed = (session.participant_id, trial.index) in st.session_state.get(
        keys.KEY_FRAMES_FALLBACK, set()
    )
    use_frames = session.stimuli.study.picker == "frames" or failed
    # The instructions name only the controls the participant has (the slider when the
    # browser cannot play the video).
    st.markdown(
        (VIDEO_FAILED_TEXT if failed else "") + SLIDER_TEXT
        if use_frames
        else PLAYER_TEXT.format(watch=WATCH_TEXT if study.require_watch else "")
    )
    widgets.show_flash()
    widgets.trial_clock(session, trial)
    if not use_frames:
        _player(session.participant_id, trial.index)
        return
    _frames_picker(session.participant_id, sc, trial)


@widgets.timed_fragment
def _player(pid: str, trial_index: int) -> None:
    """The video player, a fragment: its log batches (sent as the participant plays,
    pauses, seeks) rerun only the player, which stores them; Confirm stores the answer
    in its callback and reruns the whole page, which shows the next step."""
    session = answers.leave_fragment_if_moved_on(pid, trial_index)
    trial = session.plan[trial_index]
    sc = session.stimuli.scenes[trial.scene]
    study = session.stimuli.study
    # Where the participant was (frame, share watched) before a reload: read once per
    # trial and browser session (the player keeps its own state after that), not on
    # every rerun of the page. Keyed by the player's widget key, so a player remounted
    # after a refused answer starts where the log says.
    widget = widgets.widget_key(keys.KEY_PICKER, trial)
    starts = st.session_state.setdefault(keys.KEY_PICKER_START, {})
    key = (pid, widget)
    if key not in starts:
        starts[key] = session.watch_record(trial.index)
    frame, watched, ranges = starts[key]
    answer = frame_picker(
        sc.videos,
        fps=sc.video_fps,
        n_frames=sc.n_video_frames,
        trial=trial.index,
        key=widget,
        start_frame=frame,
        watched=watched,
        watched_ranges=ranges,
        require_watch=study.require_watch,
        watch_min=WATCHED_ENOUGH,
        min_answer_s=study.min_answer_s,
        log_key=f"{pid}:{trial.index}",
        on_confirm=_on_confirm,
        args=(pid, trial.index, widget),
    )
    if answer and "error" in answer:
        # The video did not play after retries: this trial offers the frames instead
        # (the page's instructions change too, the answer says "slider"), and the
        # failure is recorded with the trial.
        session.record_media_failure(answer.get("trial"), "video")
        st.session_state.setdefault(keys.KEY_FRAMES_FALLBACK, set()).add((pid, trial.index))
        st.rerun(scope="app")
    if answer and "log" in answer:
        # A batch of the player's log, stored as it happens; the player stays.
        session.record_picker_events(answer.get("trial"), answer["log"])


def _on_confirm(pid: str, trial_index: int, widget: str) -> None:
    """The player's Confirm, stored before the run it causes (which shows the next step)."""
    answer = confirmed(widget)
    session = context.answering_session(pid)
    if answer is None or session is None:
        return
    _submit(session, session.plan[trial_index], answer)


def _submit(session, trial, answer: dict) -> None:
    """Store a pose answer for ``trial`` (the trial its page showed); a refused answer
    remounts the picker with the reason above it."""
    answers.store_answer(
        session,
        trial.index,
        lambda: session.submit_pose(
            answer.get("trial"),
            answer.get("frame"),
            response_time_s=widgets.elapsed_s(session, trial),
            events=answer.get("events") or (),
            watched=answer.get("watched"),
            ranges=answer.get("ranges"),
            client=answer.get("client"),
        ),
        lambda err: answers.retry_trial(trial, err),
        resend=bool(answer.get("resend")),
    )


def _frames_picker(pid: str, sc, trial) -> None:
    """Fallback picker: a slider over the pre-extracted frames, the frame (its height
    capped so Confirm stays on screen: ``SLIDER_CSS``) and Confirm, which reports what
    the answer was given on as the player does."""
    n = sc.n_video_frames
    k = st.slider(
        "Frame",
        min_value=1,
        max_value=n,
        value=1,
        key=widgets.widget_key(keys.KEY_FRAME_SLIDER, trial),
    )
    st.html(SLIDER_CSS)
    st.image(str(sc.frames[k - 1]), caption=f"Frame {k} / {n}", width="stretch")
    answer_button(
        "Confirm this frame",
        key=widgets.widget_key(keys.KEY_FRAME_CONFIRM, trial),
        tab_key=f"{pid}:{trial.index}",
        on_press=_on_slider_confirm,
        args=(pid, trial.index),
        testid="slider-confirm",
    )


#: The slider's frame no taller than what a 1280×720 window leaves under the page's
#: header, instructions and slider, so Confirm below it stays on screen (it was at
#: y = 894 px at 1366×768).
SLIDER_CSS = """<style>
[data-testid=stImage] img { max-height: max(8rem, calc(100vh - 28rem)); width: auto;
  max-width: 100%; object-fit: contain; }
</style>"""


def _on_slider_confirm(pid: str, trial_index: int) -> None:
    """The slider's Confirm, stored before the run it causes (which shows the next step)."""
    session = context.answering_session(pid)
    if session is None:
        return
    trial = session.plan[trial_index]
    k = st.session_state.get(widgets.widget_key(keys.KEY_FRAME_SLIDER, trial), 1)
    press = pressed(widgets.widget_key(keys.KEY_FRAME_CONFIRM, trial)) or {}
    _submit(
        session,
        trial,
        {"trial": trial.index, "frame": int(k) - 1, "events": [], "client": press.get("client")},
    )
