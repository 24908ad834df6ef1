"""Annotated key moments: reading them, and measuring pose selectors against them.

An annotation file lists scenes (one or more BVH files) with the source-frame
intervals where the clip's action is (``../shared/keymoments``). Two formats, the same
content:

- TSV with a header row and the columns ``scene``, ``files`` (comma-separated paths
  relative to the data folder), ``fps`` (empty: trust the header), ``intervals``
  (``a-b;c-d``, 0-based source frames, inclusive) and ``what`` (free text); ``fps``
  and ``what`` may be left out;
- JSON following ``data_schema/keymoments.schema.json``:
  ``{"scenes": [{"scene", "files": [...], "fps", "intervals": [[a, b], ...], "what"}]}``.

A wrong file, an unknown column, a malformed or reversed interval (``a > b``), or an
interval outside the clip raises :class:`KeymomentsError`, whose message names the
file, the line (TSV) or entry (JSON) and the field.

Evaluation (:func:`evaluate_picks`) follows the README of the annotations: a pick *hits*
when it lies inside an interval widened by :data:`HIT_WIDEN_S` on each side; top-1 and
top-3 hit rates, the distance (s) from the top pick to the nearest interval, and the
chance rate (the fraction of the clip's frames inside the widened intervals).
"""

from __future__ import annotations

import csv
import json
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import NoReturn

import numpy as np

from snapcore.errors import SchemaError, SnapshotError
from snapcore.motion.load import load_scene
from snapcore.schema import validate
from snapcore.select.pose_methods import select_pose

__all__ = [
    "HIT_WIDEN_S",
    "KEYMOMENTS_FORMAT",
    "KeymomentsError",
    "KeyMoments",
    "read_keymoments",
    "keymoments_to_json",
    "check_against_scene",
    "hits",
    "distance_to_intervals",
    "chance_rate",
    "evaluate_picks",
    "summarise",
]

#: Seconds an interval is widened on each side when deciding a hit.
HIT_WIDEN_S = 0.1
#: ``format`` of the JSON results document.
KEYMOMENTS_FORMAT = "action-snapshot/keymoments-evaluation@1"
_COLUMNS = ("scene", "files", "fps", "intervals", "what")
_REQUIRED = ("scene", "files", "intervals")
_INTERVAL = re.compile(r"^\s*(\d+)\s*-\s*(\d+)\s*$")


class KeymomentsError(SnapshotError, ValueError):
    """A bad annotation file: the message is ``<file>:<line>: <field>: <what>``."""


@dataclass
class KeyMoments:
    """The annotated key moments of one scene.

    Attributes
    ----------
    scene : str
    files : list of str
        Paths relative to the data folder (one scene, several characters).
    fps : float or None
        Frame-rate override (None: the files' header).
    intervals : list of tuple of int
        ``(a, b)`` source frames, 0-based, inclusive.
    what : str
    where : str
        ``<file>:<line>`` of the entry (for messages).
    """

    scene: str
    files: list[str]
    fps: float | None
    intervals: list[tuple[int, int]]
    what: str = ""
    where: str = ""
    line: int = 0
    source: str = field(default="", repr=False)


def _fail(path, line, fld, msg) -> NoReturn:
    raise KeymomentsError(f"{path}:{line}: {fld}: {msg}")


def _parse_intervals(text: str, path, line) -> list[tuple[int, int]]:
    out = []
    parts = [p for p in str(text).split(";") if p.strip()]
    if not parts:
        _fail(path, line, "intervals", "no interval (expected a-b;c-d)")
    for part in parts:
        m = _INTERVAL.match(part)
        if not m:
            _fail(
                path,
                line,
                "intervals",
                f"{part.strip()!r} is not an interval a-b of non-negative frame numbers",
            )
        a, b = int(m.group(1)), int(m.group(2))
        if a > b:
            _fail(path, line, "intervals", f"{a}-{b}: start after end (a > b)")
        out.append((a, b))
    return out


def _parse_fps(text, path, line) -> float | None:
    if text is None or str(text).strip() == "":
        return None
    try:
        v = float(text)
    except ValueError:
        _fail(path, line, "fps", f"{text!r} is not a number")
    if not (np.isfinite(v) and v > 0):
        _fail(path, line, "fps", f"{text!r} must be a positive number")
    return v


