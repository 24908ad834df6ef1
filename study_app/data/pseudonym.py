"""Pseudonyms for exports: identifiers replaced by a keyed hash, stable across exports.

Every export (``snapshot export``, the Psych-DS dataset, the researcher page's
downloads) replaces the columns of :data:`IDENTIFIER_COLUMNS` — the participant link
id, Prolific's participant and session ids, the per-participant completion code (it can
be matched to a Prolific submission) — by ``p-`` and 16 hex digits of
HMAC-SHA256(study secret, column name + value). The same id gives the same pseudonym in
every export of the study, so a re-run analysis joins the same people; without the
secret nobody can go from a pseudonym back to the id, nor test a guessed Prolific id.

The secret is made once per study (``secrets.token_hex(32)``) and kept in the
database's ``study_secrets`` table: a backup carries it (a restored database exports
the same pseudonyms), no export does.
"""

from __future__ import annotations

import hashlib
import hmac
import secrets
from datetime import UTC, datetime

import sqlalchemy as sa
from sqlalchemy import exc as sa_exc

from .database import participants, study_secrets
from .errors import StoreError

__all__ = ["IDENTIFIER_COLUMNS", "PSEUDONYM_PREFIX", "PSEUDONYM_RE", "IDENTIFIERS_WARNING",
           "pseudonym", "study_secret", "Pseudonymiser"]

#: Columns of any export that identify a person (or link to their Prolific record).
IDENTIFIER_COLUMNS = ("participant_id", "prolific_pid", "prolific_session_id", "completion_code")
#: How a pseudonym starts, so that it is recognisable as one.
PSEUDONYM_PREFIX = "p-"
#: A pseudonym: the prefix and 16 lowercase hex digits (64 bits of the HMAC).
PSEUDONYM_RE = r"^p-[0-9a-f]{16}$"
_HEX_DIGITS = 16
#: What ``--identifiers`` prints: the files then hold personal data.
IDENTIFIERS_WARNING = ("warning: --identifiers: the export holds raw participant, Prolific and "
                       "session ids (personal data under the GDPR); keep it private, share the "
                       "default pseudonymised export instead")


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
                conn.execute(study_secrets.insert().values(
                    study_id=study_id, secret=found, created_at=datetime.now(UTC)))
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
            self._secrets[study_id] = study_secret(self.store, study_id)
        return self._secrets[study_id]

    def _study(self, record: dict) -> str:
        if record.get("study_id"):
            return record["study_id"]
        if self._study_of is None:
            with self.store.transaction(write=False) as conn:
                self._study_of = dict(conn.execute(sa.select(
                    participants.c.participant_id, participants.c.study_id)).all())
        return self._study_of[record["participant_id"]]

    def record(self, record: dict) -> dict:
        """A copy of ``record`` with every non-empty identifier column pseudonymised."""
        out = dict(record)
        present = [c for c in IDENTIFIER_COLUMNS if out.get(c) not in (None, "")]
        if present:
            secret = self._secret(self._study(record))
            for column in present:
                out[column] = pseudonym(secret, column, str(out[column]))
        return out

    def records(self, records) -> list[dict]:
        """:meth:`record` of each record, in order."""
        return [self.record(r) for r in records]
