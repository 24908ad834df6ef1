"""The events part of :class:`~study_app.data.store.Store`: interaction events (plays,
pauses, seeks, steps, page views) appended with a JSON payload, the first event of a kind
(when a trial was first shown), and reading them back.
"""

from __future__ import annotations

from collections.abc import Iterable
from datetime import datetime
from typing import Any

import sqlalchemy as sa

from .database import events
from .engine import StoreEngine, _iso, _utc, _utcnow
from .errors import StoreError
from .rows import checked_event

__all__ = ["EventRecords"]

_PARTICIPANT_EVENTS = (
    sa.select(events).where(events.c.participant_id == sa.bindparam("pid")).order_by(events.c.id)
)
_FIRST_EVENT = sa.select(sa.func.min(events.c.created_at)).where(
    events.c.participant_id == sa.bindparam("pid"),
    events.c.kind == sa.bindparam("kind"),
    events.c.trial_index == sa.bindparam("trial"),
)
_TRIAL_EVENT_COUNT = (
    sa.select(sa.func.count())
    .select_from(events)
    .where(
        events.c.participant_id == sa.bindparam("pid"),
        events.c.trial_index == sa.bindparam("trial"),
    )
)


class EventRecords(StoreEngine):
    """Appending and reading interaction events (one transaction per call)."""

    def record_event(
        self, pid: str, trial_index: int | None, kind: str, payload: dict | None = None
    ) -> None:
        """Append an interaction event (``kind`` like "play", "pause", "seek", "step").

        ``trial_index`` None is an event outside a trial (a page view); ``payload`` is
        any plain-JSON dict (no NaN/inf). Unknown participant → :class:`StoreError`.
        """
        self.record_events(pid, trial_index, [(kind, payload)])

    def record_events(
        self,
        pid: str,
        trial_index: int | None,
        items: Iterable[tuple[str, Any]],
        *,
        limit: int | None = None,
    ) -> int:
        """Append several events of one trial in one transaction; return how many.

        ``items``: ``(kind, payload)`` pairs, e.g. the picker's log of one trial. All are
        checked before anything is written. ``limit``: most events the trial may hold
        (counted in the same transaction); the items beyond it are dropped.
        """
        rows = [checked_event(trial_index, kind, payload) for kind, payload in items]
        if not rows:
            return 0
        if limit is not None and trial_index is None:
            raise StoreError("an event limit counts the events of one trial")
        now = _utcnow()

        def work(conn: sa.Connection) -> int:
            self._participant_row(conn, pid)
            room = (
                len(rows)
                if limit is None
                else max(
                    0,
                    limit
                    - conn.execute(
                        _TRIAL_EVENT_COUNT, {"pid": pid, "trial": trial_index}
                    ).scalar_one(),
                )
            )
            if room:
                conn.execute(
                    events.insert(),
                    [{**r, "participant_id": pid, "created_at": now} for r in rows[:room]],
                )
            return min(room, len(rows))

        return self._write(work)

    def first_event_or_record(
        self, pid: str, trial_index: int | None, kind: str, payload: dict | None = None
    ) -> datetime:
        """When the participant's first ``kind`` event of ``trial_index`` was stored (UTC);
        if there is none, store one now (with ``payload``) and return its time.

        One read when the event exists (a reload, a second tab); else one write
        transaction that inserts and reads back the earliest, so two tabs showing the
        trial at once agree on the first.
        """
        at = self.first_event_at(pid, trial_index, kind)
        if at is not None:
            return at
        row = checked_event(trial_index, kind, payload)

        def work(conn: sa.Connection) -> datetime | str | None:
            self._participant_row(conn, pid)
            conn.execute(events.insert().values(participant_id=pid, created_at=_utcnow(), **row))
            return self._first_event(conn, pid, trial_index, kind)

        at = _utc(self._write(work))
        if at is None:  # written in the same transaction: only a broken store gets here
            raise StoreError(f"participant {pid!r}: the event just written was not read back")
        return at

    def _first_event(
        self, conn: sa.Connection, pid: str, trial_index: int | None, kind: str
    ) -> datetime | str | None:
        if trial_index is not None:  # the common case: one statement, built once
            return conn.execute(
                _FIRST_EVENT, {"pid": self._check_pid(pid), "kind": kind, "trial": trial_index}
            ).scalar()
        return conn.execute(
            sa.select(sa.func.min(events.c.created_at)).where(
                events.c.participant_id == self._check_pid(pid),
                events.c.kind == kind,
                events.c.trial_index.is_(None),
            )
        ).scalar()

    def first_event_at(self, pid: str, trial_index: int | None, kind: str) -> datetime | None:
        """When the participant's first ``kind`` event of ``trial_index`` was stored (UTC),
        or None if there is none."""
        checked_event(trial_index, kind, None)
        with self.transaction(write=False) as conn:
            value = self._first_event(conn, pid, trial_index, kind)
        return _utc(value)

    def events(self, pid: str | None = None) -> list[dict]:
        """Stored events (all, or one participant's), oldest first."""
        with self.transaction(write=False) as conn:
            if pid is None:
                rows = conn.execute(sa.select(events).order_by(events.c.id)).mappings().all()
            else:
                rows = (
                    conn.execute(_PARTICIPANT_EVENTS, {"pid": self._check_pid(pid)})
                    .mappings()
                    .all()
                )
        return [
            {
                "participant_id": r["participant_id"],
                "trial_index": r["trial_index"],
                "kind": r["kind"],
                "payload": r["payload"],
                "created_at": _iso(r["created_at"]),
            }
            for r in rows
        ]
