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
    "POSE_ALIKE_DISTANCE",
    "ALIKE_ANGLE_DEG",
    "alike_check",
    "pose_points",
    "projected_pose",
    "pose_distance",
    "candidate_pose_distances",
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


#: Projected-joint distance (:func:`pose_distance`) at or under which two views show the
#: same picture of the pose. Set from the check of :func:`alike_check` (documented in
#: ``docs/alike-pictures.md``, held by ``tests/test_similarity.py``): on 10 scenes × 5
#: poses × 208 views, the distance that misclassifies as many pairs 15–20° apart (the
#: same picture) as pairs 45° apart (different pictures), the equal-error point, 0.362
#: (78% of 15–20° pairs alike, 19% of 45°, 8% of 60°, 3% of 90°). Pairs within
#: :data:`ALIKE_ANGLE_DEG` count as alike by angle whatever their distance.
POSE_ALIKE_DISTANCE = 0.35
#: Views this close in direction (degrees), or this close to each other's opposite (a
#: mirror image), show the same picture whatever the pose.
ALIKE_ANGLE_DEG = 20.0
#: Roles left out of :func:`pose_points`: many finger joints in a small hand would weigh
#: the hands above the limbs a viewer sees.
_LEFT_OUT_ROLES = ("hidden", "finger")


def pose_points(scene, frame: int) -> tuple[np.ndarray, np.ndarray]:
    """The joints a viewer sees at an internal ``frame``, every character's.

    Returns
    -------
    (points, mirror) : (ndarray of float, shape (N, 3); ndarray of int, shape (N,))
        World positions (metres) and each point's left-right twin
        (:func:`snapcore.motion.anatomy.mirror_permutation`, per character).
    """
    from snapcore.motion.anatomy import mirror_permutation

    points, perms, n = [], [], 0
    for c in scene.characters:
        keep = np.array([r not in _LEFT_OUT_ROLES for r in c.skeleton.roles])
        idx = np.flatnonzero(keep)
        perm = mirror_permutation(c.skeleton.names)
        remap = np.full(len(keep), -1)
        remap[idx] = np.arange(len(idx))
        twin = remap[perm[idx]]
        twin = np.where(twin < 0, np.arange(len(idx)), twin)  # a twin left out: itself
        points.append(np.asarray(c.positions[frame])[idx])
        perms.append(twin + n)
        n += len(idx)
    return np.concatenate(points), np.concatenate(perms)


def projected_pose(points: np.ndarray, views) -> np.ndarray:
    """The joints as a picture along each view shows them: orthographic image-plane
    coordinates (x right, y up, as the candidates are rendered), centred on their mean
    and each axis scaled to unit RMS spread (the pictures are framed to the figure, so
    position and size do not count, and a narrow side view's arrangement of limbs
    counts as much as a wide one's).

    Parameters
    ----------
    points : ndarray, shape (N, 3)
    views : array_like, shape (V, 3) or (3,)
        Directions from the scene towards the camera.

    Returns
    -------
    ndarray, shape (V, N, 2) (or (N, 2) for one view)
    """
    from snapcore.render.camera import view_basis

    v = np.asarray(views, float)
    one = v.ndim == 1
    v = v.reshape(-1, 3)
    basis = np.array([view_basis(d)[:2] for d in v])  # (V, 2, 3): right, up
    xy = np.einsum("nk,vck->vnc", np.asarray(points, float), basis)
    xy -= xy.mean(axis=1, keepdims=True)
    spread = np.sqrt((xy**2).mean(axis=1))  # (V, 2): each axis on its own, as framed
    xy /= np.where(spread > 0, spread, 1.0)[:, None, :]
    return xy[0] if one else xy


