"""Wrong researcher tokens: logged and limited, per server process.

Kept in an imported module: the page script itself is run afresh as ``__main__`` on
every script run, so its own globals would forget every try.
"""

from __future__ import annotations

import logging
import threading
from collections import deque

__all__ = [
    "MIN_TOKEN_CHARS",
    "MAX_FAILURES",
    "FAILURE_WINDOW_S",
    "LOCKOUT_S",
    "locked",
    "failed",
    "reset",
]

#: The shortest token the page accepts (a guessable token opens every participant's data).
MIN_TOKEN_CHARS = 16
#: Wrong tokens allowed within FAILURE_WINDOW_S seconds before the page locks.
MAX_FAILURES = 5
FAILURE_WINDOW_S = 60.0
#: Seconds the page refuses every token after too many wrong ones.
LOCKOUT_S = 120.0

_log = logging.getLogger("study_app.researcher")
_FAILURES: deque = deque()
_LOCKED_UNTIL = [0.0]
_GUARD = threading.Lock()


def reset() -> None:
    """Forget the wrong tokens seen (tests; a restart does the same)."""
    with _GUARD:
        _FAILURES.clear()
        _LOCKED_UNTIL[0] = 0.0


def locked(now: float) -> float:
    """Seconds the page stays locked from ``now`` (monotonic seconds); 0 when open."""
    with _GUARD:
        return max(0.0, _LOCKED_UNTIL[0] - now)


def failed(now: float) -> int:
    """Count a wrong token; return the wrong tries in the window (0: the page just locked)."""
    with _GUARD:
        _FAILURES.append(now)
        while _FAILURES and _FAILURES[0] < now - FAILURE_WINDOW_S:
            _FAILURES.popleft()
        n = len(_FAILURES)
        if n >= MAX_FAILURES:
            _LOCKED_UNTIL[0] = now + LOCKOUT_S
            _FAILURES.clear()
    _log.warning(
        "researcher page: wrong access token (%d in the last %.0f s)%s",
        n,
        FAILURE_WINDOW_S,
        f"; locked for {LOCKOUT_S:.0f} s" if n >= MAX_FAILURES else "",
    )
    return 0 if n >= MAX_FAILURES else n
