"""How alike two candidate pictures are: their silhouettes' IoU, mirror images included.

Two candidate views are near-duplicates when their *pictures* are: the angle between
view directions misses mirror images near (but not at) 180° and symmetric poses. Used
by the stimuli builder (:mod:`study_app.design.candidates`) on the rendered candidates, and
to pick a replacement view (:mod:`study_app.design.replacement`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from snapcore.select.view_methods import VIEW_METHODS

__all__ = [
    "NEAR_DUPLICATE_IOU",
    "silhouette",
    "silhouette_iou",
    "mask_iou",
    "candidate_ious",
]

#: Silhouette IoU (mirror images included) at or above which two candidate pictures count
#: as nearly the same picture. Measured on the rendered candidates of the demo study
#: (480×360, study_app/configs/demo.toml, each method's own view): the pairs a person
#: sees as the same figure or its mirror image are ours/motion area in 4 of 5 scenes,
#: IoU 0.85 (walk, 10.2° apart), 0.95 (jump, 163.6°: the mirror pair the 165° angle
#: cut-off misses), 0.85 (punch, 9.8°) and 0.89 (push, 169.2°); every other pair scored
#: 0.27–0.63 (kick's three pairs 0.27–0.46, 19.6–56° apart). The tiny test study
#: (160×120, tests/app_helpers.TINY_STUDY) gives 0.94 (jump) and 0.90 (push) for the
#: same pairs. 0.8 lies between the two groups; the views that replace the alike ones
#: (:mod:`study_app.design.replacement`) score 0.61–0.76 with ours.
NEAR_DUPLICATE_IOU = 0.8
#: Side of the square the silhouettes are compared at (px), after cropping each to its
#: bounding box (so framing and scale do not count, only the shape).
_SILHOUETTE_SIDE = 64


def silhouette(picture: str | Path | np.ndarray) -> np.ndarray:
    """The figure's silhouette in a candidate picture: pixels unlike the background (the
    corner colour), cropped to their bounding box and resampled to a square.

    Parameters
    ----------
    picture : path or ndarray of uint8, shape (H, W, 3)
        The picture's file, or the picture as rendered (not yet written).

    Returns
    -------
    ndarray of bool, shape (64, 64)
    """
    from PIL import Image

    if isinstance(picture, np.ndarray):
        img = np.asarray(picture[..., :3], dtype=np.int16)
    else:
        img = np.asarray(Image.open(picture).convert("RGB"), dtype=np.int16)
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
    return mask_iou(silhouette(a), silhouette(b))


def mask_iou(sa: np.ndarray, sb: np.ndarray) -> float:
    """:func:`silhouette_iou` of two :func:`silhouette` masks (bool, same shape): the
    larger IoU of ``sb`` as it is and mirrored left-right."""

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
