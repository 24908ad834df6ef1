"""Replacing a baseline's candidate view whose picture is nearly another candidate's.

The view task shows the selected pose from three directions (ours, viewpoint entropy,
motion area) and asks which shows it best. When two of the pictures are nearly the same
(silhouette IoU at or above :data:`~study_app.design.similarity.NEAR_DUPLICATE_IOU`,
mirror images included: :mod:`study_app.design.similarity`), the votes split between
them and the task no longer compares three methods. On the demo study as built before
this module (480×360) motion area's picture was nearly ours in 4 of 5 scenes: IoU 0.85
(walk, 10.2° apart), 0.95 (jump, 163.6°: a mirror image the 165° angle cut-off misses),
0.85 (punch, 9.8°) and 0.89 (push, 169.2°); every other pair scored 0.27–0.63.

With ``study.near_duplicate = "replace"`` (the default) the stimuli builder keeps ours
and, baseline by baseline in :data:`~snapcore.select.view_methods.VIEW_METHODS` order
(viewpoint entropy, then motion area), replaces a picture that is too alike to one
already kept by the best view *of that baseline's own score* whose picture is not:

1. Rank the baseline's scored views (:func:`ranked_views`): motion area's exact score
   (m²) of every sample of its view sphere (one half of it: the score is the same from
   ``v`` and ``-v``; the side is chosen by the same rule as its pick), viewpoint
   entropy's score (bits) of each of its rendered sample views.
2. Skip, without rendering, every view within ``near_duplicate_deg`` of a kept view, of
   the rejected original, of a view already rejected, or of their opposites (the
   mirror images): such views show the same silhouette.
3. Render the next view as the candidate is rendered and keep it when its silhouette
   IoU with every kept picture is below the threshold; otherwise reject it (step 2
   then skips its neighbourhood) and go on, at most :data:`MAX_RENDERS` renders.
4. None found: :class:`~study_app.design.stimuli.StimuliError`, naming the scene, the
   method and the measure.

Only a handful of pictures are rendered per replaced view, never the sphere. The
manifest records each replacement (:class:`Replacement`): the original and the new
direction, the IoUs before and after, the scores and why.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from snapcore.errors import SnapshotError
from snapcore.select.view_methods import VIEW_METHODS, ViewMethod

from .similarity import NEAR_DUPLICATE_IOU, mask_iou, silhouette

__all__ = ["MAX_RENDERS", "Replacement", "NoReplacement", "ranked_views", "find_replacement"]

#: Pictures rendered at most while looking for one baseline's replacement view.
MAX_RENDERS = 12


class NoReplacement(SnapshotError):
    """No view of the baseline's ranking is unlike the kept pictures within the bound."""


@dataclass
class Replacement:
    """One baseline view replaced because its picture was nearly another candidate's.

    Attributes
    ----------
    method : str
        The baseline whose view was replaced.
    original, replacement : list of float
        Unit view directions (scene centre → camera, world frame, Y up).
    alike : list of str
        The candidates whose pictures the original was too alike to.
    iou_before, iou_after : dict of str to float
        Silhouette IoU of the original / the replacement with each kept candidate,
        keyed ``"a|b"`` in :data:`VIEW_METHODS` order.
    score_original, score_replacement : float
        The method's own score of each view (``score_unit``).
    score_unit : str
        ``"m²"`` (motion area) or ``"bits"`` (viewpoint entropy).
    rank : int
        1-based rank of the replacement in the method's ranking of its views.
    renders : int
        Pictures rendered to find it.
    reason : str
        One line: which IoU was too high, against which threshold.
    """

    method: str
    original: list
    replacement: list
    alike: list
    iou_before: dict
    iou_after: dict
    score_original: float
    score_replacement: float
    score_unit: str
    rank: int
    renders: int
    reason: str

    def to_dict(self) -> dict:
        """The manifest's record (``data_schema/stimuli.schema.json``, ``replacements``)."""
        return {
            "method": self.method,
            "original": [round(float(x), 6) for x in self.original],
            "replacement": [round(float(x), 6) for x in self.replacement],
            "alike": list(self.alike),
            "iou_before": {k: round(float(v), 3) for k, v in self.iou_before.items()},
            "iou_after": {k: round(float(v), 3) for k, v in self.iou_after.items()},
            "score_original": float(self.score_original),
            "score_replacement": float(self.score_replacement),
            "score_unit": self.score_unit,
            "rank": int(self.rank),
            "renders": int(self.renders),
            "reason": self.reason,
        }