def read_keymoments(path) -> list[KeyMoments]:
    """Read an annotation file (TSV or JSON, by suffix).

    Raises
    ------
    KeymomentsError
        Unreadable file, missing or unknown column, empty or duplicated scene name, no
        files, a malformed interval, ``a > b``, a bad fps.
    """
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as err:
        raise KeymomentsError(
            f"{p}:0: file: cannot read it ({err.__class__.__name__}: "
            f"{getattr(err, 'strerror', None) or err})"
        ) from None
    if p.suffix.lower() == ".json":
        out = _read_json(p, text)
    else:
        out = _read_tsv(p, text)
    seen: dict[str, str] = {}
    for km in out:
        if km.scene in seen:
            _fail(p, km.line, "scene", f"{km.scene!r} is listed twice (first at {seen[km.scene]})")
        seen[km.scene] = km.where
    if not out:
        _fail(p, 1, "scenes", "no scene annotated")
    return out


def _read_tsv(p: Path, text: str) -> list[KeyMoments]:
    lines = text.splitlines()
    if not lines or not lines[0].strip():
        _fail(p, 1, "header", f"expected a header row with columns {', '.join(_COLUMNS)}")
    header = [h.strip() for h in lines[0].split("\t")]
    for h in header:
        if h not in _COLUMNS:
            _fail(p, 1, h or "(empty)", f"unknown column (expected {', '.join(_COLUMNS)})")
    for h in _REQUIRED:
        if h not in header:
            _fail(p, 1, h, "missing column")
    out = []
    reader = csv.reader(lines[1:], delimiter="\t", quoting=csv.QUOTE_NONE)
    for n, row in enumerate(reader, start=2):
        if not any(c.strip() for c in row):
            continue
        if len(row) > len(header):
            _fail(p, n, "row", f"{len(row)} fields for {len(header)} columns")
        rec = dict(zip(header, row + [""] * (len(header) - len(row))))
        out.append(
            _entry(
                p,
                n,
                rec.get("scene", ""),
                rec.get("files", ""),
                rec.get("fps"),
                rec.get("intervals", ""),
                rec.get("what", ""),
            )
        )
    return out


def _read_json(p: Path, text: str) -> list[KeyMoments]:
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as err:
        raise KeymomentsError(f"{p}:{err.lineno}: json: {err.msg}") from None

    try:
        validate(doc, "keymoments", source=str(p))
    except SchemaError as err:
        raise KeymomentsError(f"{p}:0: {err}") from None
    out = []
    for n, e in enumerate(doc["scenes"], start=1):
        iv = ";".join(f"{a}-{b}" for a, b in e["intervals"])
        out.append(
            _entry(
                p,
                n,
                e["scene"],
                ",".join(e["files"]),
                e.get("fps"),
                iv,
                e.get("what", ""),
                kind="entry",
            )
        )
    return out


def _entry(p, n, scene, files, fps, intervals, what, kind="line") -> KeyMoments:
    scene = str(scene).strip()
    if not scene:
        _fail(p, n, "scene", "empty scene name")
    names = [f.strip() for f in str(files).split(",") if f.strip()]
    if not names:
        _fail(p, n, "files", "no file")
    km = KeyMoments(
        scene=scene,
        files=names,
        fps=_parse_fps(fps, p, n),
        intervals=_parse_intervals(intervals, p, n),
        what=str(what or "").strip(),
        where=f"{p}:{n}" if kind == "line" else f"{p}: entry {n}",
        line=n,
        source=str(p),
    )
    return km


def keymoments_to_json(entries: list[KeyMoments]) -> dict:
    """The JSON form of annotations (``data_schema/keymoments.schema.json``)."""
    return {
        "scenes": [
            {
                "scene": k.scene,
                "files": list(k.files),
                **({"fps": k.fps} if k.fps is not None else {}),
                "intervals": [[a, b] for a, b in k.intervals],
                **({"what": k.what} if k.what else {}),
            }
            for k in entries
        ]
    }


