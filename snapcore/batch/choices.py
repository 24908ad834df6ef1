"""Thumbnail choices: the source frame an animator chose as a scene's thumbnail.

They live in ``OUT/thumb-choices.csv`` (a ``path,frame`` header, then one line per
scene; an empty frame clears a choice, back to the chosen pose), written by the gallery
server (``snapshot gallery OUT``) or saved from the page opened from disk. A run reads
them, renders each chosen frame as its scene's thumbnail and records the choice in the
index (``thumb_choice``), so that a choice outlives the file, ``--force``, a re-run and
another ``--pose-method``: it is a frame of the clip, not a rank among poses that a new
method would pick differently. The file is rewritten whole, never appended to, so the
last save holds every choice.
"""

from __future__ import annotations

import csv
import io
import threading
from collections.abc import Iterable, Mapping
from pathlib import Path

from snapcore.batch.discover import BatchError
from snapcore.batch.index import atomic_write

__all__ = ["CHOICES_NAME", "read_choices", "write_choices", "update_choices", "choices_for"]

#: ``OUT/thumb-choices.csv``.
CHOICES_NAME = "thumb-choices.csv"
_HEADER = ["path", "frame"]
#: The server's threads update the file one at a time (read, change, write).
_LOCK = threading.Lock()


def read_choices(out, rows: Iterable[Mapping] = ()) -> dict[str, int | None]:
    """The entries of ``OUT/thumb-choices.csv``: scene key → source frame, or None for
    a cleared choice (no file: none).

    Parameters
    ----------
    out : path-like
    rows : iterable of dict
        The index rows: an older file of ``path,pose`` lines (a rank among the top
        poses) is read through their ``top_frames``, so its choices are not lost.

    Raises
    ------
    BatchError
        A line that is not ``path,frame`` with a frame of 0 or more (file and line named),
        or an old rank no row can turn into a frame.
    """
    path = Path(out) / CHOICES_NAME
    if not path.is_file():
        return {}
    top = {r["path"]: r.get("top_frames") or [] for r in rows}
    choices: dict[str, int | None] = {}
    ranks = False
    with open(path, encoding="utf-8", newline="") as fh:
        for n, cells in enumerate(csv.reader(fh), start=1):
            if not cells:
                continue
            if n == 1 and cells in (_HEADER, ["path", "pose"]):
                ranks = cells[1] == "pose"
                continue
            try:
                key, text = cells
                value = int(text) if text.strip() else None
                if value is not None and value < (1 if ranks else 0):
                    raise ValueError
            except ValueError:
                raise BatchError(
                    f"{path}:{n}: expected 'path,frame' with a source frame of 0 or more "
                    f"(or nothing, to clear), got {','.join(cells)!r}"
                ) from None
            if ranks and value is not None:
                if value > len(top.get(key, [])):
                    raise BatchError(
                        f"{path}:{n}: pose #{value} of {key} (an older file of ranks) is "
                        "not in the index: choose its frame again in the gallery (move "
                        "this file away to run without it)"
                    )
                value = top[key][value - 1]
            choices[key] = value
    return choices


def write_choices(out, choices: Mapping[str, int | None]) -> Path:
    """Write every choice (cleared ones as an empty frame) to ``OUT/thumb-choices.csv``,
    sorted by key, atomically; return its path."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(_HEADER)
    for key in sorted(choices):
        v = choices[key]
        w.writerow([key, "" if v is None else int(v)])
    path = Path(out) / CHOICES_NAME
    atomic_write(path, buf.getvalue())
    return path


def update_choices(out, changes: Mapping[str, int | None]) -> dict[str, int | None]:
    """Merge ``changes`` into the file (the other choices stay) and return them all."""
    with _LOCK:
        merged = {**read_choices(out), **changes}
        write_choices(out, merged)
        return merged


def choices_for(out, rows: Iterable[Mapping]) -> dict[str, int]:
    """The choice in force for each scene: the index's ``thumb_choice``, overridden by
    the file's entries (a cleared entry removes it).

    ``rows`` is the previous index, read even when ``--force`` redoes every scene."""
    rows = list(rows)
    merged: dict[str, int | None] = {
        r["path"]: r["thumb_choice"] for r in rows if r.get("thumb_choice") is not None
    }
    merged.update(read_choices(out, rows))
    return {k: v for k, v in merged.items() if v is not None}
