"""Browser widgets of the study: a frame-accurate video frame picker and a view chooser.

Both are Streamlit components v2 (``st.components.v2.component``): inline JavaScript
and CSS read from this folder, no build step, mounted in the app page (not an iframe).
Each reports one *trigger* value per answer, so a trial costs one round trip:

- :func:`frame_picker` — the video with play/pause, step ±1 frame, a scrub bar and the
  frame number; returns ``{"trial", "frame", "events", "watched"}`` when the participant
  confirms (``frame`` = the 0-based video frame on screen, read with
  ``requestVideoFrameCallback``), ``{"trial", "log"}`` for a batch of its interaction
  log (sent as it happens), or ``{"trial", "error"}`` if the browser cannot play the
  video.
- :func:`view_chooser` — the candidate views side by side, by position only (which
  method made which picture never reaches the browser); returns
  ``{"trial", "position"}`` for the one clicked.

Media reach the browser through Streamlit's media file manager (the mechanism behind
``st.video``/``st.image``), which serves them with HTTP range requests, so seeking works.
"""

from __future__ import annotations

from functools import cache, partial
from pathlib import Path

__all__ = [
    "frame_picker",
    "view_chooser",
    "copy_button",
    "confirmed",
    "chosen",
    "skipped",
    "answer_button",
    "pressed",
    "media_url",
    "pin_files",
    "FRAME_PICKER",
    "VIEW_CHOOSER",
    "DEFAULT_LABELS",
]

HERE = Path(__file__).resolve().parent
#: Component names (unique in the app).
FRAME_PICKER = "snapshot_frame_picker"
VIEW_CHOOSER = "snapshot_view_chooser"
COPY_LINK = "snapshot_copy_link"
ANSWER_BUTTON = "snapshot_answer_button"
#: Text shown by the widgets (English defaults; pass ``labels`` to translate).
DEFAULT_LABELS = {
    "play": "Play",
    "pause": "Pause",
    "back": "Previous frame",
    "forward": "Next frame",
    "frame": "Frame",
    "confirm": "Confirm this frame",
    "saving": "Saving…",
    "scrub": "Position in the animation",
    "video_error": "The video cannot be played",
    "choose": "Choose",
    "watch_first": "Watch the whole animation once to choose a frame.",
    "video": "The animation",
    "retry": "Try again",
    "not_saved": "The connection was lost: your answer was not saved. Please press Confirm again.",
    "not_saved_choice": "The connection was lost: your choice was not saved. Please choose again.",
    "image_error": "A picture could not be loaded, so this question cannot be answered yet.",
    "skip": "I can't see the pictures: skip this question",
}
_MIME = {
    ".mp4": "video/mp4",
    ".webm": "video/webm",
    ".png": "image/png",
    ".jpg": "image/jpeg",
    ".jpeg": "image/jpeg",
}


#: The components get their data wrapped in a one-item list, ``[data]`` (the JavaScript
#: reads ``component.data[0]``). Streamlit probes every value of a dict given as data for
#: a dataframe to convert to Arrow (~1.8 ms for the player's data, on every run that
#: draws it; measured), and passes a list through as JSON (~15 µs).


@cache
def _components():
    import streamlit as st

    css = (HERE / "picker.css").read_text(encoding="utf-8")
    picker = st.components.v2.component(FRAME_PICKER, js=_script("frame_picker.js"), css=css)
    chooser = st.components.v2.component(VIEW_CHOOSER, js=_script("view_chooser.js"), css=css)
    return picker, chooser


def _script(name: str) -> str:
    """A component's JavaScript with the shared client report (client.js) before it."""
    return (
        (HERE / "client.js").read_text(encoding="utf-8")
        + "\n"
        + (HERE / name).read_text(encoding="utf-8")
    )


@cache
def _answer_component():
    import streamlit as st

    css = (HERE / "picker.css").read_text(encoding="utf-8")
    return st.components.v2.component(ANSWER_BUTTON, js=_script("answer_button.js"), css=css)


def answer_button(
    label: str, *, key: str, tab_key: str, on_press, args: tuple = (), testid: str = ""
) -> None:
    """A button whose press is an answer, reporting what it was given on (viewport,
    device pixel ratio, input, active time, tab id) as the pickers do; ``on_press(*args)``
    runs before the script run it causes (read the report with :func:`pressed`).

    Parameters
    ----------
    label : str
    key : str
        Streamlit element key.
    tab_key : str
        Names the participant's trial in the browser tab (the active time counted under
        it by the trial's pickers goes on).
    testid : str
        The button's ``data-testid``.
    """
    _answer_component()(
        key=key,
        data=[{"label": label, "tab_key": str(tab_key), "testid": testid}],
        on_press_change=_bound(on_press, args),
    )


def pressed(key: str) -> dict | None:
    """In an ``on_press`` callback: the answer button's ``{"client"}``, or None."""
    return _trigger(key, "press")


#: {absolute path: sha256} of the stimulus files the server serves (:func:`pin_files`).
_PINNED: dict[str, str] = {}


