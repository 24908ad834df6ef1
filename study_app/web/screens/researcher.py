"""Researcher page: monitor, votes, recruitment switches, exclusion, withdrawal,
completion codes and every download.

Behind a token: the page compares what is typed with ``$SNAPSHOT_ADMIN_TOKEN``
(constant-time). Without the variable, with one shorter than 16 characters, or
without the right token, it shows nothing but the token field. Wrong tokens are logged
and limited (:mod:`study_app.web.screens.token_guard`): after 5 within 60 seconds (from
any browser, this server process) every try, right or wrong, is refused for 120 seconds.

Every action (withdraw, exclude, the recruitment switches) runs in its button's
callback, before the page is drawn again: the tables and the downloads drawn after it
already show its effect (a download offered after a withdrawal never holds the
withdrawn person's rows). Tables and histograms come from :mod:`analysis`: the UI layer
sits above the analysis, which reads the store (see :mod:`study_app`).
"""

from __future__ import annotations

import hmac
import io
import os
import tempfile
import time
import zipfile
from pathlib import Path

import streamlit as st

from snapcore.errors import SnapshotError
from study_app.data import monitor
from study_app.data.pseudonym import OPEN_DROPPED, PSEUDONYM_RE, Pseudonymiser
from study_app.data.withdraw import (
    withdraw,
    withdrawal_counts,
    withdrawal_plan,
    withdrawals_of_study,
)
from study_app.web.screens import context, keys, widgets
from study_app.web.screens import token_guard as guard

#: Seconds between refreshes of the live panels.
REFRESH_S = 10
#: Widget keys of the sections added here (keys.py holds the older ones).
K = {
    name: f"researcher.{name}"
    for name in (
        "message",
        "exclude.id",
        "exclude.reason",
        "exclude.button",
        "cap.on",
        "cap.n",
        "closed",
        "controls.button",
    )
}


def _token_ok() -> bool:
    expected = os.environ.get(keys.ENV_ADMIN_TOKEN, "")
    st.header("Researcher")
    if not expected:
        st.info(f"This page is disabled. Start the app with {keys.ENV_ADMIN_TOKEN} set to open it.")
        return False
    if len(expected) < guard.MIN_TOKEN_CHARS:
        st.error(
            f"This page is disabled: {keys.ENV_ADMIN_TOKEN} has {len(expected)} "
            f"characters; use at least {guard.MIN_TOKEN_CHARS} random ones (e.g. "
            "python -c 'import secrets; print(secrets.token_urlsafe(24))')."
        )
        return False
    given = st.text_input("Access token", type="password", key=keys.KEY_ADMIN_TOKEN)
    if not given:
        return False
    now = time.monotonic()
    wait = guard.locked(now)
    if wait > 0:
        st.error(f"Too many wrong tokens: the page is locked for {wait:.0f} more seconds.")
        return False
    if not hmac.compare_digest(given.encode(), expected.encode()):
        n = guard.failed(now)
        st.error(
            f"Wrong token. {n} of {guard.MAX_FAILURES} wrong tries allowed in "
            f"{guard.FAILURE_WINDOW_S:.0f} s."
            if n
            else f"Wrong token. Too many wrong tokens: the page is locked for "
            f"{guard.LOCKOUT_S:.0f} seconds."
        )
        return False
    return True


def render() -> None:
    if not _token_ok():
        return
    ctx = context.load_context()
    study = ctx.stimuli.study
    st.caption(
        f"Study **{study.id}** · database {ctx.store.url} · stimuli "
        f"{ctx.stimuli.folder.name} (manifest {ctx.stimuli.sha256[:12]}…)"
    )
    for kind, text in st.session_state.pop(K["message"], []):
        getattr(st, kind)(text)
    _live(ctx)
    _recruitment(ctx)
    _exclusion(ctx)
    _withdrawal(ctx)
    _completion_codes(ctx)
    _downloads(ctx)


def _say(kind: str, text: str) -> None:
    """Show ``text`` on the page's next run (a callback cannot draw)."""
    st.session_state.setdefault(K["message"], []).append((kind, text))


