"""What the researcher page watches and switches: participants' progress, exclusions,
recruitment (a cap and a close switch), the completion codes to approve.

What researchers get from JATOS, oTree or Gorilla:

- :func:`monitor_rows`: each participant's state (:func:`participant_state`: ``started``,
  ``finished``, ``timed out`` — no activity for :data:`TIMEOUT_S` —, ``excluded``), the
  step they are on, how long they have been on it and their last activity (their latest
  answer or player event);
- :func:`participation`: the counts the page, ``snapshot analyze`` (report and
  ``summary.json``) and the exports' columns share — started, finished, excluded (with
  reasons), withdrawn — from participant records, the store's or an export file's;
- :func:`exclude`: leave a participant out of the analysis with a reason, keeping their
  data (unlike a withdrawal, which deletes them). ``snapshot analyze`` and the page's
  tables leave excluded participants out; exports keep them;
- :func:`set_controls` / :func:`enrolment`: close the study to new participants, or cap
  how many may start; participants already in it (and a returning Prolific id) go on;
- :func:`completion_codes`: who finished, with their Prolific id and code.
"""

from __future__ import annotations

from datetime import UTC, datetime

import sqlalchemy as sa

from .database import (
    _utc,
    events,
    exclusions,
    participants,
    responses,
    study_controls,
    withdrawals,
)
from .errors import StoreError

__all__ = [
    "TIMEOUT_S",
    "STATES",
    "monitor_rows",
    "participant_state",
    "participation",
    "exclude",
    "excluded_ids",
    "with_exclusions",
    "controls",
    "set_controls",
    "enrolment",
    "completion_codes",
]

#: Seconds without an answer or a player event after which a participant who has not
#: finished counts as timed out (the study's own estimate is ~10 minutes).
TIMEOUT_S = 30 * 60
#: The states of :func:`monitor_rows`.
STATES = ("started", "finished", "timed out", "excluded")


def _now() -> datetime:
    return datetime.now(UTC)


def participant_state(
    completed_at, excluded, *, idle_s: float | None = None, timeout_s: float = TIMEOUT_S
) -> str:
    """The one definition of where a participant stands (:data:`STATES`).

    Everyone with a participant record has *started* (agreed to take part). They have
    *finished* when the store recorded their completion (``completed_at``: they answered
    the plan's last trial and got their code). They are *excluded* when the researcher
    left them out of the analysis with a reason, whether or not they finished; this
    state wins over the others. Someone neither finished nor excluded is *timed out*
    after ``timeout_s`` without activity (only when ``idle_s`` is known: a live view),
    else still *started*. A withdrawn participant has no record left: they are counted
    from the withdrawal log (:func:`study_app.data.withdraw.withdrawal_counts`).

    Parameters
    ----------
    completed_at : datetime, str or None
        The record's ``completed_at`` (any non-empty value: finished).
    excluded : str or None
        The exclusion reason (the participants export's ``excluded`` column), or None.
    idle_s : float, optional
        Seconds since their last activity.
    """
    if excluded:
        return "excluded"
    if completed_at is not None and completed_at != "":
        return "finished"
    if idle_s is not None and idle_s > timeout_s:
        return "timed out"
    return "started"


def participation(records, *, withdrawn: int | None = None) -> dict:
    """Who started, finished, was excluded (and why) and withdrew.

    Parameters
    ----------
    records : iterable of dict
        Participant records with ``completed_at`` and ``excluded`` (the reason or None):
        :func:`with_exclusions` of :meth:`Store.participants`, or the rows of a
        participants export (:func:`study_app.data.export.read_export` with
        ``schema="participant"``).
    withdrawn : int, optional
        Withdrawals (their records are deleted; the log counts them), None if unknown.

    Returns
    -------
    dict
        ``started`` (every record: the page's "Participants"), ``finished`` (finished
        and not excluded), ``excluded`` (excluded, finished or not),
        ``exclusion_reasons`` (reason → count), ``unfinished`` (neither: in progress,
        timed out or gone), ``withdrawn``.
    """
    states = [(participant_state(r.get("completed_at"), r.get("excluded")), r) for r in records]
    reasons: dict[str, int] = {}
    for state, r in states:
        if state == "excluded":
            reasons[str(r["excluded"])] = reasons.get(str(r["excluded"]), 0) + 1
    return {
        "started": len(states),
        "finished": sum(s == "finished" for s, _ in states),
        "excluded": sum(s == "excluded" for s, _ in states),
        "exclusion_reasons": dict(sorted(reasons.items())),
        "unfinished": sum(s == "started" for s, _ in states),
        "withdrawn": withdrawn,
    }


