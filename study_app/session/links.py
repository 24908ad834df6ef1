"""The study's links: Prolific's URL parameters, the participant's resume link, and URL
values described safely for the researcher's log.
"""

from __future__ import annotations

import re

__all__ = ["PROLIFIC_KEYS", "prolific_problems", "prolific_params", "resume_url", "describe_value"]

#: URL parameters Prolific appends to a study link; recorded when present.
PROLIFIC_KEYS = ("PROLIFIC_PID", "STUDY_ID", "SESSION_ID")
#: Prolific ids are 24 hex characters; accept any short token of safe characters.
_PROLIFIC_VALUE = re.compile(r"^[A-Za-z0-9_-]{1,64}$")


def prolific_problems(query: dict) -> list[str]:
    """What is wrong with the Prolific parameters of a URL query (empty when nothing is).

    A present but malformed ``PROLIFIC_PID``, ``STUDY_ID`` or ``SESSION_ID`` (too long,
    characters a Prolific id never has, given twice) must stop the participant on the
    first page: storing the participant without it would lose who they are.

    Returns
    -------
    list of str
        One participant-facing sentence per malformed parameter.
    """
    out = []
    for k in PROLIFIC_KEYS:
        if k not in query:
            continue
        v = query.get(k)
        if isinstance(v, list) and len(v) == 1:
            v = v[0]
        if not isinstance(v, str) or not _PROLIFIC_VALUE.match(v):
            out.append(
                f"The study link's {k} is not a valid Prolific value (expected up to 64 "
                "letters, digits, '-' or '_')."
            )
    return out


def resume_url(base_url: str, participant_id: str) -> str:
    """The participant's personal link: the app's address with only ``?pid=``."""
    from urllib.parse import urlencode, urlsplit, urlunsplit

    parts = urlsplit(base_url or "/")
    path = parts.path
    for suffix in ("/study", "/researcher"):  # the page's own address, not the app's
        if path.endswith(suffix):
            path = path[: -len(suffix)]
    return urlunsplit(
        (parts.scheme, parts.netloc, path.rstrip("/") + "/", urlencode({"pid": participant_id}), "")
    )


def describe_value(value, limit: int = 80) -> str:
    """A safe one-line rendering of a value from the URL for the researcher's log."""
    text = ascii(value)
    return text if len(text) <= limit else text[:limit] + f"... ({len(text)} characters)"


def prolific_params(query: dict) -> dict:
    """The Prolific parameters of a URL query (``PROLIFIC_PID``, ``STUDY_ID``, ``SESSION_ID``).

    Values that could not be Prolific ids (wrong characters, too long, a list) are
    dropped rather than stored.
    """
    out = {}
    for k in PROLIFIC_KEYS:
        v = query.get(k)
        if isinstance(v, str) and _PROLIFIC_VALUE.match(v):
            out[k] = v
    return out