def pin_files(digests: dict[str, str]) -> None:
    """Serve the files named in ``digests`` (``{absolute path: sha256}``, the manifest
    the server started with) only with those contents."""
    _PINNED.update(digests)


@cache
def _media_bytes(path: str) -> bytes:
    """A stimulus file's bytes, read once per server process and checked against the
    pinned manifest (:func:`pin_files`).

    Streamlit's media manager reads and hashes a file given by path on every call,
    holding its one process-wide lock; with every participant's page registering its
    videos and pictures on every script run, threads queued on that lock under load.
    A file whose bytes are not the ones the study started with (changed on disk since)
    is refused, never served under the old manifest's records.

    Raises
    ------
    StimuliError
        The file is missing or its sha256 differs from the pinned one (one line).
    """
    import hashlib

    from study_app.design.stimuli import StimuliError

    try:
        data = Path(path).read_bytes()
    except OSError as err:
        raise StimuliError(f"stimulus file {path} cannot be read ({err.strerror})") from None
    want = _PINNED.get(path)
    if want is not None and hashlib.sha256(data).hexdigest() != want:
        _media_bytes.cache_clear()  # nothing of a changed set stays cached
        raise StimuliError(
            f"stimulus file {path} changed on disk since the study started "
            "(its sha256 differs from the manifest); restart the study "
            "server on a stimuli folder that is not rebuilt in place"
        )
    return data


def media_url(path: str | Path, *, where: str) -> str:
    """A URL the browser can fetch ``path`` from (served by the running Streamlit app).

    Parameters
    ----------
    path : path
        A video or image file.
    where : str
        A stable name for the place in the page that shows it (the media manager frees
        a session's file when another one takes its place).
    """
    from streamlit.runtime import Runtime
    from streamlit.runtime.scriptrunner_utils.script_run_context import get_script_run_ctx

    p = Path(path)
    mime = _MIME.get(p.suffix.lower(), "application/octet-stream")
    ctx = get_script_run_ctx()
    coordinates = f"snapshot.{where}" if ctx is None else f"snapshot.{ctx.page_script_hash}.{where}"
    # Keyed by the path as given (the stimuli's paths are absolute): resolving it on
    # every run cost a few file-system calls per picture per run.
    return Runtime.instance().media_file_mgr.add(_media_bytes(str(p)), mime, coordinates)


def frame_picker(
    video: str | Path | list,
    *,
    fps: float,
    n_frames: int,
    trial: int,
    key: str,
    start_frame: int = 0,
    watched: float = 0.0,
    watched_ranges=(),
    require_watch: bool = False,
    watch_min: float = 0.9,
    min_answer_s: float = 0.0,
    labels: dict | None = None,
    height: int | None = None,
    log_key: str = "",
    on_confirm=None,
    args: tuple = (),
):
    """Mount the frame picker; return the confirm payload of this run, else None.

    Parameters
    ----------
    video : path or list of path
        The stimulus video, or its encodings in order of preference (H.264 MP4, then
        WebM/VP9 for browsers without H.264); the browser plays the first it can.
    fps : float
        Its frame rate (frames per second).
    n_frames : int
        Its number of frames; the picker offers frames ``0 .. n_frames-1``.
    trial : int
        Trial index, echoed back so a late answer cannot land on another trial.
    key : str
        Streamlit element key (one per trial keeps trials apart).
    start_frame : int
        Frame shown first (e.g. where the participant was before a reload).
    watched : float
        Share of the animation already watched (restored after a reload).
    watched_ranges : list of [float, float]
        The video frames already watched, ``[[from, to], ...]`` (restored after a
        reload or a return; united with what this page plays).
    require_watch : bool
        Confirm stays off until ``watch_min`` of the animation was played.
    min_answer_s : float
        Confirm stays off this many seconds after the player appears.
    labels : dict, optional
        Overrides of :data:`DEFAULT_LABELS`.
    log_key : str
        Names this participant's player for this trial in the browser tab: log entries a
        reload interrupts are kept under it and sent by the next player with the same
        key. Empty: nothing is kept.
    on_confirm : callable, optional
        Called with ``args`` when the participant confirms, before the script run that
        follows (read the answer with :func:`confirmed`): a callback can store the
        answer so that this very run shows the next step.

    Returns
    -------
    dict or None
        ``{"trial", "frame", "events", "watched"}`` on confirm (when no ``on_confirm``
        handles it), ``{"trial", "log"}``
        for a batch of the interaction log, ``{"trial", "error"}`` if the video cannot
        be played, None otherwise.
    """
    picker, _ = _components()
    videos = [video] if isinstance(video, (str, Path)) else list(video)
    sources = [
        {
            "src": media_url(v, where=f"video.{key}.{i}"),
            "type": _MIME.get(Path(v).suffix.lower(), ""),
        }
        for i, v in enumerate(videos)
    ]
    data = {
        "sources": sources,
        "fps": float(fps),
        "n_frames": int(n_frames),
        "trial": int(trial),
        "start_frame": int(start_frame),
        "watched": float(watched),
        "require_watch": bool(require_watch),
        "watched_ranges": [[float(a), float(b)] for a, b in watched_ranges],
        "watch_min": float(watch_min),
        "min_answer_s": float(min_answer_s),
        "labels": {**DEFAULT_LABELS, **(labels or {})},
        "log_key": str(log_key),
    }
    result = picker(
        key=key,
        data=[data],
        on_confirm_change=_bound(on_confirm, args),
        on_error_change=_noop,
        on_log_change=_noop,
        height=height or "content",
    )
    if result.get("confirm") and on_confirm is None:
        return dict(result["confirm"])
    if result.get("log"):
        return {
            "trial": (result["log"] or {}).get("trial"),
            "log": (result["log"] or {}).get("events") or [],
        }
    if result.get("error"):
        return {
            "trial": (result["error"] or {}).get("trial"),
            "error": (result["error"] or {}).get("message", ""),
        }
    return None


