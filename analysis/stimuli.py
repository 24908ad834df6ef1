"""Reading the stimuli manifest (``data_schema/stimuli.schema.json``) for the analysis.

The app's stimuli builder writes ``manifest.json``: per scene the motion's fps, length,
frame offset, the algorithm's picks (``picks.frame``, top-k ``picks.frames``), timings,
and ``source`` — what was loaded (a demo scene name, BVH files or a scene manifest,
fps/scale overrides, a frame window). The analysis uses it for what response rows do
not carry: the top-k picks to mark, the scene titles, and every selector's picks
(``picks.by_method``: the fastest and stretch baselines).
"""

from __future__ import annotations

import warnings
from pathlib import Path

import pandas as pd

from .load import LoadError

__all__ = [
    "read_stimuli",
    "stimuli_scenes",
    "load_scene_for_entry",
    "near_duplicate_scenes",
    "replaced_views",
    "DEFAULT_NEAR_DUPLICATE_DEG",
]

#: Threshold (degrees) for manifests that do not name one (the study config's default).
DEFAULT_NEAR_DUPLICATE_DEG = 15.0


def read_stimuli(manifest) -> tuple[dict, Path | None]:
    """The manifest as a dict and the folder its relative paths start from.

    Parameters
    ----------
    manifest : str, Path or dict
        ``manifest.json``, the stimuli folder holding it, or the parsed document.
    """
    if isinstance(manifest, dict):
        return manifest, None
    p = Path(manifest)
    if p.is_dir():
        p = p / "manifest.json"
    from snapcore.schema import read_document

    return read_document(p, "stimuli"), p.parent


def stimuli_scenes(manifest) -> pd.DataFrame:
    """One row per scene of a stimuli manifest.

    Returns
    -------
    DataFrame
        ``scene``, ``title``, ``fps``, ``n_frames``, ``frame_offset``,
        ``algorithm_frame``, ``algorithm_frames`` (tuple, top-k), ``pose_s`` and
        ``view_s`` (selection timings when the manifest has them, else NaN).
    """
    doc, _ = read_stimuli(manifest)
    rows = []
    for e in doc.get("scenes", []):
        picks = e.get("picks") or {}
        t = e.get("timings_s") or {}
        rows.append(
            {
                "scene": e["id"],
                "title": e.get("title", e["id"]),
                "fps": float(e["fps"]),
                "n_frames": int(e["n_frames"]),
                "frame_offset": int(e["frame_offset"]),
                "algorithm_frame": int(picks["frame"]),
                "algorithm_frames": tuple(int(f) for f in picks.get("frames", ()) or ()),
                "pose_s": _first(t, "select_pose", "pose"),
                "view_s": _first(t, "select_view", "view"),
            }
        )
    return pd.DataFrame(rows)


def near_duplicate_scenes(manifest) -> pd.DataFrame:
    """Scenes whose candidate views, as shown, are nearly the same picture.

    A scene whose alike pictures were merged (the manifest's ``shown``: each shown
    once, standing for its methods) has none: no vote was split between alike pictures.
    The pairs are the builder's ``near_duplicates`` when the manifest records them
    (judged on the views shown, after any replacement: by angle or by silhouette IoU,
    mirror images included; empty when every alike view was replaced). Older manifests
    without them are judged by angle: ``view_angles`` when recorded, else the picks'
    view directions, against the study's ``near_duplicate_deg`` (a pair under it, or
    over 180 minus it — a mirror image — is a near-duplicate).

    Returns
    -------
    DataFrame
        One row per near-duplicate pair: ``scene``, ``method_a``, ``method_b``,
        ``angle_deg``, ``iou`` (silhouette IoU, NaN when not recorded); empty (with
        those columns) when there is none.
    """
    from snapcore.select.view import near_duplicate_views, view_angles_deg

    doc, _ = read_stimuli(manifest)
    thr = float(
        (doc.get("study") or {})
        .get("study", {})
        .get("near_duplicate_deg", DEFAULT_NEAR_DUPLICATE_DEG)
    )
    rows = []
    for e in doc.get("scenes", []):
        if "shown" in e:  # merged (issue 36): alike pictures were shown once, no split votes
            continue
        ious = e.get("view_iou") or {}
        if "near_duplicates" in e and ious:  # judged by the builder on the pictures shown
            angles = e.get("view_angles") or {}
            for a, b in e["near_duplicates"]:
                key = f"{a}|{b}"
                rows.append(
                    {
                        "scene": e["id"],
                        "method_a": a,
                        "method_b": b,
                        "angle_deg": float(angles.get(key, float("nan"))),
                        "iou": float(ious.get(key, float("nan"))),
                    }
                )
            continue
        angles = e.get("view_angles")
        if not angles:
            picks = e.get("picks") or {}
            dirs = {
                "ours": picks.get("view"),
                "viewpoint_entropy": picks.get("viewpoint_entropy"),
                "motion_area": picks.get("motion_area"),
            }
            if any(v is None for v in dirs.values()):
                continue
            angles = view_angles_deg(dirs)
        for a, b in near_duplicate_views(angles, thr):
            rows.append(
                {
                    "scene": e["id"],
                    "method_a": a,
                    "method_b": b,
                    "angle_deg": float(angles[f"{a}|{b}"]),
                    "iou": float(ious.get(f"{a}|{b}", float("nan"))),
                }
            )
    return pd.DataFrame(rows, columns=["scene", "method_a", "method_b", "angle_deg", "iou"])