def check_against_scene(km: KeyMoments, scene) -> None:
    """Raise :class:`KeymomentsError` when an interval lies outside the clip.

    The clip's source frames are ``0 .. frame_offset + n_frames - 1``.
    """
    last = int(scene.frame_offset + scene.n_frames - 1)
    for a, b in km.intervals:
        if b > last:
            _fail(
                km.source,
                km.line,
                "intervals",
                f"{a}-{b} is outside the clip of {km.scene} (source frames 0..{last})",
            )


# ----------------------------------------------------------------------- measures


def _widened(intervals, fps: float, widen_s: float) -> np.ndarray:
    iv = np.asarray(intervals, dtype=float).reshape(-1, 2)
    w = widen_s * fps
    return np.stack([iv[:, 0] - w, iv[:, 1] + w], axis=1)


def hits(frames, intervals, *, fps: float, widen_s: float = HIT_WIDEN_S) -> np.ndarray:
    """Whether each source frame lies in an interval widened by ``widen_s`` s, (n,) bool."""
    f = np.asarray(frames, dtype=float).reshape(-1, 1)
    w = _widened(intervals, fps, widen_s)
    return np.any((f >= w[:, 0]) & (f <= w[:, 1]), axis=1)


def distance_to_intervals(frames, intervals, *, fps: float) -> np.ndarray:
    """Seconds from each source frame to the nearest (unwidened) interval; 0 inside."""
    f = np.asarray(frames, dtype=float).reshape(-1, 1)
    iv = np.asarray(intervals, dtype=float).reshape(-1, 2)
    d = np.maximum(np.maximum(iv[:, 0] - f, f - iv[:, 1]), 0.0)
    return d.min(axis=1) / fps


def chance_rate(
    intervals, *, first: int, last: int, fps: float, widen_s: float = HIT_WIDEN_S
) -> float:
    """Fraction of the clip's source frames ``first..last`` inside the widened intervals:
    the top-1 hit rate of a uniformly random pick."""
    frames = np.arange(first, last + 1)
    return float(hits(frames, intervals, fps=fps, widen_s=widen_s).mean())


def evaluate_picks(
    picks: dict, km: KeyMoments, *, fps: float, first: int, last: int, widen_s: float = HIT_WIDEN_S
) -> list[dict]:
    """One row per method for one scene.

    Parameters
    ----------
    picks : dict of str to list of int
        Each method's top-k source frames, best first.
    km : KeyMoments
    fps : float
    first, last : int
        The clip's analysed source frames.

    Returns
    -------
    list of dict
        ``scene``, ``method``, ``frames``, ``top1_hit``, ``top3_hit`` (bool),
        ``distance_s`` (top pick to the nearest interval), ``chance`` (float).
    """
    chance = chance_rate(km.intervals, first=first, last=last, fps=fps, widen_s=widen_s)
    rows = []
    for method, frames in picks.items():
        frames = [int(f) for f in frames]
        h = hits(frames, km.intervals, fps=fps, widen_s=widen_s)
        rows.append(
            {
                "scene": km.scene,
                "method": method,
                "frames": frames,
                "top1_hit": bool(h[0]) if h.size else False,
                "top3_hit": bool(h[:3].any()) if h.size else False,
                "distance_s": float(distance_to_intervals(frames[:1], km.intervals, fps=fps)[0]),
                "chance": chance,
            }
        )
    return rows


def summarise(rows: list[dict]) -> list[dict]:
    """Per method over scenes: ``top1_hits``, ``top3_hits``, ``n_scenes``,
    ``median_distance_s``, ``chance_hits`` (expected top-1 hits of a random pick)."""
    out = []
    methods = list(dict.fromkeys(r["method"] for r in rows))
    for m in methods:
        rs = [r for r in rows if r["method"] == m]
        out.append(
            {
                "method": m,
                "n_scenes": len(rs),
                "top1_hits": int(sum(r["top1_hit"] for r in rs)),
                "top3_hits": int(sum(r["top3_hit"] for r in rs)),
                "median_distance_s": float(np.median([r["distance_s"] for r in rs])),
                "chance_hits": float(sum(r["chance"] for r in rs)),
            }
        )
    return out


