"""What a participant's browser reports with a trial, checked before it is stored: the
frame picker's event log, the video frames played (and the share of the animation they
cover), and the client an answer was given on (viewport, input, active time, tab).

Anything malformed is dropped, never stored: the browser is not trusted.
"""

from __future__ import annotations

import math
import re
from typing import Any

from study_app.data.answer import ClientFields

__all__ = [
    "EVENT_KINDS",
    "MEDIA_FAILED_EVENT",
    "MEDIA_LOADED_EVENT",
    "PICKED_WITH",
    "INPUT_TYPES",
    "WATCHED_ENOUGH",
    "SHOWN_EVENT",
    "MAX_EVENTS_PER_TRIAL",
    "client_fields",
]

#: Picker interactions worth keeping (plays, pauses, seeks, frame steps, scrubbing).
EVENT_KINDS = ("play", "pause", "seek", "step", "scrub", "ended", "select", "watch")
#: The event the server stores when a trial's media did not load in the participant's
#: browser after retries (nothing is answered: the chooser stays closed, the player
#: falls back to the frame slider, whose answers say so).
MEDIA_FAILED_EVENT = "media_failed"
#: The event stored when "Try again" brought every picture of a view trial back after a
#: :data:`MEDIA_FAILED_EVENT`: the positions it named can be chosen again.
MEDIA_LOADED_EVENT = "media_loaded"
#: How a pose answer's frame was picked: in the video player, or on the frame slider
#: (the fallback when the video cannot be played, or the study's ``picker = "frames"``).
PICKED_WITH = ("player", "slider")
#: Input types a browser reports for the click that answered.
INPUT_TYPES = ("mouse", "touch", "pen", "keyboard")
#: A browser tab's id as the page reports it (picker log entries, answers, failures).
_TAB = re.compile(r"^[A-Za-z0-9_-]{1,32}$")
#: Share of the animation that must have been played (the video's played ranges) for
#: "watched through once": a little under 1, as the last frame's interval and a
#: dropped frame at the start are not counted as played by every browser.
WATCHED_ENOUGH = 0.9
#: The event the server stores when a trial is first shown: its response time counts
#: from there, across reloads and tabs (never sent by the browser).
SHOWN_EVENT = "shown"
#: A cap on stored events per trial, so a runaway client cannot flood the store.
MAX_EVENTS_PER_TRIAL = 500


def _picker_items(events, *, n_video_frames: int) -> list[tuple[str, dict]]:
    """The picker's log entries as ``(kind, payload)`` for the store: known kinds only,
    well-formed fields only (frames inside the video), at most
    :data:`MAX_EVENTS_PER_TRIAL`."""
    items = []
    for ev in list(events or [])[:MAX_EVENTS_PER_TRIAL]:
        if not isinstance(ev, dict) or ev.get("kind") not in EVENT_KINDS:
            continue
        payload: dict[str, Any] = {}  # plain JSON for the store
        t = ev.get("t")
        if isinstance(t, (int, float)) and not isinstance(t, bool) and math.isfinite(t):
            payload["t"] = round(float(t), 3)
        for key in ("frame", "from"):
            f = ev.get(key)
            if isinstance(f, int) and not isinstance(f, bool) and 0 <= f < n_video_frames:
                payload[key] = f
        if ev.get("by") in (-1, 1) and not isinstance(ev.get("by"), bool):
            payload["by"] = ev["by"]
        w = ev.get("watched")
        if isinstance(w, (int, float)) and not isinstance(w, bool) and 0 <= w <= 1:
            payload["watched"] = round(float(w), 3)
        ranges = _ranges(ev.get("ranges"), limit=n_video_frames + 1)
        if ranges:
            payload["ranges"] = ranges
        if isinstance(ev.get("tab"), str) and _TAB.match(ev["tab"]):
            payload["tab"] = ev["tab"]
        items.append((ev["kind"], payload))
    return items


def _number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _ranges(value, *, limit: float = 1e6) -> list[list[float]]:
    """Well-formed ``[[from, to], ...]`` video-frame ranges (at most 64, inside
    ``[0, limit]``), united; anything else is dropped."""
    if not isinstance(value, list):
        return []
    out = [
        [round(float(r[0]), 2), round(float(r[1]), 2)]
        for r in value[:64]
        if isinstance(r, list)
        and len(r) == 2
        and all(_number(x) for x in r)
        and 0 <= r[0] < r[1] <= limit
    ]
    return _unite(out)


def _unite(ranges) -> list[list[float]]:
    """Sorted ranges with overlaps merged."""
    out: list[list[float]] = []
    for a, b in sorted(ranges):
        if out and a <= out[-1][1]:
            out[-1][1] = max(out[-1][1], b)
        else:
            out.append([a, b])
    return out


def _share(ranges, n_video_frames: int, more=()) -> float:
    """Share of an ``n_video_frames`` animation the ranges (with ``more``) cover."""
    covered = sum(
        min(b, n_video_frames) - max(a, 0.0)
        for a, b in _unite(list(ranges) + list(more))
        if b > 0 and a < n_video_frames
    )
    return min(covered / n_video_frames, 1.0) if n_video_frames > 0 else 0.0


def client_fields(client, response_time_s: float) -> ClientFields:
    """The response columns of what an answer was given on, from the widget's ``client``
    report (``{viewport: [w, h], dpr, input, active_s, tab}``): well-formed values only
    (None otherwise); the active time at most the response time."""
    c: dict[str, Any] = client if isinstance(client, dict) else {}
    vp: Any = c.get("viewport")  # the browser's report: any JSON, checked below
    ok_vp = (
        isinstance(vp, list)
        and len(vp) == 2
        and all(isinstance(x, int) and not isinstance(x, bool) and 0 < x < 100_000 for x in vp)
    )
    dpr: Any = c.get("dpr")
    active: Any = c.get("active_s")
    return {
        "viewport_width": vp[0] if ok_vp else None,
        "viewport_height": vp[1] if ok_vp else None,
        "device_pixel_ratio": round(float(dpr), 3) if _number(dpr) and 0 < dpr <= 16 else None,
        "input_type": c.get("input") if c.get("input") in INPUT_TYPES else None,
        "active_time_s": min(round(float(active), 3), response_time_s)
        if _number(active) and active >= 0
        else None,
        "tab_id": c.get("tab") if isinstance(c.get("tab"), str) and _TAB.match(c["tab"]) else None,
    }