def pose_distance(points: np.ndarray, mirror: np.ndarray, a, b) -> np.ndarray:
    """How unlike the pictures of a pose along views ``a`` and ``b`` are: the RMS distance
    between the normalised projected joints (:func:`projected_pose`), the smallest over
    ``b``'s picture as it is and mirrored left-right, each with its limbs as they are and
    with left and right swapped (a viewer does not tell a left arm from a right one).
    0 = the same picture; a figure's spread along each image axis is 1 (each axis is
    scaled on its own, as a picture framed to the figure shows a thin figure's width).

    Parameters
    ----------
    points, mirror : :func:`pose_points`
    a, b : array_like, shape (3,) or (V, 3)
        View directions (broadcast together).

    Returns
    -------
    ndarray of float, shape () or (V,)
    """
    a, b = np.broadcast_arrays(np.asarray(a, float), np.asarray(b, float))
    pa = projected_pose(points, a.reshape(-1, 3))
    pb = projected_pose(points, b.reshape(-1, 3))
    flip = np.array([-1.0, 1.0])
    cands = [pb, pb * flip, pb[:, mirror], pb[:, mirror] * flip]
    d = np.min([np.sqrt(((pa - c) ** 2).sum(axis=2).mean(axis=1)) for c in cands], axis=0)
    return d.reshape(a.shape[:-1])


def candidate_pose_distances(points: np.ndarray, mirror: np.ndarray, views: dict) -> dict:
    """``{"a|b": pose_distance}`` for each pair of candidate views (``views``: method →
    ``{"direction": [x, y, z]}`` or a direction), in :data:`VIEW_METHODS` order."""
    dirs = {
        m: np.asarray(v["direction"] if isinstance(v, dict) else v, float) for m, v in views.items()
    }
    names = [m.value for m in VIEW_METHODS if m.value in dirs]
    return {
        f"{a}|{b}": round(float(pose_distance(points, mirror, dirs[a], dirs[b])), 3)
        for i, a in enumerate(names)
        for b in names[i + 1 :]
    }


def _fibonacci_views(n: int) -> np.ndarray:
    """``n`` near-uniform unit directions on the sphere, shape (n, 3), Y up."""
    i = np.arange(n) + 0.5
    polar = np.arccos(1 - 2 * i / n)
    azimuth = np.pi * (1 + 5**0.5) * i
    return np.stack(
        [np.cos(azimuth) * np.sin(polar), np.cos(polar), np.sin(azimuth) * np.sin(polar)], axis=1
    )


def alike_check(
    poses, *, offsets=((15.0, 20.0), (45.0, 45.0), (60.0, 60.0)), n_views: int = 400, seed: int = 0
) -> dict:
    """The check :data:`POSE_ALIKE_DISTANCE` is set from: pose distances of view pairs a
    known angle apart.

    For each pose, views of the candidates' range (elevation −10° to 60°: 208 of the
    400 default ``n_views`` sphere samples) are paired with a view turned by an angle drawn from each
    offset range about a random axis (seeded). Pairs 15–20° apart show the same picture;
    pairs 45° or more apart mostly do not.

    Parameters
    ----------
    poses : iterable of (points, mirror)
        :func:`pose_points` of each pose.
    offsets : sequence of (low, high)
        Angle ranges (degrees).

    Returns
    -------
    dict
        ``(low, high)`` → ndarray of the pose distances of every pair.
    """
    rng = np.random.default_rng(seed)
    base = _fibonacci_views(n_views)
    elevation = np.degrees(np.arcsin(base[:, 1]))
    base = base[(elevation > -10) & (elevation < 60)]
    out: dict = {tuple(o): [] for o in offsets}
    for points, mirror in poses:
        for lo, hi in out:
            axis = rng.normal(size=base.shape)
            axis -= (axis * base).sum(axis=1, keepdims=True) * base
            axis /= np.linalg.norm(axis, axis=1, keepdims=True)
            turn = np.radians(rng.uniform(lo, hi, len(base)))[:, None]
            other = np.cos(turn) * base + np.sin(turn) * axis
            out[(lo, hi)].append(pose_distance(points, mirror, base, other))
    return {k: np.concatenate(v) if v else np.zeros(0) for k, v in out.items()}