def _n_trials(ctx) -> int:
    from study_app.design.protocol import trial_plan

    return len(trial_plan(ctx.stimuli.scene_ids, 0, shown=dict(ctx.stimuli.view_groups)))


# ----------------------------------------------------------------------------- live
@st.fragment(run_every=REFRESH_S)
def _live(ctx) -> None:
    rows = monitor.monitor_rows(ctx.store, ctx.stimuli.study.id, n_trials=_n_trials(ctx))
    states = {s: sum(r["state"] == s for r in rows) for s in monitor.STATES}
    p = ctx.store.progress()
    c = st.columns(7)
    c[0].metric("Participants", len(rows))
    c[1].metric("Finished", states["finished"])
    c[2].metric("In progress", states["started"])
    c[3].metric("Timed out", states["timed out"])
    c[4].metric("Excluded", states["excluded"])
    # the same counts as `snapshot analyze`'s "Who was left out" (monitor.participation)
    c[5].metric("Withdrawn", withdrawal_counts(ctx.store).get(ctx.stimuli.study.id, 0))
    c[6].metric("Responses", p["responses"])
    st.subheader("Monitor")
    st.caption(
        f"Each participant (newest first; pseudonyms as in the exports): state, the "
        f"step they are on, seconds since their last answer or player event. "
        f"Timed out: no activity for {monitor.TIMEOUT_S // 60} minutes."
    )
    if rows:
        import pandas as pd

        anon = Pseudonymiser(ctx.store)
        table = pd.DataFrame(
            [
                {
                    "participant": anon.record(
                        {"participant_id": r["participant_id"], "study_id": ctx.stimuli.study.id}
                    )["participant_id"],
                    "state": r["state"],
                    "step": r["step"],
                    "idle s": r["idle_s"],
                    "last activity (UTC)": r["last_activity"].strftime("%Y-%m-%d %H:%M:%S"),
                    "started (UTC)": r["started_at"].strftime("%Y-%m-%d %H:%M:%S"),
                    "exclusion reason": r["reason"] or "",
                }
                for r in rows
            ]
        )
        st.dataframe(table, hide_index=True, width="stretch")
    _votes(ctx)


def _analysed_rows(ctx) -> list[dict]:
    """The rows the report analyses: participants who finished, none excluded (the
    state "finished" of :func:`monitor.participant_state`, as ``snapshot analyze``)."""
    done = {
        p["participant_id"]
        for p in monitor.with_exclusions(ctx.store, ctx.store.participants())
        if p["study_id"] == ctx.stimuli.study.id
        and monitor.participant_state(p["completed_at"], p["excluded"]) == "finished"
    }
    return [r for r in ctx.store.export_rows() if r["participant_id"] in done]


def _votes(ctx) -> None:
    rows = _analysed_rows(ctx)
    if not rows:
        st.write("No finished participants yet.")
        return
    n = len({r["participant_id"] for r in rows})
    st.subheader("Votes per method (view tasks)")
    st.caption(f"{n} participants who finished and are not excluded (as `snapshot analyze`).")
    st.table(vote_frame(rows, ctx.stimuli.scene_ids))
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
        index=counts.index, columns=counts.columns
    )


