"""Server-side timing of the app's script runs: a log line each, and a JSON-lines file.

Every script run (one per participant interaction, plus one per ``st.rerun()``) is timed
by a :class:`RunClock`: from the first answer callback of the run (Streamlit runs widget
callbacks just before the script; :func:`callback_started` marks it), else from the
script's first line, to its last. A fragment run (only the part of a page in an
``st.fragment``, e.g. a picker's log batch) is timed the same way, with
``"fragment": true``; a fragment drawn inside a full run is part of that run. The clock
hands each run to :func:`record_run`. It
logs ``script run 12.3 ms stage=pose`` on the ``study_app.web.timing`` logger (debug level,
so a normal server log stays quiet) and, when ``$SNAPSHOT_TIMINGS`` names a file,
appends one JSON line per run there::

    {"t": 1764620000.123, "ms": 12.3, "cpu_ms": 9.8, "stage": "pose", "pid": 4242}
    {"t": 1764620001.456, "ms": 3.1, "cpu_ms": 2.9, "stage": "pose", "pid": 4242, "fragment": true}

``ms`` is the wall time of the run, ``cpu_ms`` the CPU time of the thread that ran it:
under load the two differ by the time the run waited for the interpreter (Streamlit
runs every session's script in one process), so ``cpu_ms`` is the cost of a page and
``ms - cpu_ms`` the queueing.

``snapshot loadtest --timings FILE`` reads that file back, so an interaction's latency
splits into the server's work and everything else (transport, queueing, Streamlit's own
message handling). Several replicas can share one file: each line is a single
``write`` of less than a pipe buffer in append mode, and carries the process id.
"""

from __future__ import annotations

import json
import logging
import os
import threading
import time

__all__ = [
    "ENV_TIMINGS",
    "RunClock",
    "callback_started",
    "in_fragment_run",
    "record_run",
    "read_timings",
]

#: Environment variable naming the JSON-lines file of script-run timings.
ENV_TIMINGS = "SNAPSHOT_TIMINGS"
log = logging.getLogger("study_app.web.timing")
_lock = threading.Lock()
#: Per script thread: the clock of the run in progress, and when its callbacks began.
_local = threading.local()
_file = None
_file_path = None


def _handle():
    """This process's append handle on the timings file (opened once), or None."""
    global _file, _file_path
    path = os.environ.get(ENV_TIMINGS)
    if not path:
        return None
    with _lock:
        if _file is None or _file_path != path:
            _file = open(path, "a", buffering=1, encoding="utf-8")  # noqa: SIM115 - per process
            _file_path = path
    return _file


def callback_started() -> None:
    """Mark, in a widget callback, that this thread's coming run began now (its answer
    is stored here, before the script: that time belongs to the run)."""
    if getattr(_local, "callback", None) is None:
        _local.callback = (time.perf_counter(), time.thread_time())


def in_fragment_run() -> bool:
    """True inside a fragment's own run (not a fragment drawn by a full run)."""
    clock = getattr(_local, "clock", None)
    return clock is not None and clock._fragment


class RunClock:
    """Times one script or fragment run of this thread; see the module docstring.

    Parameters
    ----------
    stage : callable
        Returns the stage to record (read when the run ends, after it moved on).
    fragment : bool
        A fragment's own run. When this thread is already inside a run (the fragment is
        drawn by a full run), the clock records nothing.
    """

    def __init__(self, stage, *, fragment: bool = False):
        self._stage = stage
        self._fragment = fragment
        self._outer = False

    def __enter__(self) -> RunClock:
        self._outer = getattr(_local, "clock", None) is None
        if self._outer:
            _local.clock = self
            self._t0: float
            self._c0: float
            self._t0, self._c0 = getattr(_local, "callback", None) or (
                time.perf_counter(),
                time.thread_time(),
            )
            _local.callback = None
        return self

    def __exit__(self, *exc) -> None:
        if not self._outer:
            return
        _local.clock = None
        record_run(
            time.perf_counter() - self._t0,
            stage=self._stage(),
            cpu_seconds=time.thread_time() - self._c0,
            fragment=self._fragment,
        )


def record_run(
    seconds: float, *, stage: str, cpu_seconds: float | None = None, fragment: bool = False
) -> None:
    """Record one script run of ``seconds`` (wall time; ``cpu_seconds`` of its thread's
    CPU time) on the page of ``stage``; ``fragment``: a fragment's own run."""
    ms = round(seconds * 1000.0, 2)
    log.debug("script run %.1f ms stage=%s%s", ms, stage, " (fragment)" if fragment else "")
    f = _handle()
    if f is not None:
        row = {"t": round(time.time(), 3), "ms": ms, "stage": stage, "pid": os.getpid()}
        if cpu_seconds is not None:
            row["cpu_ms"] = round(cpu_seconds * 1000.0, 2)
        if fragment:
            row["fragment"] = True
        line = json.dumps(row) + "\n"
        with _lock:
            f.write(line)


def read_timings(paths, *, since: float = 0.0, until: float = float("inf")) -> list[dict]:
    """The script runs recorded in ``paths`` between ``since`` and ``until`` (epoch s).

    Malformed lines (a server killed mid-write) are skipped.
    """
    out = []
    for p in paths:
        try:
            with open(p, encoding="utf-8") as f:
                for line in f:
                    try:
                        row = json.loads(line)
                    except ValueError:
                        continue
                    if isinstance(row, dict) and since <= row.get("t", -1) <= until:
                        out.append(row)
        except FileNotFoundError:
            continue
    return out
