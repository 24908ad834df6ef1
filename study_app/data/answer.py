"""The answer record: one participant's answer to one trial, as every layer passes it on.

An answer is made by the session (:class:`~study_app.session.ParticipantSession`, or a
simulated participant, :mod:`analysis.simulate`), checked and stored by the store
(:meth:`~study_app.data.store.Store.record_response`), read back as an export row
(:meth:`~study_app.data.store.Store.export_rows`), written to and read from export files
(:func:`~study_app.data.export.write_export`, :func:`~study_app.data.export.read_export`)
and loaded by :func:`analysis.load.load_responses`. At run time both records are plain
dicts (JSON, SQL rows, CSV cells): these types tell the type checker, and the reader,
which keys each hop may rely on. ``data_schema/response.schema.json`` is the contract the
fields follow (``tests/test_answer_record.py`` checks that the two agree).

This module has no ``from __future__ import annotations``: ``Required`` must be seen at
run time for ``__required_keys__`` to be right.
"""

from typing import Literal, Required, TypedDict

__all__ = ["Answer", "ClientFields", "ResponseRow", "Task"]

#: The three tasks of a study.
Task = Literal["pose", "view", "attention"]


class ClientFields(TypedDict):
    """What an answer was given on (:func:`study_app.session.client_fields`); None where
    the browser's report was missing or malformed."""

    viewport_width: int | None
    viewport_height: int | None
    device_pixel_ratio: float | None
    input_type: Literal["mouse", "touch", "pen", "keyboard"] | None
    active_time_s: float | None
    tab_id: str | None


class Answer(TypedDict, total=False):
    """One trial's answer as the session hands it to the store (the trial fields).

    Frames are in source numbering (the motion file's). The task decides which optional
    fields are set: a pose answer its frames, ``fps``, ``n_frames``, ``picked_with`` and
    ``watched``; a view answer ``chosen_method``, ``chosen_position``, ``shown_order`` and
    ``shown_groups`` (or ``skipped``); an attention answer ``chosen_value`` and
    ``correct``. The store fills the rest of a :class:`ResponseRow`.
    """

    trial_index: Required[int]
    task: Required[Task]
    scene: Required[str]
    stimulus_id: Required[str]
    chosen_frame: int | None
    chosen_video_frame: int | None
    algorithm_frame: int | None
    fps: float | None
    n_frames: int | None
    chosen_method: str | None  # one of snapcore.select.VIEW_METHODS (the store checks)
    chosen_position: int | None
    shown_order: list[str] | None
    chosen_value: str | None
    correct: bool | None
    response_time_s: Required[float]
    picked_with: Literal["player", "slider"] | None
    watched: float | None
    viewport_width: int | None
    viewport_height: int | None
    device_pixel_ratio: float | None
    input_type: Literal["mouse", "touch", "pen", "keyboard"] | None
    active_time_s: float | None
    tab_id: str | None
    shown_groups: list[list[str]] | None
    skipped: Literal["media_failed"] | None


class ResponseRow(Answer, total=False):
    """One row of ``data_schema/response.schema.json``: an :class:`Answer` with what the
    store adds (who, which study, which app and stimuli, when, simulated or not) and the
    participant's background answers joined in. What :meth:`Store.export_rows
    <study_app.data.store.Store.export_rows>` returns, export files hold and
    :func:`analysis.load.load_responses` reads; ``created_at`` is ISO 8601 text, UTC."""

    participant_id: Required[str]
    study_id: Required[str]
    created_at: Required[str]
    app_version: Required[str]
    manifest_sha256: Required[str]
    simulated: Required[bool]
    age_band: str | None
    gender: str | None
    experience: str | None
    prolific_pid: str | None
