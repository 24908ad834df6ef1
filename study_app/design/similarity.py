"""How alike two candidate pictures are: their silhouettes' IoU, mirror images included.

Two candidate views are near-duplicates when their *pictures* are: the angle between
view directions misses mirror images near (but not at) 180° and symmetric poses. Used
by the stimuli builder (:mod:`study_app.design.stimuli`) on the rendered candidates.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from snapcore.select.view_methods import VIEW_METHODS

__all__ = ["NEAR_DUPLICATE_IOU", "silhouette", "silhouette_iou", "candidate_ious"]

#: Silhouette IoU (mirror images included) at or above which two candidate pictures count
#: as nearly the same picture. Measured on the tiny test study's rendered candidates
#: (160×120, tests/app_helpers.TINY_STUDY): the pairs a person sees as the same figure
#: or its mirror image score 0.93 (jump: ours/motion area, 163.6° apart, the mirror pair
#: the 165° angle cut-off misses) and 0.91 (push: ours/motion area, 168.9°); the other
#: pairs 0.47–0.64. 0.8 lies between the two groups.
NEAR_DUPLICATE_IOU = 0.8
#: Side of the square the silhouettes are compared at (px), after cropping each to its
#: bounding box (so framing and scale do not count, only the shape).
_SILHOUETTE_SIDE = 64


def silhouette(path: str | Path) -> np.ndarray:
    """The figure's silhouette in a candidate picture: pixels unlike the background (the
    corner colour), cropped to their bounding box and resampled to a square.

    Returns
    -------
    ndarray of bool, shape (64, 64)
    """
    from PIL import Image

    img = np.asarray(Image.open(path).convert("RGB"), dtype=np.int16)
    mask = np.abs(img - img[0, 0]).max(axis=2) > 30
    if not mask.any():
        return np.zeros((_SILHOUETTE_SIDE, _SILHOUETTE_SIDE), dtype=bool)
    rows, cols = np.flatnonzero(mask.any(axis=1)), np.flatnonzero(mask.any(axis=0))
    crop = mask[rows[0] : rows[-1] + 1, cols[0] : cols[-1] + 1]
    small = Image.fromarray(crop.astype(np.uint8) * 255).resize(
        (_SILHOUETTE_SIDE, _SILHOUETTE_SIDE), Image.Resampling.BILINEAR
    )
    return np.asarray(small) >= 128


def silhouette_iou(a: str | Path, b: str | Path) -> float:
    """How alike two candidate pictures are: the IoU of their silhouettes, the larger of
    ``b`` as it is and mirrored left-right (a mirror image is the same picture to a
    viewer choosing the clearest one). 0 (nothing shared) to 1 (the same shape)."""
    sa, sb = silhouette(a), silhouette(b)

    def iou(x, y) -> float:
        union = np.logical_or(x, y).sum()
        return float(np.logical_and(x, y).sum() / union) if union else 1.0

    return max(iou(sa, sb), iou(sa, sb[:, ::-1]))


def candidate_ious(views: dict) -> dict[str, float]:
    """``{"a|b": silhouette IoU}`` for each pair of candidate pictures (``views``:
    method → ``{"file": path}`` or path), in :data:`VIEW_METHODS` order."""
    files = {m: Path(v["file"] if isinstance(v, dict) else v) for m, v in views.items()}
    names = [m.value for m in VIEW_METHODS if m.value in files]
    return {
        f"{a}|{b}": round(silhouette_iou(files[a], files[b]), 3)
        for i, a in enumerate(names)
        for b in names[i + 1 :]
    }
