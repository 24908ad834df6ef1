"""Researcher page: live progress, votes, frame histograms, export download, withdrawal.

Behind a token: the page compares what is typed with ``$SNAPSHOT_ADMIN_TOKEN``
(constant-time). Without the variable, or without the right token, it shows nothing
but the token field. Tables and histograms come from :mod:`analysis`
(``analysis.votes``, ``analysis.frames``): the UI layer sits above the analysis, which
reads the store (see :mod:`study_app`).
"""

from __future__ import annotations

import hmac
import os
import tempfile
from pathlib import Path

import streamlit as st

from snapcore.errors import SnapshotError
from study_app.data.pseudonym import Pseudonymiser
from study_app.data.withdraw import withdraw, withdrawal_plan
from study_app.web.screens import context, keys, widgets

#: Seconds between refreshes of the live panels.
REFRESH_S = 10


def _token_ok() -> bool:
    expected = os.environ.get(keys.ENV_ADMIN_TOKEN, "")
    st.header("Researcher")
    if not expected:
        st.info(f"This page is disabled. Start the app with {keys.ENV_ADMIN_TOKEN} set to "
                "open it.")
        return False
    given = st.text_input("Access token", type="password", key=keys.KEY_ADMIN_TOKEN)
    if not given:
        return False
    if not hmac.compare_digest(given.encode(), expected.encode()):
        st.error("Wrong token.")
        return False
    return True


def render() -> None:
    if not _token_ok():
        return
    ctx = context.load_context()
    st.caption(f"Study **{ctx.stimuli.study.id}** · database {ctx.store.url} · stimuli "
               f"{ctx.stimuli.folder.name} (manifest {ctx.stimuli.sha256[:12]}…)")
    _live(ctx)
    _downloads(ctx)
    _withdrawal(ctx)


@st.fragment(run_every=REFRESH_S)
def _live(ctx) -> None:
    p = ctx.store.progress()
    c = st.columns(4)
    c[0].metric("Participants", p["participants"])
    c[1].metric("Completed", p["completed"])
    c[2].metric("Responses", p["responses"])
    c[3].metric("Simulated", p.get("simulated", 0))
    rows = ctx.store.export_rows()
    if not rows:
        st.write("No responses yet.")
        return
    st.subheader("Votes per method (view tasks)")
    st.dataframe(vote_frame(rows, ctx.stimuli.scene_ids), width="stretch")
    st.subheader("Chosen frames (pose tasks)")
    for scene in ctx.stimuli.scene_ids:
        fig = frame_histogram_figure(rows, ctx.stimuli.scenes[scene])
        if fig is not None:
            st.pyplot(fig, clear_figure=True)


def vote_frame(rows: list[dict], order):
    """Votes per scene and method (:mod:`analysis.votes`)."""
    from analysis.load import tidy_responses, view_choices
    from analysis.votes import vote_counts, vote_table

    counts = vote_counts(view_choices(tidy_responses(rows, validate=False)), order=order)
    table = vote_table(counts)
    return table.pivot(index="scene", columns="method", values="votes").reindex(
        index=counts.index, columns=counts.columns)


def frame_histogram_figure(rows: list[dict], sc):
    """Histogram of one scene's chosen motion frames, the algorithm's pick marked."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    chosen = np.array([r["chosen_frame"] for r in rows
                       if r["task"] == "pose" and r["scene"] == sc.scene
                       and r["chosen_frame"] is not None], dtype=float)
    if chosen.size == 0:
        return None
    bins = int(np.clip(round(sc.n_frames / (0.25 * sc.fps)), 10, 60))
    edges = np.linspace(sc.frame_offset - 0.5, sc.frame_offset + sc.n_frames - 0.5, bins + 1)
    import pandas as pd

    from analysis.frames import frame_histogram

    counts, edges = frame_histogram(pd.DataFrame({"scene": sc.scene, "chosen_frame": chosen}), sc)
    fig, ax = plt.subplots(figsize=(7, 1.8))
    ax.bar(edges[:-1], counts, width=np.diff(edges), align="edge", color="#7a9cc6")
    ax.axvline(sc.algorithm_frame, color="#c0392b", lw=2, label="algorithm")
    ax.set_title(f"{sc.scene}: {chosen.size} choices", fontsize=9)
    ax.set_xlabel("motion frame (source numbering)", fontsize=8)
    ax.tick_params(labelsize=7)
    ax.legend(fontsize=7, loc="upper right")
    fig.tight_layout()
    return fig


def _downloads(ctx) -> None:
    from study_app.data.export import write_export

    st.subheader("Export")
    # Pseudonymised, as every export (the raw ids only from `snapshot export --identifiers`).
    rows = Pseudonymiser(ctx.store).records(ctx.store.export_rows())
    with tempfile.TemporaryDirectory() as tmp:
        for fmt, mime in (("csv", "text/csv"), ("jsonl", "application/x-ndjson")):
            path = Path(tmp) / f"responses.{fmt}"
            write_export(rows, path)
            st.download_button(f"Download responses ({fmt.upper()}, {len(rows)} rows)",
                               path.read_bytes(), file_name=f"{ctx.stimuli.study.id}-responses.{fmt}",
                               mime=mime, key=f"{keys.KEY_DOWNLOAD}.{fmt}")


#: The ids a withdrawal can be asked by: label → keyword of study_app.data.withdraw.withdraw.
WITHDRAW_BY = {"Participant link id (pid=…)": "participant_id", "Prolific ID": "prolific_pid"}


def _withdrawal(ctx) -> None:
    """Delete a participant's data when they withdraw, after a confirmation."""
    st.subheader("Withdraw a participant")
    st.caption("Deletes their responses, events and background answers; only a record "
               "that they withdrew is kept, and their link says so.")
    label = st.radio("They gave their", list(WITHDRAW_BY), key=keys.KEY_WITHDRAW_KIND,
                     horizontal=True)
    given = st.text_input("Id", key=keys.KEY_WITHDRAW_ID).strip()
    if not given:
        return
    which = {WITHDRAW_BY[label]: given, "study_id": ctx.stimuli.study.id}
    try:
        plan = withdrawal_plan(ctx.store, **which)
    except SnapshotError as err:
        st.warning(widgets.one_line(err))
        return
    for p in plan:
        st.warning(f"Participant **{p['participant_id']}** will be deleted: "
                   f"{p['n_responses']} responses, {p['n_events']} events"
                   + (", background answers" if p["has_background"] else "")
                   + ". This cannot be undone.")
    sure = st.checkbox("Yes, delete this participant's data",
                       key=f"{keys.KEY_WITHDRAW_CONFIRM}.{given}")
    if st.button("Withdraw", key=keys.KEY_WITHDRAW_BUTTON, type="primary", disabled=not sure):
        try:
            done = withdraw(ctx.store, by="page", **which)
        except SnapshotError as err:
            st.error(widgets.one_line(err))
            return
        for w in done:
            st.success(f"Withdrew participant {w.participant_id}: deleted {w.n_responses} "
                       f"responses and {w.n_events} events.")


if __name__ == "__main__":  # run as the page script by st.navigation (see app.py)
    render()