def frame_histogram_figure(rows: list[dict], sc):
    """Histogram of one scene's chosen motion frames, the algorithm's pick marked."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np
    import pandas as pd

    from analysis.frames import frame_histogram

    chosen = np.array(
        [
            r["chosen_frame"]
            for r in rows
            if r["task"] == "pose" and r["scene"] == sc.scene and r["chosen_frame"] is not None
        ],
        dtype=float,
    )
    if chosen.size == 0:
        return None
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


# ----------------------------------------------------------------------------- recruitment
def _recruitment(ctx) -> None:
    sid = ctx.stimuli.study.id
    now = monitor.controls(ctx.store, sid)
    st.subheader("Recruitment")
    state = ("closed" if now["closed"] else "open") + (
        f", cap {now['cap']} participants" if now["cap"] is not None else ", no cap"
    )
    st.caption(
        f"Now: **{state}**. Closed or full, the study link tells new participants so; "
        "those already in it (and a returning Prolific id) go on."
    )
    st.session_state.setdefault(K["closed"], now["closed"])
    st.session_state.setdefault(K["cap.on"], now["cap"] is not None)
    st.session_state.setdefault(K["cap.n"], now["cap"] if now["cap"] is not None else 100)
    c = st.columns(3)
    c[0].toggle("Close the study", key=K["closed"])
    c[1].checkbox("Cap the participants", key=K["cap.on"])
    c[2].number_input("Most participants", min_value=0, step=1, key=K["cap.n"])
    st.button("Save recruitment", key=K["controls.button"], on_click=_save_controls, args=(ctx,))


def _save_controls(ctx) -> None:
    closed = bool(st.session_state.get(K["closed"]))
    cap = int(st.session_state[K["cap.n"]]) if st.session_state.get(K["cap.on"]) else None
    try:
        monitor.set_controls(ctx.store, ctx.stimuli.study.id, closed=closed, cap=cap)
    except SnapshotError as err:
        _say("error", widgets.one_line(err))
        return
    _say(
        "success",
        "Recruitment saved: "
        + ("closed" if closed else "open")
        + (f", cap {cap}" if cap is not None else ", no cap")
        + ".",
    )


# ----------------------------------------------------------------------------- exclusion
def _resolve(ctx, given: str) -> str:
    """A participant link id, or the one a pseudonym names."""
    import re

    from study_app.data.pseudonym import participants_by_pseudonym

    if re.match(PSEUDONYM_RE, given):
        found = participants_by_pseudonym(ctx.store, given, study_id=ctx.stimuli.study.id)
        if len(found) != 1:
            raise SnapshotError(f"no participant of this study has the pseudonym {given}")
        return found[0]
    return given


def _exclusion(ctx) -> None:
    st.subheader("Exclude a participant from the analysis")
    st.caption(
        "Keeps their data, with the reason; the page's tables and `snapshot analyze` "
        "leave them out (to delete the data, withdraw them below)."
    )
    c = st.columns([2, 3])
    c[0].text_input("Participant (link id or pseudonym p-…)", key=K["exclude.id"])
    c[1].text_input("Reason", key=K["exclude.reason"])
    st.button("Exclude", key=K["exclude.button"], on_click=_do_exclude, args=(ctx,))


def _do_exclude(ctx) -> None:
    given = (st.session_state.get(K["exclude.id"]) or "").strip()
    reason = st.session_state.get(K["exclude.reason"]) or ""
    try:
        if not given:
            raise SnapshotError("give the participant's link id or pseudonym")
        monitor.exclude(ctx.store, _resolve(ctx, given), reason, study_id=ctx.stimuli.study.id)
    except SnapshotError as err:
        _say("error", widgets.one_line(err))
        return
    st.session_state[K["exclude.id"]] = ""
    st.session_state[K["exclude.reason"]] = ""
    _say("success", f"Excluded {given} from the analysis ({' '.join(reason.split())}).")


# ----------------------------------------------------------------------------- withdrawal
#: The ids a withdrawal can be asked by: label → keyword of study_app.data.withdraw.withdraw.
WITHDRAW_BY = {
    "Participant link id (pid=…)": "participant_id",
    "Prolific ID": "prolific_pid",
    "Pseudonym in a shared dataset (p-…)": "pseudonym",
}


def _which(ctx, given: str) -> dict:
    label = st.session_state.get(keys.KEY_WITHDRAW_KIND) or next(iter(WITHDRAW_BY))
    return {WITHDRAW_BY[label]: given, "study_id": ctx.stimuli.study.id}


def _withdrawal(ctx) -> None:
    """Delete a participant's data when they withdraw, after a confirmation."""
    st.subheader("Withdraw a participant")
    st.caption(
        "Deletes their responses, events and background answers; only a record "
        "that they withdrew is kept, and their link says so."
    )
    done = withdrawals_of_study(ctx.store, ctx.stimuli.study.id)
    if done:
        st.caption(f"Withdrawals so far: {len(done)} (who finished is still in Completion codes)")
        st.dataframe(
            [
                {
                    "withdrawn (UTC)": w.withdrawn_at.strftime("%Y-%m-%d %H:%M"),
                    "by": w.requested_by,
                    "link id": w.participant_id,
                    "Prolific id": w.prolific_pid or "",
                }
                for w in done
            ],
            hide_index=True,
            width="stretch",
        )
    st.radio("They gave their", list(WITHDRAW_BY), key=keys.KEY_WITHDRAW_KIND, horizontal=True)
    given = st.text_input("Id", key=keys.KEY_WITHDRAW_ID).strip()
    if not given:
        return
    try:
        plan = withdrawal_plan(ctx.store, **_which(ctx, given))
    except SnapshotError as err:
        st.warning(widgets.one_line(err))
        return
    for p in plan:
        st.warning(
            f"Participant **{p['participant_id']}** will be deleted: "
            f"{p['n_responses']} responses, {p['n_events']} events"
            + (", background answers" if p["has_background"] else "")
            + ". This cannot be undone."
        )
    sure = st.checkbox(
        "Yes, delete this participant's data", key=f"{keys.KEY_WITHDRAW_CONFIRM}.{given}"
    )
    st.button(
        "Withdraw",
        key=keys.KEY_WITHDRAW_BUTTON,
        type="primary",
        disabled=not sure,
        on_click=_do_withdraw,
        args=(ctx, given),
    )


