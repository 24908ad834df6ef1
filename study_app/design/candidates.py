"""Choosing each scene's candidate views: the pose and the three methods' view directions
(:func:`select_scene`), how far apart they are (:func:`check_near_duplicates`), whether
their pictures are nearly the same (:func:`check_alike_pictures`), and a baseline's view
merged when their pictures are alike: shown once, standing for each method that proposed
it (:func:`merge_alike_views`, ``study.near_duplicate = "merge"``, the default), or a
baseline's view replaced when its picture nearly repeats an earlier candidate's
(:func:`replace_alike_views`, ``study.near_duplicate = "replace"``).

What the study config asks when candidates are near-duplicates (``merge``, ``warn``,
``error`` or ``replace``) is acted on here; the builder (:mod:`study_app.design.build`) records the
outcome in the manifest.
"""

from __future__ import annotations

import warnings

import numpy as np

from snapcore.select.view_methods import VIEW_METHODS, ViewMethod

from .media import render_view, view_renderer
from .protocol import Study
from .similarity import (
    ALIKE_ANGLE_DEG,
    NEAR_DUPLICATE_IOU,
    POSE_ALIKE_DISTANCE,
    candidate_ious,
    candidate_pose_distances,
    pose_points,
)
from .stimuli import PICK_KEYS, StimuliError

__all__ = [
    "select_scene",
    "select_scene_snapshot",
    "candidate_angles",
    "check_near_duplicates",
    "check_alike_pictures",
    "replace_alike_views",
    "alike_groups",
    "merge_alike_views",
]


def select_scene(scene, options: dict | None = None) -> tuple[dict, dict]:
    """Stage 2: the pose and the three view directions.

    Returns
    -------
    (picks, timings) : tuple of dict
        ``picks``: ``frame`` and ``frames`` (source numbering) of the config's pose
        method (``selection.pose_method``, named in ``pose_method``), every selector's
        top-3 in ``by_method``, ``view`` (ours),
        ``viewpoint_entropy`` and ``motion_area`` (unit vectors, world frame).
        ``timings``: seconds per stage of the selection.
    """
    picks, timings, _ = select_scene_snapshot(scene, options)
    return picks, timings


def select_scene_snapshot(scene, options: dict | None = None):
    """:func:`select_scene`, and the snapshot it came from (the baselines' scored views,
    for replacing a view whose picture is nearly another's).

    Returns
    -------
    (picks, timings, snap) : (dict, dict, snapcore.pipeline.Snapshot)
    """
    from snapcore.pipeline import snapshot_params, take_snapshot

    try:
        pose, view = snapshot_params(options or {})
    except ValueError as err:
        raise StimuliError(f"study config [selection]: {err}") from None
    snap = take_snapshot(scene, pose=pose, view=view)
    views = snap.views
    missing = [m for m in VIEW_METHODS if m not in views]
    if missing:
        raise StimuliError(
            f"scene {scene.name}: the selection gave no {', '.join(missing)} "
            "view (a baseline was skipped: see the warning above)"
        )
    picks = {
        "frame": snap.source_frame,
        "frames": snap.source_frames,
        "pose_method": snap.pose.method,
        "by_method": _picks_by_method(scene),
    }
    picks.update({PICK_KEYS[m]: _unit(views[m]) for m in VIEW_METHODS})
    timings = {k: float(v) for k, v in snap.timings_s.items()}
    return picks, timings, snap


def _picks_by_method(scene, k: int = 3) -> dict:
    """Every pose selector's top-k frames (source numbering), for the analysis to
    compare with what people choose."""
    import warnings

    from snapcore import select_pose
    from snapcore.select.pose_methods import POSE_METHODS

    out = {}
    for m in POSE_METHODS:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            sel = select_pose(scene, method=m, k=k)
        out[m] = [int(scene.source_frame(i)) for i in sel.indices]
    return out


def candidate_angles(picks: dict, *, threshold_deg: float) -> tuple[dict, list]:
    """Angles between the three candidate views and the pairs that are near-duplicates.

    Returns
    -------
    (angles, pairs) : (dict of str to float, list of [str, str])
        ``{"ours|viewpoint_entropy": degrees, ...}`` and the pairs that are under
        ``threshold_deg`` apart or over ``180 - threshold_deg`` (mirror images).
    """
    from snapcore.select.view import near_duplicate_views, view_angles_deg

    angles = view_angles_deg({m.value: picks[PICK_KEYS[m]] for m in VIEW_METHODS})
    angles = {k: round(v, 2) for k, v in angles.items()}
    return angles, [list(p) for p in near_duplicate_views(angles, threshold_deg)]


