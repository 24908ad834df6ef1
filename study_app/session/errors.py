"""The session's exceptions: what a participant did that cannot be accepted.

Every message is for the participant (the app shows it as it is).
"""

from __future__ import annotations

from snapcore.errors import SnapshotError

__all__ = [
    "SessionError",
    "UnknownParticipant",
    "MaterialsChanged",
    "Withdrawn",
    "InvalidAnswer",
    "TooEarly",
]


class SessionError(SnapshotError):
    """Something a participant did that cannot be accepted; the message is for them."""


class UnknownParticipant(SessionError):
    """A participant id (from the URL) that is malformed, unknown or from another study."""


class MaterialsChanged(UnknownParticipant):
    """A participant whose stimulus set is no longer on the server (what they answered
    so far is stored; nothing more can be)."""


class Withdrawn(UnknownParticipant):
    """A participant link (or Prolific id) whose data were withdrawn and deleted."""

    def __init__(self, when):
        super().__init__(
            f"Your data were withdrawn from this study on {when:%d %B %Y} and "
            "deleted, as you asked. Nothing more is recorded from this link. "
            "Thank you for your interest in the study."
        )


class InvalidAnswer(SessionError):
    """An answer that does not fit the current trial (nothing was written)."""


class TooEarly(InvalidAnswer):
    """An answer that came before its trial was on screen for the study's minimum time
    (e.g. the second click of a double click landing on the next trial)."""