def view_chooser(
    images: list[str | Path],
    *,
    trial: int,
    key: str,
    captions: list[str] | None = None,
    min_answer_s: float = 0.0,
    labels: dict | None = None,
    on_choice=None,
    args: tuple = (),
    tab_key: str = "",
    on_skip=None,
):
    """Mount the view chooser; return ``{"trial", "position", "client"}`` when one is
    chosen (without ``on_choice``), ``{"trial", "failed": [positions]}`` in the run
    after pictures failed to load (retried; the buttons stay off; ``[]`` once they all
    loaded again), else None.

    Parameters
    ----------
    images : list of path
        The candidate pictures in screen order, left to right. Only the pictures go to
        the browser: the caller maps the chosen position back to what it showed there.
    trial : int
        Trial index, echoed back.
    key : str
        Streamlit element key.
    captions : list of str, optional
        What participants see under each image (default "View A", "View B", ...).
    min_answer_s : float
        The Choose buttons stay off this long after every picture has loaded.
    on_choice : callable, optional
        Called with ``args`` when a picture is chosen, before the script run that
        follows (read the answer with :func:`chosen`); the function then returns None.
    tab_key : str
        Names this participant's trial in the browser tab (its active time is kept
        across reloads under it).
    on_skip : callable, optional
        Called with ``args`` when, after a picture failed to load, the participant
        presses "I can't see the pictures" (read it with :func:`skipped`).
    """
    _, chooser = _components()
    captions = captions or [f"View {chr(65 + i)}" for i in range(len(images))]
    data = {
        "trial": int(trial),
        "labels": {**DEFAULT_LABELS, **(labels or {})},
        "min_answer_s": float(min_answer_s),
        "tab_key": str(tab_key),
        "views": [
            {"src": media_url(p, where=f"view.{key}.{i}"), "label": captions[i]}
            for i, p in enumerate(images)
        ],
    }
    result = chooser(
        key=key,
        data=[data],
        on_choice_change=_bound(on_choice, args),
        on_failed_change=_noop,
        on_skip_change=_bound(on_skip, args),
    )
    if result.get("failed") is not None:
        got = result["failed"] or {}
        return {
            "trial": got.get("trial"),
            "failed": list(got.get("positions") or []),
            "tab": got.get("tab"),
        }
    return dict(result["choice"]) if result.get("choice") and on_choice is None else None


@cache
def _copy_component():
    import streamlit as st

    return st.components.v2.component(
        COPY_LINK,
        js=(HERE / "copy_link.js").read_text(encoding="utf-8"),
        css=(HERE / "picker.css").read_text(encoding="utf-8"),
    )


def copy_button(text: str, *, key: str, labels: dict | None = None) -> None:
    """A button that copies ``text`` to the clipboard (and then says so)."""
    labels = {
        "copy": "Copy the link",
        "copied": "Copied",
        "copy_failed": "Could not copy: please select the link and copy it",
        **(labels or {}),
    }
    _copy_component()(key=key, data=[{"text": str(text), "labels": labels}])


def _bound(callback, args: tuple):
    """A components-v2 callback (they take no arguments) calling ``callback(*args)``."""
    return _noop if callback is None else partial(callback, *args)


def _trigger(key: str, event: str) -> dict | None:
    """The value a component's ``event`` trigger carries in this run (in its callback)."""
    import streamlit as st

    value = st.session_state.get(key)
    got = value.get(event) if isinstance(value, dict) else None
    return dict(got) if isinstance(got, dict) else None


def confirmed(key: str) -> dict | None:
    """In an ``on_confirm`` callback: the frame picker's confirm payload
    (``{"trial", "frame", "events", "watched"}``), or None."""
    return _trigger(key, "confirm")


def chosen(key: str) -> dict | None:
    """In an ``on_choice`` callback: the view chooser's ``{"trial", "position"}``, or None."""
    return _trigger(key, "choice")


def skipped(key: str) -> dict | None:
    """In an ``on_skip`` callback: the view chooser's ``{"trial", "client"}``, or None."""
    return _trigger(key, "skip")


def _noop():
    """Trigger callbacks must exist for the trigger to be reported; the page reads the result."""
