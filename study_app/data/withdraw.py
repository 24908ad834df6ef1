"""Withdrawal: delete one participant's data and keep a record that they withdrew.

A participant may ask, at any time, for their data to be deleted (the consent page says
how: the study config's ``contact``). :func:`withdraw` deletes, in one transaction,
their responses, their interaction events and their participant row (background
answers, seed, Prolific ids, completion code), and adds one row to ``withdrawals``:
when, the participant link id, the study, the Prolific id if they had one, and who did
it (``"cli"``: ``snapshot withdraw``; ``"page"``: the researcher page); for someone who
had finished, also their completion code and when they finished, for payment only
(:func:`study_app.data.monitor.completion_codes`; never exported). Nothing they
answered is kept.

The same record is appended to the withdrawal log outside the database
(:mod:`study_app.data.withdrawal_log`) before the transaction commits, so that a restore
after the database is lost still knows it. The record is what lets the app honour the withdrawal later: their personal link says
that their data were withdrawn (:func:`withdrawal_of`), and the study link with their
Prolific id does not enrol them again.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from datetime import UTC, datetime

import sqlalchemy as sa

from .database import events, exclusions, participants, responses, withdrawals
from .errors import StoreError
from .pseudonym import PSEUDONYM_RE, participants_by_pseudonym
from .withdrawal_log import append_log, log_path

__all__ = [
    "WITHDRAWN_BY",
    "Withdrawal",
    "withdraw",
    "withdrawal_of",
    "withdrawal_plan",
    "withdrawals_of_study",
    "withdrawal_counts",
]

#: Who can withdraw a participant: the command line or the researcher page.
WITHDRAWN_BY = ("cli", "page")


@dataclass(frozen=True)
class Withdrawal:
    """One participant's withdrawal (a row of ``withdrawals``, plus what was deleted).

    Attributes
    ----------
    participant_id, study_id : str
    prolific_pid : str or None
    requested_by : str
        ``"cli"`` or ``"page"``.
    withdrawn_at : datetime
        When (UTC).
    n_responses, n_events : int
        Rows deleted by this withdrawal (0 for a record read back later).
    """

    participant_id: str
    study_id: str
    prolific_pid: str | None
    requested_by: str
    withdrawn_at: datetime
    n_responses: int = 0
    n_events: int = 0


def _utc(value: datetime) -> datetime:
    if isinstance(value, str):
        value = datetime.fromisoformat(value)
    return value.replace(tzinfo=UTC) if value.tzinfo is None else value.astimezone(UTC)


def _record(row) -> Withdrawal:
    return Withdrawal(
        row["participant_id"],
        row["study_id"],
        row["prolific_pid"],
        row["requested_by"],
        _utc(row["withdrawn_at"]),
    )


def _targets(conn, participant_id, prolific_pid, study_id, named=None) -> list:
    """The participant rows named by exactly one of the two ids (or, ``named``, the link
    ids a pseudonym stands for)."""
    cond: sa.ColumnElement[bool]
    if named is not None:
        cond = participants.c.participant_id.in_(named)
    elif (participant_id is None) == (prolific_pid is None):
        raise StoreError(
            "withdraw needs exactly one of a participant id, a Prolific id and a pseudonym"
        )
    elif participant_id is not None:
        cond = participants.c.participant_id == str(participant_id)
    else:
        cond = participants.c.prolific_pid == str(prolific_pid)
    if study_id is not None:
        cond = sa.and_(cond, participants.c.study_id == study_id)
    return (
        conn.execute(sa.select(participants).where(cond).order_by(participants.c.created_at))
        .mappings()
        .all()
    )


def _by_pseudonym(store, participant_id, prolific_pid, pseudonym_value, study_id):
    """The link ids a pseudonym names (None when no pseudonym is given)."""
    if pseudonym_value is None:
        return None
    if participant_id is not None or prolific_pid is not None:
        raise StoreError(
            "withdraw needs exactly one of a participant id, a Prolific id and a pseudonym"
        )
    value = str(pseudonym_value).strip()
    if not re.match(PSEUDONYM_RE, value):
        raise StoreError(
            f"{value[:70]!r} is not a pseudonym (p- and 16 hex digits, as in the shared exports)"
        )
    named = participants_by_pseudonym(store, value, study_id=study_id)
    if not named:
        from .anonymise import anonymised_studies

        gone = {
            sid: at
            for sid, at in anonymised_studies(store).items()
            if study_id is None or sid == study_id
        }
        if gone:
            sid, at = sorted(gone.items())[0]
            raise StoreError(
                f"pseudonym {value!r} cannot be traced: study {sid!r} was anonymised on "
                f"{at.date().isoformat()} (its pseudonyms lead to nobody any more); "
                "withdraw by link id or Prolific id; nothing was deleted"
            )
        raise StoreError(
            f"unknown pseudonym {value!r}: no participant of "
            + (f"study {study_id!r}" if study_id else "this database")
            + " has it (already withdrawn, or from another database); "
            "nothing was deleted"
        )
    return named


def _unknown(conn, participant_id, prolific_pid) -> StoreError:
    """The error for an id with no participant: already withdrawn, or never known."""
    kind, value = (
        ("participant id", participant_id)
        if participant_id is not None
        else ("Prolific id", prolific_pid)
    )
    column = (
        withdrawals.c.participant_id if participant_id is not None else withdrawals.c.prolific_pid
    )
    done = (
        conn.execute(
            sa.select(withdrawals.c.withdrawn_at)
            .where(column == str(value))
            .order_by(withdrawals.c.withdrawn_at)
        )
        .scalars()
        .first()
    )
    if done is not None:
        return StoreError(
            f"{kind} {value!r} was already withdrawn on "
            f"{_utc(done).isoformat(timespec='seconds')}; nothing to delete"
        )
    return StoreError(
        f"unknown {kind} {str(value)[:70]!r}: no participant has it; nothing was deleted"
    )


def _count(conn, table, pid: str) -> int:
    return int(
        conn.execute(
            sa.select(sa.func.count()).select_from(table).where(table.c.participant_id == pid)
        ).scalar()
    )


def withdrawal_plan(
    store,
    *,
    participant_id: str | None = None,
    prolific_pid: str | None = None,
    study_id: str | None = None,
    pseudonym: str | None = None,
) -> list[dict]:
    """What :func:`withdraw` would delete, without deleting it (for a confirmation).

    Returns
    -------
    list of dict
        One per participant: ``participant_id``, ``study_id``, ``prolific_pid``,
        ``n_responses``, ``n_events``, ``has_background``.

    Raises
    ------
    StoreError
        No participant has that id (the message says if they already withdrew).
    """
    named = _by_pseudonym(store, participant_id, prolific_pid, pseudonym, study_id)
    with store.transaction(write=False) as conn:
        rows = _targets(conn, participant_id, prolific_pid, study_id, named)
        if not rows:
            raise _unknown(conn, participant_id, prolific_pid)
        out = []
        for row in rows:
            pid = row["participant_id"]
            out.append(
                {
                    "participant_id": pid,
                    "study_id": row["study_id"],
                    "prolific_pid": row["prolific_pid"],
                    "n_responses": _count(conn, responses, pid),
                    "n_events": _count(conn, events, pid),
                    "has_background": row["background"] is not None,
                }
            )
    return out


def withdraw(
    store,
    *,
    participant_id: str | None = None,
    prolific_pid: str | None = None,
    study_id: str | None = None,
    by: str = "cli",
    pseudonym: str | None = None,
) -> list[Withdrawal]:
    """Delete a participant's data and record the withdrawal, in one transaction.

    Parameters
    ----------
    store : study_app.data.store.Store
    participant_id : str, optional
        The participant link id (``?pid=``).
    prolific_pid : str, optional
        Their Prolific id instead (every participant with it, in every study unless
        ``study_id`` is given: a person who withdraws withdraws everything).
    study_id : str, optional
        Only this study's participants.
    by : {"cli", "page"}
        Who did it (stored in the record).
    pseudonym : str, optional
        Instead of an id: the pseudonym (``p-`` and 16 hex digits) of their participant,
        Prolific or session id or completion code in a shared export — the only id a
        published dataset shows.

    Returns
    -------
    list of Withdrawal
        One per participant withdrawn (with the number of rows deleted).

    Raises
    ------
    StoreError
        Not exactly one id given, ``by`` unknown, or no participant has the id (the
        message says when it was already withdrawn). Nothing is changed.
    """
    if by not in WITHDRAWN_BY:
        raise StoreError(f"withdrawn by must be one of {', '.join(WITHDRAWN_BY)}, got {by!r}")
    named = _by_pseudonym(store, participant_id, prolific_pid, pseudonym, study_id)
    now = datetime.now(UTC)
    done, logged = [], []
    with store.transaction(write=True) as conn:
        rows = _targets(conn, participant_id, prolific_pid, study_id, named)
        if not rows:
            raise _unknown(conn, participant_id, prolific_pid)
        # A database made before the payment columns keeps working (without them).
        keeps_codes = "completion_code" in {
            c["name"] for c in sa.inspect(conn).get_columns("withdrawals")
        }
        for row in rows:
            pid = row["participant_id"]
            # Children first: responses and events refer to the participant row.
            n_resp = conn.execute(
                responses.delete().where(responses.c.participant_id == pid)
            ).rowcount
            n_ev = conn.execute(events.delete().where(events.c.participant_id == pid)).rowcount
            conn.execute(exclusions.delete().where(exclusions.c.participant_id == pid))
            conn.execute(participants.delete().where(participants.c.participant_id == pid))
            payment = (
                {"completion_code": row["completion_code"], "completed_at": row["completed_at"]}
                if row["completed_at"] is not None
                else {}
            )
            record = {
                "participant_id": pid,
                "study_id": row["study_id"],
                "prolific_pid": row["prolific_pid"],
                "requested_by": by,
                "withdrawn_at": now,
            }
            conn.execute(withdrawals.insert().values(**record, **(payment if keeps_codes else {})))
            logged.append({**record, **payment})
            done.append(
                Withdrawal(
                    pid, row["study_id"], row["prolific_pid"], by, now, int(n_resp), int(n_ev)
                )
            )
        # Before the commit: a withdrawal the log cannot keep is not made (a lost
        # database would take it along, and a restore bring the person back).
        append_log(log_path(store._url), logged)
    return done


def withdrawal_of(
    store,
    *,
    participant_id: str | None = None,
    prolific_pid: str | None = None,
    study_id: str | None = None,
) -> Withdrawal | None:
    """The withdrawal record of a participant link id or a Prolific id, or None."""
    if (participant_id is None) == (prolific_pid is None):
        raise StoreError("withdrawal_of needs exactly one of a participant id and a Prolific id")
    cond = (
        withdrawals.c.participant_id == str(participant_id)
        if participant_id is not None
        else withdrawals.c.prolific_pid == str(prolific_pid)
    )
    if study_id is not None:
        cond = sa.and_(cond, withdrawals.c.study_id == study_id)
    with store.transaction(write=False) as conn:
        row = (
            conn.execute(sa.select(withdrawals).where(cond).order_by(withdrawals.c.withdrawn_at))
            .mappings()
            .first()
        )
    return None if row is None else _record(row)


def withdrawals_of_study(store, study_id: str) -> list[Withdrawal]:
    """Every withdrawal recorded for ``study_id``, oldest first (the researcher page's
    list: when, by whom, whose link id and Prolific id)."""
    with store.transaction(write=False) as conn:
        rows = (
            conn.execute(
                sa.select(withdrawals)
                .where(withdrawals.c.study_id == study_id)
                .order_by(withdrawals.c.withdrawn_at)
            )
            .mappings()
            .all()
        )
    return [_record(r) for r in rows]


def withdrawal_counts(store) -> dict[str, int]:
    """Study id → how many participants withdrew (the log's rows; their data are gone)."""
    with store.transaction(write=False) as conn:
        if not sa.inspect(conn).has_table("withdrawals"):  # a database older than the log
            return {}
        query = sa.select(withdrawals.c.study_id, sa.func.count()).group_by(withdrawals.c.study_id)
        return {sid: int(n) for sid, n in conn.execute(query).all()}
