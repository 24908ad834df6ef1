"""Pseudonyms for exports: identifiers replaced by a keyed hash, stable across exports.

Every export (``snapshot export``, the Psych-DS dataset, the researcher page's
downloads) replaces the columns of :data:`IDENTIFIER_COLUMNS` — the participant link
id, Prolific's participant and session ids, the per-participant completion code (it can
be matched to a Prolific submission) — by ``p-`` and 16 hex digits of
HMAC-SHA256(study secret, column name + value). The same id gives the same pseudonym in
every export of the study, so a re-run analysis joins the same people; without the
secret nobody can go from a pseudonym back to the id, nor test a guessed Prolific id.

The secret is made once per study (``secrets.token_hex(32)``) and kept in the
database's ``study_secrets`` table, in the transaction that registers the study's first
participant (:func:`ensure_secret`, called by the store): a backup taken at any time
after that carries it (a restored database exports the same pseudonyms), no export
does, and exporting from a backup reads it instead of writing a new one.

Open exports also leave out or coarsen every column that could link a row back to
Prolific's records or to an identifiers file without the ids (docs/open-data.md): the
participant's ``seed`` (62 random bits, unique per person) is left out; times
(``created_at``/``completed_at``, to the microsecond) become their UTC month
(``YYYY-MM``: days would group people whom Prolific's start dates tell apart, and
the analysis uses no date); durations (``response_time_s``, ``active_time_s``) are rounded to 0.1 s
and shares watched floored to 0.001 (what the analysis uses: medians in seconds, a watch
threshold such as 0.9); the browser tab's random id (``tab_id``, and ``tab`` in events)
is pseudonymised like an identifier; and rows come ordered by pseudonym
(:meth:`Pseudonymiser.records`), not in arrival order, which Prolific's start times
would match rank for rank. ``snapshot export --identifiers`` keeps everything exact.

:func:`anonymise` destroys a study's secret for good: its row keeps an empty secret
and the time (``anonymised_at``), exports then draw a fresh secret per export that is
never stored, and no pseudonym of a published dataset can be traced to anybody again.
"""

from __future__ import annotations

import hashlib
import hmac
import math
import secrets
from collections.abc import Iterable, Mapping
from datetime import UTC, datetime
from typing import Any, TypeVar, cast

import sqlalchemy as sa
from sqlalchemy import exc as sa_exc

from .database import participants, study_secrets
from .errors import StoreError

__all__ = [
    "IDENTIFIER_COLUMNS",
    "PSEUDONYM_PREFIX",
    "PSEUDONYM_RE",
    "IDENTIFIERS_WARNING",
    "OPEN_DROPPED",
    "TIME_COLUMNS",
    "pseudonym",
    "study_secret",
    "ensure_secret",
    "Pseudonymiser",
    "participants_by_pseudonym",
    "DURATION_COLUMNS",
    "TAB_COLUMN",
    "open_value",
]

#: Columns of any export that identify a person (or link to their Prolific record).
IDENTIFIER_COLUMNS = ("participant_id", "prolific_pid", "prolific_session_id", "completion_code")
#: How a pseudonym starts, so that it is recognisable as one.
PSEUDONYM_PREFIX = "p-"
#: A pseudonym: the prefix and 16 lowercase hex digits (64 bits of the HMAC).
PSEUDONYM_RE = r"^p-[0-9a-f]{16}$"
_HEX_DIGITS = 16
#: Columns left out of open exports: the seed is unique per person (a join key).
OPEN_DROPPED = ("seed",)
#: A record of any kind (an export row, a participant, an event): pseudonymised, it
#: keeps its kind (the same keys, less :data:`OPEN_DROPPED`, none of them an answer's).
_Record = TypeVar("_Record", bound=Mapping[str, Any])
#: Timestamp columns, given as their UTC month (``YYYY-MM``) in open exports.
TIME_COLUMNS = ("created_at", "completed_at")
#: Durations (s), rounded to :data:`DURATION_DECIMALS` places in open exports: 15 digits
#: are the same in an identifiers file and join a row to it.
DURATION_COLUMNS = ("response_time_s", "active_time_s")
DURATION_DECIMALS = 1
#: Shares of the animation watched (0-1), floored to :data:`SHARE_DECIMALS` places (a
#: floor keeps ``watched >= 0.9`` as it was for any threshold of up to 3 decimals).
SHARE_DECIMALS = 3
#: The browser tab's random id: pseudonymised in open exports (the hashed message uses
#: this name for ``tab`` in event payloads too, so responses and events still agree).
TAB_COLUMN = "tab_id"
#: Event payload floats: video time and played ranges (s, frames) to 2 places.
_PAYLOAD_DECIMALS = 2
#: What ``--identifiers`` prints: the files then hold personal data.
IDENTIFIERS_WARNING = (
    "warning: --identifiers: the export holds raw participant, Prolific and "
    "session ids (personal data under the GDPR); keep it private, share the "
    "default pseudonymised export instead"
)


