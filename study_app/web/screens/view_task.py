"""View task: three views of the selected pose in seeded positions; pick the clearest."""

from __future__ import annotations

import streamlit as st

from study_app.web.picker import chosen, skipped, view_chooser
from study_app.web.screens import answers, context, keys, widgets


def render() -> None:
    session = context.current_session()
    trial = session.current_trial
    views = [t for t in session.plan if t.task == "view"]
    k = views.index(trial) + 1
    n_pictures = len(trial.shown_order or ())
    st.header(f"Pictures {k} of {len(views)}")
    st.markdown(
        f"Here is one moment of an animation, seen from {_NUMBERS.get(n_pictures, n_pictures)} "
        "directions. **Which picture shows best what the figure is doing?** Click "
        "**Choose** under it."
    )
    widgets.show_flash()
    widgets.trial_clock(session, trial)
    # Pictures only: the position → method map stays here (submit_view applies it).
    widget = widgets.widget_key(keys.KEY_CHOOSER, trial)
    failed = view_chooser(
        [path for _, path in session.view_choices(trial)],
        trial=trial.index,
        key=widget,
        min_answer_s=session.stimuli.study.min_answer_s,
        on_choice=_on_choice,
        args=(session.participant_id, trial.index, widget),
        tab_key=f"{session.participant_id}:{trial.index}",
        on_skip=_on_skip,
    )
    if failed is not None and "failed" in failed:
        # Pictures that did not load after retries: the buttons stay off (the page offers
        # to try again, or to skip the question), nothing is answered, and the trial
        # records it (an empty report: they loaded again, their positions are free).
        session.record_media_failure(
            failed.get("trial"), "image", failed["failed"], failed.get("tab")
        )


#: How the instructions say the number of pictures shown.
_NUMBERS = {2: "two", 3: "three"}


def _on_skip(pid: str, trial_index: int, widget: str) -> None:
    """ "I can't see the pictures": the trial stored as skipped, before the run it causes."""
    answer = skipped(widget)
    session = context.answering_session(pid)
    if answer is None or session is None:
        return
    trial = session.plan[trial_index]
    answers.store_answer(
        session,
        trial.index,
        lambda: session.skip_view(
            answer.get("trial"),
            response_time_s=widgets.elapsed_s(session, trial),
            client=answer.get("client"),
        ),
        lambda err: answers.retry_trial(trial, err),
    )


def _on_choice(pid: str, trial_index: int, widget: str) -> None:
    """The chosen picture, stored before the run it causes (which shows the next step)."""
    answer = chosen(widget)
    session = context.answering_session(pid)
    if answer is None or session is None:
        return
    trial = session.plan[trial_index]
    answers.store_answer(
        session,
        trial.index,
        lambda: session.submit_view(
            answer.get("trial"),
            answer.get("position"),
            response_time_s=widgets.elapsed_s(session, trial),
            client=answer.get("client"),
        ),
        lambda err: answers.retry_trial(trial, err),
        resend=bool(answer.get("resend")),
    )