def check_near_duplicates(
    study: Study, scene_id: str, picks: dict, *, action: str | None = None
) -> tuple[dict, list]:
    """The candidates' pairwise angles and near-duplicates, acted on as the study says.

    ``study.near_duplicate == "warn"`` warns (the build goes on; the manifest records the
    pairs and the analysis reports them); ``"error"`` raises
    :class:`~study_app.design.stimuli.StimuliError`; ``"replace"`` only reports them: the
    pictures decide (:func:`replace_alike_views`). ``action`` overrides the study's (the
    builder warns about pairs left after replacing).

    Returns
    -------
    (angles, pairs)
        As :func:`candidate_angles`.
    """
    action = action or study.near_duplicate
    angles, dupes = candidate_angles(picks, threshold_deg=study.near_duplicate_deg)
    if dupes and action not in ("replace", "merge"):
        report = ", ".join(f"{k.replace('|', '/')} {v:.1f}°" for k, v in angles.items())
        which = "; ".join(f"{a} and {b} ({angles[f'{a}|{b}']:.1f}° apart)" for a, b in dupes)
        text = (
            f"nearly the same picture from {which} "
            f"(threshold {study.near_duplicate_deg:g}°; all pairs: {report})"
        )
        if action == "error":
            raise StimuliError(
                f"scene {scene_id}: {text}; set study.near_duplicate = "
                '"replace" (the default) or "warn" to build anyway'
            )
        warnings.warn(
            text + ": votes may split between them (the analysis reports it)", stacklevel=3
        )
    return angles, dupes


def check_alike_pictures(study: Study, scene_id: str, views: dict) -> tuple[dict, list]:
    """The candidates' silhouette IoUs and the pairs at or above
    :data:`NEAR_DUPLICATE_IOU`, acted on as the study's ``near_duplicate`` says (as
    :func:`check_near_duplicates`, with the measure in the message)."""
    ious = candidate_ious(views)
    pairs = [k.split("|") for k, v in ious.items() if v >= NEAR_DUPLICATE_IOU]
    if pairs and study.near_duplicate != "merge":
        which = "; ".join(
            f"{a} and {b} (silhouette IoU {ious[f'{a}|{b}']:.2f}, mirror images included)"
            for a, b in pairs
        )
        text = (
            f"nearly the same picture from {which} (threshold IoU "
            f"{NEAR_DUPLICATE_IOU:g}; all pairs: "
            + ", ".join(f"{k.replace('|', '/')} {v:.2f}" for k, v in ious.items())
            + ")"
        )
        if study.near_duplicate == "error":
            raise StimuliError(
                f"scene {scene_id}: {text}; set study.near_duplicate = "
                '"replace" (the default) or "warn" to build anyway'
            )
        warnings.warn(
            text + ": votes may split between them (the analysis reports it)", stacklevel=3
        )
    return ious, pairs


def replace_alike_views(
    study: Study, scene_id: str, snap, picks: dict, views: dict, *, renderer=None
) -> tuple[dict, list]:
    """Replace each baseline view whose picture is nearly an earlier candidate's by that
    baseline's best-scoring view whose picture is not (:mod:`study_app.design.replacement`).

    Parameters
    ----------
    study : Study
        Its ``near_duplicate_deg`` is the angle around kept views skipped unrendered.
    scene_id : str
    snap : snapcore.pipeline.Snapshot
        The selection the picks came from (the baselines' scored views).
    picks : dict
        :func:`select_scene`'s picks (the frame).
    views : dict
        :func:`~study_app.design.media.write_views`'s pictures; replaced ones are
        rewritten in place and their ``direction`` updated.
    renderer : SceneRenderer, optional
        The one :func:`~study_app.design.media.write_views` used
        (:func:`~study_app.design.media.view_renderer`).

    Returns
    -------
    (views, replacements) : (dict, list of dict)
        The views as shown, and one record per replaced view
        (:meth:`~study_app.design.replacement.Replacement.to_dict`).

    Raises
    ------
    StimuliError
        A baseline has no view unlike the others within the bound (scene, method and
        IoU named).
    """
    import imageio.v3 as iio

    from snapcore.render.renderer import save_png

    from .replacement import NoReplacement, find_replacement, ranked_views

    scene = snap.scene
    renderer = renderer or view_renderer(scene, study.size)
    frame = int(picks["frame"])

    def render(direction) -> np.ndarray:
        return render_view(scene, frame, direction, renderer)

    def picture(m: str) -> np.ndarray:
        return np.asarray(iio.imread(views[m]["file"]))[..., :3]

    kept = {ViewMethod.OURS.value: (views["ours"]["direction"], picture("ours"))}
    out = []
    for m in VIEW_METHODS[1:]:
        try:
            found, pic = find_replacement(
                m.value,
                views[m.value]["direction"],
                picture(m.value),
                kept,
                ranked_views(snap, m),
                render,
                exclude_deg=study.near_duplicate_deg,
            )
        except NoReplacement as err:
            raise StimuliError(f"scene {scene_id}: {err}") from None
        if found is not None and pic is not None:
            save_png(pic, views[m.value]["file"])
            views[m.value] = {**views[m.value], "direction": _unit(found.replacement)}
            out.append(found.to_dict())
        kept[m.value] = (views[m.value]["direction"], picture(m.value))
    return views, out