def pseudonym(secret: str, column: str, value: str) -> str:
    """The pseudonym of one identifier.

    Parameters
    ----------
    secret : str
        The study's secret (:func:`study_secret`).
    column : str
        The identifier's column; part of the hashed message, so that the same text in
        two columns gives two unrelated pseudonyms.
    value : str
        The identifier.

    Returns
    -------
    str
        ``p-`` followed by the first 16 hex digits of
        ``HMAC-SHA256(secret, column + "\\x00" + value)``.
    """
    mac = hmac.new(secret.encode(), f"{column}\x00{value}".encode(), hashlib.sha256)
    return PSEUDONYM_PREFIX + mac.hexdigest()[:_HEX_DIGITS]


def ensure_secret(conn, study_id: str) -> None:
    """Make the study's secret in the open transaction ``conn`` unless it exists.

    One ``INSERT ... ON CONFLICT DO NOTHING``: two first participants registered at
    once on PostgreSQL cannot fail each other's registration.
    """
    if conn.dialect.name == "postgresql":
        from sqlalchemy.dialects.postgresql import insert
    elif conn.dialect.name == "sqlite":
        # the same construct as PostgreSQL's (on_conflict_do_nothing), another class
        from sqlalchemy.dialects.sqlite import insert  # type: ignore[assignment]
    else:  # pragma: no cover - other databases: look first (no upsert construct)
        if (
            conn.execute(
                sa.select(study_secrets.c.study_id).where(study_secrets.c.study_id == study_id)
            ).first()
            is None
        ):
            conn.execute(
                study_secrets.insert().values(
                    study_id=study_id, secret=secrets.token_hex(32), created_at=datetime.now(UTC)
                )
            )
        return
    conn.execute(
        insert(study_secrets)
        .values(study_id=study_id, secret=secrets.token_hex(32), created_at=datetime.now(UTC))
        .on_conflict_do_nothing(index_elements=["study_id"])
    )


def study_secret(store, study_id: str) -> str:
    """The study's pseudonym secret, made and stored on first use.

    Two exports started at once may both try to make it: the primary key lets one
    insert win and the other reads the winner's secret.
    """
    query = sa.select(study_secrets.c.secret).where(study_secrets.c.study_id == study_id)
    with store.transaction(write=False) as conn:
        found = conn.execute(query).scalar()
    if found is not None:
        return found
    try:
        with store.transaction(write=True) as conn:
            found = conn.execute(query).scalar()
            if found is None:
                found = secrets.token_hex(32)
                conn.execute(
                    study_secrets.insert().values(
                        study_id=study_id, secret=found, created_at=datetime.now(UTC)
                    )
                )
        return found
    except StoreError as err:
        if not isinstance(err.__cause__, sa_exc.IntegrityError):
            raise  # only a lost insert race is retried
    with store.transaction(write=False) as conn:
        return conn.execute(query).scalar_one()