def _do_withdraw(ctx, given: str) -> None:
    try:
        done = withdraw(ctx.store, by="page", **_which(ctx, given))
    except SnapshotError as err:
        _say("error", widgets.one_line(err))
        return
    # The id field emptied: the warning and the confirmation go with it.
    st.session_state[keys.KEY_WITHDRAW_ID] = ""
    st.session_state.pop(f"{keys.KEY_WITHDRAW_CONFIRM}.{given}", None)
    for w in done:
        _say(
            "success",
            f"Withdrew participant {w.participant_id}: deleted {w.n_responses} "
            f"responses and {w.n_events} events.",
        )


# ----------------------------------------------------------------------------- codes
def _completion_codes(ctx) -> None:
    rows = monitor.completion_codes(ctx.store, ctx.stimuli.study.id)
    st.subheader("Completion codes")
    st.caption(
        "Who finished, with their Prolific id and code: approve these submissions on "
        "Prolific (an excluded participant is marked; the decision is yours). Someone "
        "who finished and then withdrew is listed with the date of the withdrawal: "
        "their data are deleted, they are still owed."
    )
    if not rows:
        st.write("Nobody has finished yet.")
        return
    import pandas as pd

    table = pd.DataFrame(
        [
            {
                "Prolific id": r["prolific_pid"] or "",
                "completion code": r["completion_code"] or "",
                "finished (UTC)": r["completed_at"].strftime("%Y-%m-%d %H:%M"),
                "excluded": r["excluded"] or "",
                "withdrawn (UTC)": (
                    r["withdrawn"].strftime("%Y-%m-%d %H:%M") if r.get("withdrawn") else ""
                ),
            }
            for r in rows
        ]
    )
    st.dataframe(table, hide_index=True, width="stretch")
    st.download_button(
        f"Download completion codes (CSV, {len(rows)} rows)",
        table.to_csv(index=False).encode(),
        file_name=f"{ctx.stimuli.study.id}-completion-codes.csv",
        mime="text/csv",
        key=f"{keys.KEY_DOWNLOAD}.codes",
        on_click="ignore",
    )


