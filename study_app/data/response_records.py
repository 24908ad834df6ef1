"""The answers part of :class:`~study_app.data.store.Store`: recording each trial's answer
exactly once (with the events that go with it), and the answered trials a participant
resumes from.
"""

from __future__ import annotations

from collections.abc import Iterable
from datetime import datetime
from typing import Any

import sqlalchemy as sa
from sqlalchemy import exc as sa_exc

from .answer import Answer
from .database import events, responses
from .engine import _DUPLICATE_RETRIES, _PARTICIPANT, PARTICIPANT_ID_RE, StoreEngine, _utcnow
from .errors import StoreError
from .participant_records import _participant_dict
from .rows import checked_event, checked_response

__all__ = ["ResponseRecords"]

_ANSWERED = sa.select(responses.c.trial_index).where(
    responses.c.participant_id == sa.bindparam("pid")
)


class ResponseRecords(StoreEngine):
    """Appending answers (append-only, one per participant and trial) and reading which
    trials are answered."""

    def record_response(
        self,
        pid: str,
        row: Answer,
        *,
        with_events: Iterable[tuple[int | None, str, Any]] = (),
        at: datetime | None = None,
    ) -> bool:
        """Append one trial's answer; False (and nothing changed) if that trial is stored.

        Parameters
        ----------
        pid : str
            Participant id.
        row : Answer
            The trial fields of ``data_schema/response.schema.json``: ``trial_index``,
            ``task``, ``scene``, ``stimulus_id``, ``response_time_s`` and any of
            ``chosen_frame``, ``chosen_video_frame``, ``algorithm_frame``, ``fps``,
            ``n_frames``, ``chosen_method``, ``chosen_position``, ``shown_order``,
            ``chosen_value``, ``correct`` (frames in source numbering). The store adds
            participant, study, app version, manifest hash, simulated flag and time.
        with_events : iterable of (int, str, dict), optional
            ``(trial_index, kind, payload)`` events stored with the answer, in the same
            transaction, if the answer is new (e.g. the picker's log of this trial, the
            next trial's ``shown`` event).
        at : datetime, optional
            The time stored with the answer and its events (default: now, UTC).

        Returns
        -------
        bool
            True if stored, False if this participant already answered this trial (the
            first answer stays).

        Raises
        ------
        StoreError
            Unknown participant id, or a row that does not follow the schema (the
            message names the field). Nothing is written.
        """
        return self.record_responses(pid, [row], with_events=with_events, at=at) == 1

    def record_responses(
        self,
        pid: str,
        rows: list[Answer],
        *,
        with_events: Iterable[tuple[int | None, str, Any]] = (),
        at: datetime | None = None,
    ) -> int:
        """Append several trials of one participant in one transaction; return how many were new.

        Already-answered trials are skipped (their first answer stays). Every row is
        checked before anything is written. ``with_events`` (with one row only) and
        ``at`` as in :meth:`record_response`.
        """
        checked = [checked_response(r) for r in rows]
        indices = [r["trial_index"] for r in checked]
        if len(set(indices)) != len(indices):
            raise StoreError(f"participant {pid!r}: the same trial_index twice in one batch")
        with_events = list(with_events)
        if with_events and len(checked) != 1:
            raise StoreError("events go with one response at a time")
        event_rows = [checked_event(t, kind, payload) for t, kind, payload in with_events]
        if at is not None and (not isinstance(at, datetime) or at.tzinfo is None):
            raise StoreError(f"the time of an answer must be an aware datetime, got {at!r}")

        def work(conn: sa.Connection) -> int:
            part = self._participant_row(conn, pid)
            stored = self._answered(conn, pid)
            new = [r for r in checked if r["trial_index"] not in stored]
            now = at or _utcnow()
            if new:
                conn.execute(
                    responses.insert(),
                    [
                        {
                            **r,
                            "participant_id": pid,
                            "created_at": now,
                            "app_version": part["app_version"],
                            "manifest_sha256": part["manifest_sha256"],
                        }
                        for r in new
                    ],
                )
                if event_rows:
                    conn.execute(
                        events.insert(),
                        [{**e, "participant_id": pid, "created_at": now} for e in event_rows],
                    )
            return len(new)

        attempt = 0
        while True:
            try:
                return self._write(work)
            except StoreError as err:
                # The same participant and trial sent by two requests at once (possible
                # on PostgreSQL, where readers do not wait): one insert hit the unique
                # key and rolled back. Retry: the answered-trials check now sees the
                # winner's row and skips it.
                if (
                    not isinstance(err.__cause__, sa_exc.IntegrityError)
                    or attempt == _DUPLICATE_RETRIES
                ):
                    raise
                attempt += 1

    @staticmethod
    def _answered(conn: sa.Connection, pid: str) -> set[int]:
        return set(conn.execute(_ANSWERED, {"pid": pid}).scalars())

    def participant_state(self, pid: str) -> tuple[dict | None, set[int]]:
        """``(record, answered trial indices)`` of a participant, read together.

        What resuming a participant needs on every script run, in one transaction: the
        record as :meth:`get_participant` (None if the id is unknown or malformed, with
        an empty set) and the trial indices as :meth:`answered_trials`.
        """
        if not isinstance(pid, str) or not PARTICIPANT_ID_RE.match(pid):
            return None, set()
        with self.transaction(write=False) as conn:
            row = conn.execute(_PARTICIPANT, {"pid": pid}).mappings().first()
            if row is None:
                return None, set()
            return _participant_dict(row), self._answered(conn, pid)

    def answered_trials(self, pid: str) -> set[int]:
        """Trial indices this participant has answered (to resume at the first gap)."""
        with self.transaction(write=False) as conn:
            self._participant_row(conn, pid)
            return self._answered(conn, pid)
