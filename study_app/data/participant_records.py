"""The participants part of :class:`~study_app.data.store.Store`: registering a
participant (also once per Prolific id), reading their record, every participant with their
answer count, the background answers and completion (with its code).
"""

from __future__ import annotations

import re
import secrets
from functools import partial
from typing import Any

import sqlalchemy as sa
from sqlalchemy import exc as sa_exc

from .database import participants, responses
from .engine import _DUPLICATE_RETRIES, _PARTICIPANT, PARTICIPANT_ID_RE, StoreEngine, _iso, _utcnow
from .errors import StoreError
from .pseudonym import ensure_secret

__all__ = ["ParticipantRecords", "PROLIFIC_KEYS"]

#: Completion codes: 8 characters from an alphabet without look-alikes (0/O, 1/I).
COMPLETION_ALPHABET = "ABCDEFGHJKLMNPQRSTUVWXYZ23456789"
COMPLETION_CODE_LENGTH = 8
#: Seeds are stored as signed 64-bit integers.
MAX_SEED = 2**63 - 1
PROLIFIC_KEYS = {
    "PROLIFIC_PID": "prolific_pid",
    "STUDY_ID": "prolific_study_id",
    "SESSION_ID": "prolific_session_id",
}


class ParticipantRecords(StoreEngine):
    """Registering, reading and completing participants (one transaction per call)."""

    def create_participant(
        self,
        study_id: str,
        manifest_sha256: str,
        *,
        app_version: str,
        seed: int,
        prolific: dict | None = None,
        simulated: bool = False,
    ) -> str:
        """Register a participant; return their new unguessable id.

        Parameters
        ----------
        study_id : str
            The study config's id.
        manifest_sha256 : str
            sha256 (64 hex digits) of the stimuli manifest the participant sees.
        app_version : str
            Version of the app serving them.
        seed : int
            Their trial-order seed, 0 <= seed < 2**63.
        prolific : dict, optional
            ``{"PROLIFIC_PID": ..., "STUDY_ID": ..., "SESSION_ID": ...}`` (any subset;
            empty values are dropped).
        simulated : bool
            True for simulated observers (excluded from exports unless asked).
        """
        self._check_new(study_id, manifest_sha256, app_version, seed)
        values = self._prolific_values(prolific)
        return self._write(
            partial(
                _insert_participant,
                study_id=study_id,
                seed=seed,
                app_version=app_version,
                manifest_sha256=manifest_sha256,
                simulated=bool(simulated),
                values=values,
            )
        )

    @staticmethod
    def _check_new(
        study_id: object, manifest_sha256: object, app_version: object, seed: object
    ) -> None:
        if not isinstance(study_id, str) or not study_id or len(study_id) > 200:
            raise StoreError(f"study_id must be a non-empty string, got {study_id!r}")
        if not isinstance(manifest_sha256, str) or not re.fullmatch(
            r"[0-9a-f]{64}", manifest_sha256
        ):
            raise StoreError(
                f"manifest_sha256 must be 64 lowercase hex digits, got {manifest_sha256!r}"
            )
        if not isinstance(app_version, str) or not app_version:
            raise StoreError(f"app_version must be a non-empty string, got {app_version!r}")
        if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed <= MAX_SEED:
            raise StoreError(f"seed must be an integer in [0, 2**63), got {seed!r}")

    @staticmethod
    def _prolific_values(prolific: dict | None) -> dict:
        values: dict[str, str | None] = {v: None for v in PROLIFIC_KEYS.values()}
        for key, value in (prolific or {}).items():
            if key not in PROLIFIC_KEYS:
                raise StoreError(
                    f"unknown Prolific parameter {key!r} (expected {', '.join(PROLIFIC_KEYS)})"
                )
            if value not in (None, ""):
                values[PROLIFIC_KEYS[key]] = str(value)[:200]
        return values

    def find_prolific(self, study_id: str, prolific_pid: str) -> str | None:
        """The participant id registered for a Prolific id in a study, or None."""
        with self.transaction(write=False) as conn:
            return (
                conn.execute(
                    sa.select(participants.c.participant_id)
                    .where(
                        participants.c.study_id == study_id,
                        participants.c.prolific_pid == str(prolific_pid),
                    )
                    .order_by(participants.c.created_at)
                )
                .scalars()
                .first()
            )

    def participant_for_prolific(
        self, study_id: str, manifest_sha256: str, *, app_version: str, seed: int, prolific: dict
    ) -> tuple[str, bool]:
        """The participant of a Prolific id in this study, registered if new.

        One Prolific id is one participant per study: the same study link opened again,
        in any browser, finds the first record instead of starting a second one.

        Parameters
        ----------
        study_id, manifest_sha256, app_version, seed
            As :meth:`create_participant` (used only when the id is new).
        prolific : dict
            Must hold ``PROLIFIC_PID``; ``STUDY_ID``/``SESSION_ID`` are stored if given.

        Returns
        -------
        (participant_id, created) : tuple of (str, bool)
        """
        ppid = (prolific or {}).get("PROLIFIC_PID")
        if not ppid:
            raise StoreError("participant_for_prolific needs a PROLIFIC_PID")
        self._check_new(study_id, manifest_sha256, app_version, seed)
        values = self._prolific_values(prolific)
        for attempt in range(_DUPLICATE_RETRIES + 1):
            try:
                # Look-up and insert in one write transaction: on SQLite it holds the
                # write lock (BEGIN IMMEDIATE), so two browsers cannot both insert; on
                # PostgreSQL the unique index refuses the loser, who retries and finds
                # the winner's row.
                return self._write(
                    partial(
                        self._find_or_insert_prolific,
                        study_id=study_id,
                        seed=seed,
                        app_version=app_version,
                        manifest_sha256=manifest_sha256,
                        values=values,
                    )
                )
            except StoreError as err:
                if (
                    not isinstance(err.__cause__, sa_exc.IntegrityError)
                    or attempt == _DUPLICATE_RETRIES
                ):
                    raise
        raise AssertionError("unreachable")  # pragma: no cover

    @staticmethod
    def _find_or_insert_prolific(
        conn: sa.Connection,
        *,
        study_id: str,
        seed: int,
        app_version: str,
        manifest_sha256: str,
        values: dict[str, Any],
    ) -> tuple[str, bool]:
        found = (
            conn.execute(
                sa.select(participants.c.participant_id)
                .where(
                    participants.c.study_id == study_id,
                    participants.c.prolific_pid == values["prolific_pid"],
                )
                .order_by(participants.c.created_at)
            )
            .scalars()
            .first()
        )
        if found is not None:
            return found, False
        pid = _insert_participant(
            conn,
            study_id=study_id,
            seed=seed,
            app_version=app_version,
            manifest_sha256=manifest_sha256,
            simulated=False,
            values=values,
        )
        return pid, True

    def get_participant(self, pid: str) -> dict | None:
        """The participant's record as a dict, or None if the id is unknown or malformed.

        Keys: participant_id, study_id, seed, created_at, completed_at (ISO 8601 UTC or
        None), completion_code, background (dict or None), prolific_pid,
        prolific_study_id, prolific_session_id, simulated, manifest_sha256, app_version.
        """
        if not isinstance(pid, str) or not PARTICIPANT_ID_RE.match(pid):
            return None
        with self.transaction(write=False) as conn:
            row = conn.execute(_PARTICIPANT, {"pid": pid}).mappings().first()
        return None if row is None else _participant_dict(row)

    def participants(self, *, include_simulated: bool = False) -> list[dict]:
        """Every participant (as :meth:`get_participant`) with ``n_responses``, oldest first."""
        n = (
            sa.select(sa.func.count())
            .where(responses.c.participant_id == participants.c.participant_id)
            .scalar_subquery()
            .label("n_responses")
        )
        query = sa.select(participants, n).order_by(
            participants.c.created_at, participants.c.participant_id
        )
        if not include_simulated:
            query = query.where(participants.c.simulated.is_(False))
        with self.transaction(write=False) as conn:
            rows = conn.execute(query).mappings().all()
        return [{**_participant_dict(r), "n_responses": int(r["n_responses"])} for r in rows]

    def set_background(self, pid: str, answers: dict) -> bool:
        """Store the background answers (``{"age_band", "gender", "experience", ...}``).

        The first answers stay (nothing stored is overwritten): a second call returns
        False and changes nothing. Unknown participant → :class:`StoreError`.
        """
        if not isinstance(answers, dict) or not all(isinstance(k, str) for k in answers):
            raise StoreError(f"background answers must be a dict with string keys, got {answers!r}")
        for key, value in answers.items():
            if not (
                value is None
                or isinstance(value, (str, int, float, bool))
                or (isinstance(value, list) and all(isinstance(v, str) for v in value))
            ):
                raise StoreError(
                    f"background answer {key!r} must be text, a number or a "
                    f"list of text, got {value!r}"
                )

        def work(conn: sa.Connection) -> bool:
            if self._participant_row(conn, pid)["background"] is not None:
                return False
            conn.execute(
                participants.update()
                .where(participants.c.participant_id == pid)
                .values(background=dict(answers))
            )
            return True

        return self._write(work)

    def complete(self, pid: str, *, code: str | None = None) -> str:
        """Mark the participant done and return their completion code (idempotent).

        Parameters
        ----------
        code : str, optional
            The code to hand out (e.g. the study's Prolific completion code); default a
            fresh random 8-character code. Once completed, later calls return the stored
            code whatever ``code`` says.
        """
        if code is not None and (not isinstance(code, str) or not code or len(code) > 64):
            raise StoreError(f"completion code must be 1-64 characters, got {code!r}")
        new = code or "".join(
            secrets.choice(COMPLETION_ALPHABET) for _ in range(COMPLETION_CODE_LENGTH)
        )

        def work(conn: sa.Connection) -> str:
            row = self._participant_row(conn, pid)
            if row["completed_at"] is not None:
                return row["completion_code"]
            conn.execute(
                participants.update()
                .where(participants.c.participant_id == pid)
                .where(participants.c.completed_at.is_(None))
                .values(completed_at=_utcnow(), completion_code=new)
            )
            return new

        return self._write(work)


