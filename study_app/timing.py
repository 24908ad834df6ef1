"""Server-side timing of the app's script runs: a log line each, and a JSON-lines file.

Every script run (one per participant interaction, plus one per ``st.rerun()``) is timed
by ``app.py`` from its first line to its last, and handed to :func:`record_run`. It
logs ``script run 12.3 ms stage=pose`` on the ``study_app.timing`` logger (debug level,
so a normal server log stays quiet) and, when ``$SNAPSHOT_TIMINGS`` names a file,
appends one JSON line per run there::

    {"t": 1764620000.123, "ms": 12.3, "cpu_ms": 9.8, "stage": "pose", "pid": 4242}

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

__all__ = ["ENV_TIMINGS", "record_run", "read_timings"]

#: Environment variable naming the JSON-lines file of script-run timings.
ENV_TIMINGS = "SNAPSHOT_TIMINGS"
log = logging.getLogger("study_app.timing")
_lock = threading.Lock()
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


def record_run(seconds: float, *, stage: str, cpu_seconds: float | None = None) -> None:
    """Record one script run of ``seconds`` (wall time; ``cpu_seconds`` of its thread's
    CPU time) on the page of ``stage``."""
    ms = round(seconds * 1000.0, 2)
    log.debug("script run %.1f ms stage=%s", ms, stage)
    f = _handle()
    if f is not None:
        row = {"t": round(time.time(), 3), "ms": ms, "stage": stage, "pid": os.getpid()}
        if cpu_seconds is not None:
            row["cpu_ms"] = round(cpu_seconds * 1000.0, 2)
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