# ----------------------------------------------------------------------- running


def run_keymoments(
    entries: list[KeyMoments],
    *,
    data,
    methods,
    k: int = 3,
    widen_s: float = HIT_WIDEN_S,
    source: str = "",
    progress=None,
) -> dict:
    """Run every selector on every annotated scene and score the picks.

    Parameters
    ----------
    entries : list of KeyMoments
    data : path
        Folder the ``files`` are relative to.
    methods : sequence of str
        Pose methods (:data:`snapcore.select.pose_methods.POSE_METHODS`).
    k : int
        Picks per method (top-k).
    widen_s : float
    source : str
        The annotation file's name, for the document.
    progress : callable, optional
        Called with each scene name before it runs.

    Returns
    -------
    dict
        The evaluation document (``data_schema/keymoments_evaluation.schema.json``).

    Raises
    ------
    KeymomentsError
        A file that cannot be loaded, or an interval outside its clip.
    """
    import warnings

    base = Path(data)
    scenes, rows = [], []
    for km in entries:
        if progress:
            progress(km.scene)
        paths = [base / f for f in km.files]
        for f, pth in zip(km.files, paths):
            if not pth.is_file():
                _fail(km.source, km.line, "files", f"{f}: no such file in {base}")
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # unit fits etc.: not this table's business
                scene = load_scene([str(p) for p in paths], fps=km.fps)
        except SnapshotError as err:
            _fail(km.source, km.line, "files", str(err))
        check_against_scene(km, scene)
        picks = {}
        for m in methods:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                sel = select_pose(scene, method=m, k=k)
            picks[m] = [int(scene.source_frame(i)) for i in sel.indices]
        first = int(scene.frame_offset)
        last = int(scene.frame_offset + scene.n_frames - 1)
        fps = float(scene.fps)
        rs = evaluate_picks(picks, km, fps=fps, first=first, last=last, widen_s=widen_s)
        rows += rs
        scenes.append(
            {
                "scene": km.scene,
                "files": list(km.files),
                "fps": fps,
                "first_frame": first,
                "last_frame": last,
                "intervals": [[a, b] for a, b in km.intervals],
                "chance": rs[0]["chance"] if rs else 0.0,
            }
        )
    return {
        "format": KEYMOMENTS_FORMAT,
        "annotations": str(source),
        "widen_s": float(widen_s),
        "k": int(k),
        "methods": list(methods),
        "scenes": scenes,
        "rows": rows,
        "overall": summarise(rows),
    }


def table_rows(doc: dict) -> list[dict]:
    """Flat table: one row per scene and method, then ``ALL`` rows per method."""
    out = []
    for r in doc["rows"]:
        out.append(
            {
                "scene": r["scene"],
                "method": r["method"],
                "top1": int(r["top1_hit"]),
                "top3": int(r["top3_hit"]),
                "distance_s": round(r["distance_s"], 3),
                "chance": round(r["chance"], 3),
                "frames": " ".join(str(f) for f in r["frames"]),
            }
        )
    for o in doc["overall"]:
        out.append(
            {
                "scene": "ALL",
                "method": o["method"],
                "top1": f"{o['top1_hits']}/{o['n_scenes']}",
                "top3": f"{o['top3_hits']}/{o['n_scenes']}",
                "distance_s": round(o["median_distance_s"], 3),
                "chance": round(o["chance_hits"], 2),
                "frames": "",
            }
        )
    return out


def overall_markdown(doc: dict) -> str:
    """The overall table as Markdown (methods as rows)."""
    lines = ["| method | top-1 hits | top-3 hits | median distance (s) |", "|---|---|---|---|"]
    for o in doc["overall"]:
        lines.append(
            f"| {o['method']} | {o['top1_hits']}/{o['n_scenes']} | "
            f"{o['top3_hits']}/{o['n_scenes']} | {o['median_distance_s']:.2f} |"
        )
    chance = doc["overall"][0]["chance_hits"] if doc["overall"] else 0.0
    lines.append(f"| chance (random frame) | {chance:.1f} expected | | |")
    return "\n".join(lines)