def _unit(v) -> list[float]:
    a = np.asarray(v, dtype=float).reshape(3)
    return (a / np.linalg.norm(a)).tolist()


def alike_groups(pairs) -> list[list[str]]:
    """The candidates grouped by alike pictures: the connected components of ``pairs``
    (a method alike to one of a group joins it), every method of
    :data:`VIEW_METHODS` in one group, each group and the groups in that order.

    >>> alike_groups([["ours", "motion_area"]])
    [['ours', 'motion_area'], ['viewpoint_entropy']]
    >>> alike_groups([["viewpoint_entropy", "motion_area"], ["ours", "motion_area"]])
    [['ours', 'viewpoint_entropy', 'motion_area']]
    """
    names = [m.value for m in VIEW_METHODS]
    root = {m: m for m in names}

    def find(m: str) -> str:
        while root[m] != m:
            m = root[m]
        return m

    for a, b in pairs:
        ra, rb = find(a), find(b)
        if ra != rb:  # the earlier method in VIEW_METHODS order heads the group
            first, second = sorted((ra, rb), key=names.index)
            root[second] = first
    groups: dict[str, list[str]] = {}
    for m in names:
        groups.setdefault(find(m), []).append(m)
    return list(groups.values())


def merge_alike_views(study: Study, scene, picks: dict, views: dict, angle_pairs=()) -> dict:
    """Which candidate pictures are alike, and the pictures the view task shows: each
    group of alike ones once (``study.near_duplicate = "merge"``).

    Two candidates are alike when their pictures are by the validated measure
    (:mod:`study_app.design.similarity`): projected-joint distance at or under
    :data:`~study_app.design.similarity.POSE_ALIKE_DISTANCE`, or silhouette IoU at or
    above :data:`~study_app.design.similarity.NEAR_DUPLICATE_IOU` (mirror images
    included in both), or their directions at most
    :data:`~study_app.design.similarity.ALIKE_ANGLE_DEG` apart or from opposite (or under
    ``study.near_duplicate_deg``: ``angle_pairs``). A group's picture is its first method's (ours
    when ours is in it) and stands for every method of the group: no method is handed
    another view than its own.

    Parameters
    ----------
    study : Study
    scene : Scene
    picks : dict
        :func:`select_scene`'s picks (the frame, source numbering).
    views : dict
        :func:`~study_app.design.media.write_views`'s pictures and directions.
    angle_pairs : sequence of (str, str)
        Pairs near-duplicate by angle (:func:`check_near_duplicates`).

    Returns
    -------
    dict
        ``shown`` (:func:`alike_groups`: the pictures shown, each the methods it stands
        for, its own first), ``alike`` (the alike pairs), ``view_iou`` and
        ``pose_distance`` (per pair), ``view_task`` (``"shown"``, or ``"skipped"`` when
        all three pictures are alike: nothing to compare).
    """
    frame = int(picks["frame"]) - scene.frame_offset
    points, mirror = pose_points(scene, frame)
    dist = candidate_pose_distances(points, mirror, views)
    ious = candidate_ious(views)
    angles, near = candidate_angles(
        {**picks, **{PICK_KEYS[m]: views[m.value]["direction"] for m in VIEW_METHODS}},
        threshold_deg=ALIKE_ANGLE_DEG,
    )
    by_angle = {tuple(p) for p in [*near, *angle_pairs]}
    alike = [
        k.split("|")
        for k in dist
        if dist[k] <= POSE_ALIKE_DISTANCE
        or ious[k] >= NEAR_DUPLICATE_IOU
        or tuple(k.split("|")) in by_angle
    ]
    groups = alike_groups(alike)
    if len(groups) < len(VIEW_METHODS):
        warnings.warn(
            "alike pictures shown once for their methods: "
            + "; ".join(" = ".join(g) for g in groups if len(g) > 1)
            + " (pose distance "
            + ", ".join(f"{k.replace('|', '/')} {v:.2f}" for k, v in dist.items())
            + f", threshold {POSE_ALIKE_DISTANCE:g}; silhouette IoU "
            + ", ".join(f"{k.replace('|', '/')} {v:.2f}" for k, v in ious.items())
            + f", threshold {NEAR_DUPLICATE_IOU:g}; angles "
            + ", ".join(f"{k.replace('|', '/')} {v:.0f}°" for k, v in angles.items())
            + f", alike within {ALIKE_ANGLE_DEG:g}° of each other or of opposite)",
            stacklevel=2,
        )
    return {
        "shown": groups,
        "alike": alike,
        "view_iou": ious,
        "pose_distance": dist,
        "view_task": "shown" if len(groups) > 1 else "skipped",
    }