def replaced_views(manifest) -> pd.DataFrame:
    """Baseline views the builder replaced because their picture was nearly another
    candidate's (``replacements`` of the manifest, ``study.near_duplicate = "replace"``).

    Votes for such a baseline in that scene are votes for its best view *unlike the
    other candidates*, not for its own pick: the report lists them.

    Returns
    -------
    DataFrame
        One row per replaced view: ``scene``, ``method``, ``alike`` (the candidates it
        was too alike to, comma-separated), ``iou_before`` and ``iou_after`` (the
        largest silhouette IoU with a kept candidate), ``rank`` (of the replacement
        among the method's views, 1 = its own pick), ``score_ratio`` (replacement's
        score / the pick's), ``reason``; empty (with those columns) when none.
    """
    doc, _ = read_stimuli(manifest)
    cols = [
        "scene",
        "method",
        "alike",
        "iou_before",
        "iou_after",
        "rank",
        "score_ratio",
        "reason",
    ]
    rows = []
    for e in doc.get("scenes", []):
        for r in e.get("replacements") or []:
            s0, s1 = r.get("score_original"), r.get("score_replacement")
            rows.append(
                {
                    "scene": e["id"],
                    "method": r["method"],
                    "alike": ", ".join(r["alike"]),
                    "iou_before": max(r["iou_before"].values()),
                    "iou_after": max(r["iou_after"].values()),
                    "rank": int(r.get("rank", 0)) or None,
                    "score_ratio": float(s1) / float(s0) if s0 else float("nan"),
                    "reason": r["reason"],
                }
            )
    return pd.DataFrame(rows, columns=cols)


def _first(d: dict, *keys) -> float:
    for k in keys:
        if k in d:
            return float(d[k])
    return float("nan")


def _resolve(name: str, bases) -> Path:
    from snapcore.motion.load import resolve_data_path

    p = Path(name).expanduser()
    if p.is_absolute():
        return p
    for b in bases:
        if b is not None and (Path(b) / p).exists():
            return Path(b) / p
    return resolve_data_path(name, None)


def load_scene_for_entry(entry: dict, base: Path | None = None):
    """Load the motion a manifest scene was built from.

    In order: ``source.scene_file`` (the scene manifest the stimuli builder wrote beside
    the stimuli, window included), a ``demo`` name (rebuilt with
    :func:`snapcore.motion.synth.synth_scene` when the scene file cannot be read), ``files``
    (BVH paths) or ``manifest`` (a scene manifest), with the entry's ``fps``/``scale``
    overrides. Relative paths are tried against the stimuli folder, its parent and the
    motion data folder (``SNAPSHOT_DATA``). The frame window is applied by the caller
    (the entry's ``frame_offset`` and ``n_frames``).
    """
    from snapcore import load_scene

    src = entry.get("source") or {}
    fps, scale = src.get("fps"), src.get("scale")
    bases = [base, base.parent if base is not None else None]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # unit fitting etc. was reported when stimuli were built
        if src.get("scene_file"):
            path = _resolve(src["scene_file"], bases)
            if path.exists():
                try:
                    return load_scene(path)
                except (ValueError, OSError):
                    if not src.get("demo"):  # older builds deleted the demo BVHs it names
                        raise
        if src.get("demo"):
            from snapcore.motion import synth

            return synth.synth_scene(src["demo"], **({"fps": fps} if fps else {}))
        if src.get("files"):
            return load_scene([_resolve(f, bases) for f in src["files"]], fps=fps, scale=scale)
        if src.get("manifest"):
            return load_scene(_resolve(src["manifest"], bases), fps=fps, scale=scale)
    raise LoadError(
        f"stimuli scene '{entry.get('id')}': source names no motion "
        "(expected scene_file, demo, files or manifest)"
    )