def _participant_dict(row: sa.RowMapping) -> dict:
    return {
        "participant_id": row["participant_id"],
        "study_id": row["study_id"],
        "seed": int(row["seed"]),
        "created_at": _iso(row["created_at"]),
        "completed_at": _iso(row["completed_at"]),
        "completion_code": row["completion_code"],
        "background": row["background"],
        "prolific_pid": row["prolific_pid"],
        "prolific_study_id": row["prolific_study_id"],
        "prolific_session_id": row["prolific_session_id"],
        "simulated": bool(row["simulated"]),
        "manifest_sha256": row["manifest_sha256"],
        "app_version": row["app_version"],
    }


def _insert_participant(
    conn: sa.Connection,
    *,
    study_id: str,
    seed: int,
    app_version: str,
    manifest_sha256: str,
    simulated: bool,
    values: dict[str, Any],
) -> str:
    """Insert a new participant with a fresh random id (in the caller's transaction) and
    return the id; the study's pseudonym key is made with its first participant."""
    pid = secrets.token_urlsafe(16)
    ensure_secret(conn, study_id)
    conn.execute(
        participants.insert().values(
            participant_id=pid,
            study_id=study_id,
            seed=seed,
            app_version=app_version,
            manifest_sha256=manifest_sha256,
            simulated=simulated,
            created_at=_utcnow(),
            **values,
        )
    )
    return pid