def ranked_views(snap, method: ViewMethod | str) -> tuple[np.ndarray, np.ndarray, float, str]:
    """A baseline's views, best first by its own score.

    Parameters
    ----------
    snap : snapcore.pipeline.Snapshot
        With its baselines (``take_snapshot(scene, view=ViewParams(baselines=True))``).
    method : ViewMethod
        ``MOTION_AREA`` or ``VIEWPOINT_ENTROPY``.

    Returns
    -------
    (views, scores, score_of_pick, unit)
        ``views`` (N, 3) unit directions and their ``scores`` (N,), best first (ties in
        the sphere's order); the score of the method's own pick; the score's unit.
    """
    from snapcore.motion.facing import choose_side
    from snapcore.select.view import motion_triangles, pma_scores

    method = ViewMethod(method)
    if method is ViewMethod.MOTION_AREA:
        sel = snap.motion_area
        floor = snap.view_params.floor_m2 if snap.view_params is not None else None
        tri = motion_triangles(
            snap.scene, frames=sel.frames, **({} if floor is None else {"floor": floor})
        )
        half = sel.views[: len(sel.views) // 2]  # the other half: the same views reversed
        scores = pma_scores(half, tri, weighting="motion_area")
        views = np.array([choose_side(v, sel.facing)[0] for v in half])
        unit = "m²"
    elif method is ViewMethod.VIEWPOINT_ENTROPY:
        sel = snap.viewpoint_entropy
        ok = np.isfinite(sel.scores)  # views under the elevation limit were not scored
        views, scores = np.asarray(sel.views)[ok], np.asarray(sel.scores)[ok]
        unit = "bits"
    else:
        raise ValueError(f"only a baseline's view is replaced, not {method.value}'s")
    order = np.argsort(-scores, kind="stable")
    return views[order], scores[order], float(sel.score), unit


def _pair(a: str, b: str) -> str:
    names = [m.value for m in VIEW_METHODS]
    return f"{a}|{b}" if names.index(a) < names.index(b) else f"{b}|{a}"


def find_replacement(
    method: str,
    original,
    original_picture: np.ndarray,
    kept: dict,
    ranking: tuple[np.ndarray, np.ndarray, float, str],
    render: Callable[[np.ndarray], np.ndarray],
    *,
    exclude_deg: float,
    threshold: float = NEAR_DUPLICATE_IOU,
    max_renders: int = MAX_RENDERS,
) -> tuple[Replacement | None, np.ndarray | None]:
    """Keep ``method``'s view, or find the best-ranked one whose picture is unlike the kept.

    Parameters
    ----------
    method : str
        The baseline.
    original : array of shape (3,)
        Its view direction.
    original_picture : ndarray of uint8, shape (H, W, 3)
        Its rendered picture.
    kept : dict of str to (direction, picture)
        The candidates already kept (ours first).
    ranking : tuple
        :func:`ranked_views` of the method.
    render : callable
        Direction (3,) → picture (H, W, 3), exactly as the candidates are rendered.
    exclude_deg : float
        Views this close to a kept, original or rejected view, or to its opposite (a
        mirror image), are skipped without rendering (degrees).
    threshold : float
        Silhouette IoU at or above which two pictures are too alike.
    max_renders : int

    Returns
    -------
    (Replacement or None, picture or None)
        ``(None, None)`` when the original is unlike every kept picture.

    Raises
    ------
    NoReplacement
        No view within ``max_renders`` renders (or in the whole ranking) is unlike them;
        the message gives the measure.
    """
    kept_masks = {m: silhouette(pic) for m, (_, pic) in kept.items()}

    def ious(picture) -> dict:
        s = silhouette(picture)
        return {_pair(m, method): mask_iou(k, s) for m, k in kept_masks.items()}

    before = ious(original_picture)
    alike = [m for m in kept if before[_pair(m, method)] >= threshold]
    if not alike:
        return None, None
    views, scores, score0, unit = ranking
    cos_cut = float(np.cos(np.radians(exclude_deg)))
    avoid = [np.asarray(d, float) for d, _ in kept.values()] + [np.asarray(original, float)]
    renders, best_rejected = 0, None
    for rank, (v, score) in enumerate(zip(views, scores, strict=True), start=1):
        near = np.abs(np.array(avoid) @ v / np.linalg.norm(v)) > cos_cut
        if near.any():
            continue
        if renders >= max_renders:
            break
        picture = render(v)
        renders += 1
        after = ious(picture)
        worst = max(after.values())
        if worst < threshold:
            reason = (
                f"silhouette IoU {', '.join(f'{before[_pair(m, method)]:.2f} with {m}' for m in alike)}"
                f" at or above {threshold:g} (mirror images included)"
            )
            return (
                Replacement(
                    method=method,
                    original=list(np.asarray(original, float)),
                    replacement=list(v),
                    alike=alike,
                    iou_before=before,
                    iou_after=after,
                    score_original=score0,
                    score_replacement=float(score),
                    score_unit=unit,
                    rank=rank,
                    renders=renders,
                    reason=reason,
                ),
                picture,
            )
        avoid.append(v)
        best_rejected = worst if best_rejected is None else min(best_rejected, worst)
    measure = ", ".join(f"{before[_pair(m, method)]:.2f} with {m}" for m in alike)
    tried = (
        f"; the next {renders} views it ranks best were too alike as well "
        f"(lowest IoU {best_rejected:.2f})"
        if renders
        else (
            f"; no other view it ranks is {exclude_deg:g}° or more from the kept ones "
            "and their mirror images (study.near_duplicate_deg)"
        )
    )
    raise NoReplacement(
        f"{method}'s view has silhouette IoU {measure} (threshold {threshold:g}, mirror "
        f"images included){tried}"
    )
