"""The study store: participants, their answers and their interaction events, in SQL.

SQLAlchemy 2 Core, like all the study's SQL (:mod:`study_app.data`). SQLite by default, at
``<repo>/var/study.db`` (``$SNAPSHOT_DB`` or an explicit URL override it); any
SQLAlchemy URL works, e.g. PostgreSQL through psycopg
(``postgresql+psycopg://user:password@host:5432/db``; a plain ``postgresql://`` URL is
mapped to psycopg).

Tables
------
``participants``
    One row per participant: an unguessable id (``secrets.token_urlsafe(16)``), the
    study id, the per-participant seed, Prolific's ``PROLIFIC_PID``/``STUDY_ID``/
    ``SESSION_ID`` when present, the background answers (JSON), the app version, the
    stimulus-manifest sha256, the simulated flag, created/completed timestamps and the
    completion code.
``responses``
    Append-only, one row per trial, ``UNIQUE (participant_id, trial_index)``: task,
    scene, stimulus, the chosen motion frame (source numbering) and video frame, the
    algorithm's frame, the chosen method/position and the order the methods were shown
    in, the raw chosen value, response time, timestamp, app version, manifest hash.
``events``
    Interaction events (plays, pauses, seeks, steps...) with a JSON payload.
``withdrawals``, ``study_secrets``
    Who withdrew (:mod:`study_app.data.withdraw`) and the per-study pseudonym keys
    (:mod:`study_app.data.pseudonym`); those modules hold their queries. Opening a database
    made before them adds them.

Safety
------
Every write is one transaction. On SQLite each connection gets WAL journaling, a busy
timeout and foreign keys (a connect event), and write transactions start with
``BEGIN IMMEDIATE`` so that concurrent writers queue on the busy timeout instead of
failing when a read lock cannot be upgraded. A re-sent answer hits the unique key:
:meth:`Store.record_response` returns False and the first row stays. An unknown or
malformed participant id raises :class:`StoreError` and writes nothing. Opening a
store only creates missing tables (never drops or alters anything). A broken URL (bad
scheme, unreachable host, wrong password, unwritable SQLite path) raises a one-line
:class:`StoreError` naming the URL with the password masked.

Timestamps are stored in UTC and returned/exported as ISO 8601 strings with an explicit
``+00:00`` offset (``2025-01-31T12:00:00.123456+00:00``).

Export format
-------------
:meth:`Store.export_rows` gives one dict per response with exactly the fields of
``data_schema/response.schema.json`` (absent optional fields are ``None``); the codec,
:mod:`study_app.data.export`, writes them as CSV or JSON lines and reads them back.

The store is one class made of one part per concept: :class:`~.engine.StoreEngine` (the
engine, transactions, participant-id checks), :class:`~.participant_records.ParticipantRecords`,
:class:`~.response_records.ResponseRecords`, :class:`~.event_records.EventRecords` and
:class:`~.researcher_queries.ResearcherQueries`.
"""

from __future__ import annotations

from .database import default_url, mask_url, normalize_url
from .event_records import EventRecords
from .participant_records import ParticipantRecords
from .researcher_queries import ResearcherQueries
from .response_records import ResponseRecords

__all__ = ["Store", "default_url", "mask_url", "normalize_url"]


class Store(ParticipantRecords, ResponseRecords, EventRecords, ResearcherQueries):
    """Participants, responses and events in one SQL database.

    Parameters
    ----------
    url : str, optional
        SQLAlchemy URL (or a path to a SQLite file). Default: ``$SNAPSHOT_DB``, else
        ``sqlite:///<repo>/var/study.db`` (its folder is created).
    create : bool
        Create missing tables (never drops or changes existing ones). Default True.
        With False (readers such as ``snapshot export``) a missing SQLite file or
        missing tables are an error instead.

    Raises
    ------
    StoreError
        One line naming the (password-masked) URL when the database cannot be opened.

    Notes
    -----
    Thread-safe: one ``Store`` (one connection pool) is meant to be shared by every
    session of the app. Each method is one transaction.
    """
