"""One participant's way through the study: the app's logic layer (no Streamlit here).

The flow is a small state machine driven entirely by what the store holds, so a reload,
a second tab or a return days later lands on the same step::

    CONSENT ──(agree: participant created, id goes in the URL)──▶ BACKGROUND
    BACKGROUND ──(answers stored)──▶ first unanswered trial (POSE / VIEW / ATTENTION)
    ... every trial answered ──▶ DONE (completion code)

:class:`ParticipantSession` checks every answer against the participant's seeded plan
and the stimuli manifest *before* calling the store: a tampered or unknown id, an
answer to a trial that is not the current one, an out-of-range frame or a forged
method label raises a :class:`SessionError` with a message for the participant, and
nothing is written.

The package holds, one module per concept: :mod:`.participant` (the session and its
stages), :mod:`.errors` (what cannot be accepted), :mod:`.events` (what the browser
reports, sanitised) and :mod:`.links` (Prolific's URL parameters, the resume link).
Import the public names from here.
"""

from __future__ import annotations

from .errors import (
    InvalidAnswer,
    MaterialsChanged,
    SessionError,
    TooEarly,
    UnknownParticipant,
    Withdrawn,
)
from .events import (
    EVENT_KINDS,
    MAX_EVENTS_PER_TRIAL,
    MEDIA_FAILED_EVENT,
    PICKED_WITH,
    SHOWN_EVENT,
    WATCHED_ENOUGH,
    client_fields,
)
from .links import PROLIFIC_KEYS, describe_value, prolific_params, prolific_problems, resume_url
from .participant import STALE_TAB_TEXT, ParticipantSession, Stage

__all__ = [
    "Stage",
    "SessionError",
    "UnknownParticipant",
    "Withdrawn",
    "MaterialsChanged",
    "InvalidAnswer",
    "TooEarly",
    "prolific_problems",
    "resume_url",
    "describe_value",
    "WATCHED_ENOUGH",
    "ParticipantSession",
    "prolific_params",
    "PROLIFIC_KEYS",
    "EVENT_KINDS",
    "MEDIA_FAILED_EVENT",
    "PICKED_WITH",
    "client_fields",
    "SHOWN_EVENT",
    "MAX_EVENTS_PER_TRIAL",
    "STALE_TAB_TEXT",
]