def monitor_rows(
    store,
    study_id: str,
    *,
    n_trials: int,
    now: datetime | None = None,
    timeout_s: float = TIMEOUT_S,
) -> list[dict]:
    """One row per participant of the study (simulated ones left out), newest first.

    Parameters
    ----------
    n_trials : int
        Trials of the study's plan (the step counter's total).
    now : datetime, optional
        The time to measure from (UTC; default now).

    Returns
    -------
    list of dict
        ``participant_id``, ``prolific_pid``, ``state`` (:data:`STATES`), ``step``
        (``"k of n"``: the trial they are on, or ``"done"``), ``answered``,
        ``started_at``, ``last_activity`` (datetimes, UTC), ``idle_s`` (seconds since the
        last activity, 0 when finished), ``reason`` (of an exclusion, else None).
    """
    now = now or _now()
    n_resp = (
        sa.select(
            responses.c.participant_id,
            sa.func.count().label("n"),
            sa.func.max(responses.c.created_at).label("last"),
        )
        .group_by(responses.c.participant_id)
        .subquery()
    )
    n_ev = (
        sa.select(events.c.participant_id, sa.func.max(events.c.created_at).label("last"))
        .group_by(events.c.participant_id)
        .subquery()
    )
    p = participants
    query = (
        sa.select(
            p.c.participant_id,
            p.c.prolific_pid,
            p.c.created_at,
            p.c.completed_at,
            n_resp.c.n,
            n_resp.c.last.label("last_answer"),
            n_ev.c.last.label("last_event"),
            exclusions.c.reason,
        )
        .select_from(
            p.outerjoin(n_resp, n_resp.c.participant_id == p.c.participant_id)
            .outerjoin(n_ev, n_ev.c.participant_id == p.c.participant_id)
            .outerjoin(exclusions, exclusions.c.participant_id == p.c.participant_id)
        )
        .where(p.c.study_id == study_id, p.c.simulated.is_(False))
        .order_by(p.c.created_at.desc())
    )
    with store.transaction(write=False) as conn:
        rows = conn.execute(query).mappings().all()
    out = []
    for r in rows:
        answered = int(r["n"] or 0)
        times = [
            _utc(t)
            for t in (r["created_at"], r["last_answer"], r["last_event"], r["completed_at"])
            if t is not None
        ]
        last = max(times)
        idle = 0.0 if r["completed_at"] is not None else max(0.0, (now - last).total_seconds())
        state = participant_state(r["completed_at"], r["reason"], idle_s=idle, timeout_s=timeout_s)
        out.append(
            {
                "participant_id": r["participant_id"],
                "prolific_pid": r["prolific_pid"],
                "state": state,
                "step": (
                    "done"
                    if r["completed_at"] is not None
                    else f"{min(answered + 1, n_trials)} of {n_trials}"
                ),
                "answered": answered,
                "started_at": _utc(r["created_at"]),
                "last_activity": last,
                "idle_s": round(idle, 1),
                "reason": r["reason"],
            }
        )
    return out


def exclude(store, participant_id: str, reason: str, *, study_id: str | None = None) -> None:
    """Exclude a participant from the analysis with a reason (their data stay).

    Raises
    ------
    StoreError
        No reason, an unknown participant (of ``study_id``, when given), or one already
        excluded (the message gives the earlier reason).
    """
    reason = " ".join(str(reason or "").split())
    if not reason:
        raise StoreError("an exclusion needs a reason (it goes into the data)")
    if len(reason) > 500:
        raise StoreError(f"the reason is {len(reason)} characters; at most 500")
    with store.transaction(write=True) as conn:
        cond = participants.c.participant_id == str(participant_id)
        if study_id is not None:
            cond = sa.and_(cond, participants.c.study_id == study_id)
        sid = conn.execute(sa.select(participants.c.study_id).where(cond)).scalar()
        if sid is None:
            raise StoreError(f"unknown participant {str(participant_id)[:70]!r}")
        before = conn.execute(
            sa.select(exclusions.c.reason).where(exclusions.c.participant_id == str(participant_id))
        ).scalar()
        if before is not None:
            raise StoreError(f"participant {participant_id} is already excluded ({before})")
        conn.execute(
            exclusions.insert().values(
                participant_id=str(participant_id), study_id=sid, reason=reason, excluded_at=_now()
            )
        )