class Pseudonymiser:
    """Replaces the identifier columns of export records by their pseudonyms.

    Parameters
    ----------
    store : study_app.data.store.Store
        Where the study secrets are (and, for records without a ``study_id`` such as
        events, which study each participant belongs to).

    Examples
    --------
    >>> rows = Pseudonymiser(store).records(store.export_rows())  # doctest: +SKIP
    """

    def __init__(self, store):
        self.store = store
        self._secrets: dict[str, str] = {}
        self._study_of: dict[str, str] | None = None

    def _secret(self, study_id: str) -> str:
        if study_id not in self._secrets:
            # An anonymised study keeps an empty secret: this export gets a fresh one
            # that is never stored (consistent across its files, traceable by nobody).
            self._secrets[study_id] = study_secret(self.store, study_id) or secrets.token_hex(32)
        return self._secrets[study_id]

    def _study(self, record: Mapping[str, Any]) -> str:
        if record.get("study_id"):
            return record["study_id"]
        if self._study_of is None:
            with self.store.transaction(write=False) as conn:
                self._study_of = dict(
                    conn.execute(
                        sa.select(participants.c.participant_id, participants.c.study_id)
                    ).all()
                )
        return self._study_of[record["participant_id"]]

    def record(self, record: Mapping[str, Any]) -> dict[str, Any]:
        """A copy of ``record`` for an open export: every non-empty identifier column
        and the tab id pseudonymised, ``seed`` left out, times as their UTC month,
        durations and shares coarsened (:func:`open_value`)."""
        out = {k: open_value(k, v) for k, v in record.items() if k not in OPEN_DROPPED}
        present = [c for c in (*IDENTIFIER_COLUMNS, TAB_COLUMN) if out.get(c) not in (None, "")]
        payload = out.get("payload")
        tab = payload.get("tab") if isinstance(payload, dict) else None
        if present or tab:
            secret = self._secret(self._study(record))
            for column in present:
                out[column] = pseudonym(secret, column, str(out[column]))
            if tab and isinstance(payload, dict):  # a tab is only read from a dict
                out["payload"] = {**payload, "tab": pseudonym(secret, TAB_COLUMN, str(tab))}
        return out

    def records(self, records: Iterable[_Record]) -> list[_Record]:
        """:meth:`record` of each record, ordered by the (pseudonymised) participant id.

        The sort is stable: one participant's rows keep their order (trials, events in
        time order), while the order of the participants, which would be their arrival
        order, is the pseudonyms' (a keyed hash: as good as shuffled for anyone without
        the secret, and the same in every export of the study).
        """
        out = [cast(_Record, self.record(r)) for r in records]
        return sorted(out, key=lambda r: str(r.get("participant_id") or ""))


def open_value(column: str, value):
    """``value`` of ``column`` as an open export gives it: times as their UTC month,
    durations rounded to 0.1 s, shares floored to 0.001, event payload times and
    ranges to 0.01; anything else as it is."""
    if value is None or isinstance(value, bool):
        return value
    if column in TIME_COLUMNS and isinstance(value, str):
        return _month(value)
    if column in DURATION_COLUMNS and isinstance(value, int | float):
        return round(float(value), DURATION_DECIMALS)
    if column == "watched" and isinstance(value, int | float):
        return _floor(float(value), SHARE_DECIMALS)
    if column == "payload" and isinstance(value, dict):
        out = dict(value)
        if isinstance(out.get("watched"), int | float) and not isinstance(out["watched"], bool):
            out["watched"] = _floor(float(out["watched"]), SHARE_DECIMALS)
        if isinstance(out.get("t"), int | float) and not isinstance(out["t"], bool):
            out["t"] = round(float(out["t"]), _PAYLOAD_DECIMALS)
        if isinstance(out.get("ranges"), list):
            out["ranges"] = [
                [round(float(x), _PAYLOAD_DECIMALS) for x in r] if isinstance(r, list) else r
                for r in out["ranges"]
            ]
        return out
    return value


def _floor(value: float, decimals: int) -> float:
    """``value`` floored to ``decimals`` places (a tiny tolerance keeps 0.9 at 0.9)."""
    scale = 10**decimals
    return math.floor(value * scale + 1e-9) / scale


def _month(value: str) -> str:
    """The UTC month (``YYYY-MM``, an ISO 8601 calendar month) of an ISO 8601 time."""
    t = datetime.fromisoformat(value)
    return (t.replace(tzinfo=UTC) if t.tzinfo is None else t.astimezone(UTC)).strftime("%Y-%m")


def participants_by_pseudonym(store, value: str, *, study_id: str | None = None) -> list[str]:
    """The participant link ids whose participant, Prolific or session id, or completion
    code, has the pseudonym ``value`` (the only id a published dataset shows).

    Every participant's identifiers are hashed with their study's secret and compared;
    nothing is stored. Empty when none matches.
    """
    cond = sa.true() if study_id is None else participants.c.study_id == study_id
    with store.transaction(write=False) as conn:
        keys = dict(conn.execute(sa.select(study_secrets.c.study_id, study_secrets.c.secret)).all())
        rows = conn.execute(sa.select(participants).where(cond)).mappings().all()
    found = []
    for row in rows:
        secret = keys.get(row["study_id"])
        if not secret:  # no secret yet, or destroyed (anonymise): nothing to compare
            continue
        if any(
            row.get(c) not in (None, "")
            and hmac.compare_digest(pseudonym(secret, c, str(row[c])), value)
            for c in IDENTIFIER_COLUMNS
        ):
            found.append(row["participant_id"])
    return found