# ----------------------------------------------------------------------------- downloads
def export_files(ctx, folder: Path) -> dict[str, Path]:
    """Write every shared (pseudonymised) export of the study into ``folder``.

    Returns
    -------
    dict
        ``responses.csv``, ``responses.jsonl``, ``participants.csv``, ``events.jsonl`` and
        the Psych-DS folder ``psych-ds`` (absent when there is no response yet) → path.
    """
    from study_app.data.export import write_events, write_export, write_participants
    from study_app.data.psychds import write_psych_ds

    anon = Pseudonymiser(ctx.store)
    sid = ctx.stimuli.study.id
    people = monitor.with_exclusions(
        ctx.store, [p for p in ctx.store.participants() if p["study_id"] == sid]
    )
    keep = {p["participant_id"] for p in people}
    rows = [r for r in ctx.store.export_rows() if r["study_id"] == sid]
    out = {}
    for name in ("responses.csv", "responses.jsonl"):
        write_export(anon.records(rows), folder / name)
        out[name] = folder / name
    write_participants(anon.records(people), folder / "participants.csv", drop=OPEN_DROPPED)
    out["participants.csv"] = folder / "participants.csv"
    write_events(
        anon.records([e for e in ctx.store.events() if e["participant_id"] in keep]),
        folder / "events.jsonl",
    )
    out["events.jsonl"] = folder / "events.jsonl"
    if rows:
        write_psych_ds(ctx.store, folder / "psych-ds", stimuli_dir=ctx.stimuli.folder)
        out["psych-ds"] = folder / "psych-ds"
    return out


def _zip(paths) -> bytes:
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as z:
        for arcroot, path in paths:
            files = sorted(path.rglob("*")) if path.is_dir() else [path]
            for f in files:
                if f.is_file():
                    z.write(f, f"{arcroot}/{f.relative_to(path)}" if path.is_dir() else arcroot)
    return buf.getvalue()


def _downloads(ctx) -> None:
    st.subheader("Downloads")
    # A download does not re-run the page (on_click="ignore"): a re-run while the browser
    # fetches the file would replace it under the download (Chromium: canceled).
    st.caption(
        "Shared exports: ids are pseudonyms, no seeds, times as UTC months (the raw "
        "ids only from `snapshot export --identifiers`). Built now, after every "
        "action above."
    )
    sid = ctx.stimuli.study.id
    with tempfile.TemporaryDirectory() as tmp:
        try:
            files = export_files(ctx, Path(tmp))
        except SnapshotError as err:
            st.error(widgets.one_line(err))
            return
        n_rows = sum(1 for _ in open(files["responses.jsonl"], encoding="utf-8"))
        n_people = sum(1 for _ in open(files["participants.csv"], encoding="utf-8")) - 1
        items = [
            ("responses.csv", f"Download responses (CSV, {n_rows} rows)", "text/csv"),
            (
                "responses.jsonl",
                f"Download responses (JSONL, {n_rows} rows)",
                "application/x-ndjson",
            ),
            ("participants.csv", f"Download participants (CSV, {n_people} rows)", "text/csv"),
            ("events.jsonl", "Download events (JSONL)", "application/x-ndjson"),
        ]
        c = st.columns(3)
        for k, (name, label, mime) in enumerate(items):
            c[k % 3].download_button(
                label,
                files[name].read_bytes(),
                file_name=f"{sid}-{name}",
                mime=mime,
                key=f"{keys.KEY_DOWNLOAD}.{name}",
                on_click="ignore",
            )
        if "psych-ds" in files:
            c[1].download_button(
                "Download Psych-DS dataset (zip)",
                _zip([(f"{sid}-psych-ds", files["psych-ds"])]),
                file_name=f"{sid}-psych-ds.zip",
                mime="application/zip",
                key=f"{keys.KEY_DOWNLOAD}.psychds",
                on_click="ignore",
            )
        everything = [(f"{sid}/{n}", p) for n, p in files.items()]
        c[2].download_button(
            "Download everything (zip)",
            _zip(everything),
            file_name=f"{sid}-export.zip",
            mime="application/zip",
            key=f"{keys.KEY_DOWNLOAD}.all",
            on_click="ignore",
        )


if __name__ == "__main__":  # run as the page script by st.navigation (see app.py)
    render()