def excluded_ids(store, study_id: str | None = None) -> dict[str, str]:
    """Excluded participant id → reason (of one study, or all)."""
    query = sa.select(exclusions.c.participant_id, exclusions.c.reason)
    if study_id is not None:
        query = query.where(exclusions.c.study_id == study_id)
    with store.transaction(write=False) as conn:
        if not sa.inspect(conn).has_table("exclusions"):  # a database older than the table
            return {}
        return dict(conn.execute(query).all())


def with_exclusions(store, records) -> list[dict]:
    """Participant records (:meth:`Store.participants`) with ``excluded``: the reason, or
    None (the participants export's column)."""
    reasons = excluded_ids(store)
    return [{**r, "excluded": reasons.get(r["participant_id"])} for r in records]


def controls(store, study_id: str) -> dict:
    """``{"closed": bool, "cap": int or None}`` of a study (open, no cap by default)."""
    with store.transaction(write=False) as conn:
        row = (
            conn.execute(sa.select(study_controls).where(study_controls.c.study_id == study_id))
            .mappings()
            .first()
        )
    return {"closed": bool(row["closed"]) if row else False, "cap": row["cap"] if row else None}


def set_controls(store, study_id: str, *, closed: bool, cap: int | None) -> None:
    """Store the study's recruitment switches (one row per study, replaced)."""
    if cap is not None and (isinstance(cap, bool) or not isinstance(cap, int) or cap < 0):
        raise StoreError(f"the cap must be a whole number >= 0, got {cap!r}")
    with store.transaction(write=True) as conn:
        conn.execute(study_controls.delete().where(study_controls.c.study_id == study_id))
        conn.execute(
            study_controls.insert().values(
                study_id=study_id, closed=bool(closed), cap=cap, updated_at=_now()
            )
        )


def enrolment(store, study_id: str) -> str | None:
    """Why a new participant cannot start now (closed, or the cap reached), or None."""
    c = controls(store, study_id)
    if c["closed"]:
        return "closed"
    if c["cap"] is not None:
        with store.transaction(write=False) as conn:
            n = conn.execute(
                sa.select(sa.func.count())
                .select_from(participants)
                .where(participants.c.study_id == study_id, participants.c.simulated.is_(False))
            ).scalar()
        if n >= c["cap"]:
            return "full"
    return None


def completion_codes(store, study_id: str) -> list[dict]:
    """Who finished: ``participant_id``, ``prolific_pid``, ``completion_code``,
    ``completed_at`` (UTC), ``excluded`` (the reason, or None), ``withdrawn`` (when they
    withdrew, or None), oldest first — the list to approve submissions by on Prolific.

    Someone who finished and then withdrew is listed from their withdrawal record
    (their data are gone; the code is kept for payment only): they are owed."""
    p = participants
    query = (
        sa.select(
            p.c.participant_id,
            p.c.prolific_pid,
            p.c.completion_code,
            p.c.completed_at,
            exclusions.c.reason,
        )
        .select_from(p.outerjoin(exclusions, exclusions.c.participant_id == p.c.participant_id))
        .where(p.c.study_id == study_id, p.c.completed_at.is_not(None), p.c.simulated.is_(False))
        .order_by(p.c.completed_at)
    )
    w = withdrawals
    with store.transaction(write=False) as conn:
        out = [
            {
                "participant_id": r["participant_id"],
                "prolific_pid": r["prolific_pid"],
                "completion_code": r["completion_code"],
                "completed_at": _utc(r["completed_at"]),
                "excluded": r["reason"],
                "withdrawn": None,
            }
            for r in conn.execute(query).mappings()
        ]
        if "completed_at" in {c["name"] for c in sa.inspect(conn).get_columns("withdrawals")}:
            gone = conn.execute(
                sa.select(
                    w.c.participant_id,
                    w.c.prolific_pid,
                    w.c.completion_code,
                    w.c.completed_at,
                    w.c.withdrawn_at,
                ).where(w.c.study_id == study_id, w.c.completed_at.is_not(None))
            ).mappings()
            out += [
                {
                    "participant_id": r["participant_id"],
                    "prolific_pid": r["prolific_pid"],
                    "completion_code": r["completion_code"],
                    "completed_at": _utc(r["completed_at"]),
                    "excluded": None,
                    "withdrawn": _utc(r["withdrawn_at"]),
                }
                for r in gone
            ]
    return sorted(out, key=lambda r: r["completed_at"])
