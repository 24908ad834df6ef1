"""Viewpoint entropy (Vázquez et al. 2001): the mesh-visibility baseline view.

The paper compares its view with the viewpoint-entropy view (its Fig. 9, via the view
descriptors of Secord et al. 2011). For the posed body mesh at the selected frame and a
view ``v`` (orthographic, the mesh's bounding sphere framed identically for every view)

    H(v) = - Σ_{i=0}^{N_faces} (A_i / A_t) log2(A_i / A_t)

where ``A_i`` is the visible projected area of face ``i``, ``A_0`` the background and
``A_t`` the image area. Areas are pixel counts of a face-id render
(:func:`snapcore.render.buffers.render_face_ids`, no multisampling, back faces culled).

Resolution: the number of faces a view "sees" depends strongly on the image size
(3.2k faces per view at 256² vs 8.9k at 512² for a 77k-face mesh,
../shared/PLATFORM-NOTES.md), so the baseline fixes one: :data:`VE_RESOLUTION` = 256²
(:data:`~snapcore.render.buffers.FACE_ID_RESOLUTION`), on 162 icosphere views.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from snapcore.errors import SnapshotError
from snapcore.render.bodies import DEFAULT_BODY, BodyKind, posed_mesh
from snapcore.render.buffers import face_id_blocks
from snapcore.select.view import view_sphere

__all__ = [
    "EntropyError",
    "VE_RESOLUTION",
    "VE_VIEWS",
    "MIN_ELEVATION_DEG",
    "EntropySelection",
    "viewpoint_entropy",
    "select_view_entropy",
]

#: Square face-id image side (pixels) of the baseline: fixed, see the module notes.
VE_RESOLUTION = 256
#: Sample views of the baseline (an icosphere, ~17° apart), as in the paper's setting.
VE_VIEWS = 162
#: Lowest camera elevation the baseline may pick (degrees below the horizon): the same
#: limit the PMA view keeps (:data:`snapcore.motion.facing.ABOVE_DEG`), so neither method is
#: shown looking up through the floor. ``min_elevation_deg=None`` searches all views.
MIN_ELEVATION_DEG = -10.0


class EntropyError(SnapshotError):
    """A viewpoint-entropy request that cannot be met (bad id buffers, empty mesh)."""


def viewpoint_entropy(face_ids, n_faces: int | None = None) -> np.ndarray | float:
    """Viewpoint entropy of face-id images, one value per view (bits).

    Parameters
    ----------
    face_ids : int array of shape (V, H, W) or (H, W)
        ``0`` = background, ``k + 1`` = face ``k`` (the convention of
        :func:`snapcore.render.buffers.render_face_ids`).
    n_faces : int, optional
        Number of faces of the mesh (default: the largest id seen).

    Returns
    -------
    ndarray of shape (V,) (or a float for one image)
        ``H = -Σ_i p_i log2 p_i`` over the background and every visible face, with
        ``p_i = A_i / A_t`` the fraction of the image's pixels showing ``i``. Between 0
        (empty image) and ``log2(H·W)``.

    Notes
    -----
    Per-view histograms come from one ``bincount`` per view, not from a loop over
    faces.
    """
    ids = np.asarray(face_ids)
    single = ids.ndim == 2
    h, _ = _entropy_visible(ids[None] if single else ids, n_faces)
    return float(h[0]) if single else h


def _entropy_visible(ids, n_faces):
    """Entropy (bits) and number of visible faces per view of ids (V, H, W)."""
    if ids.ndim != 3 or not np.issubdtype(ids.dtype, np.integer):
        raise EntropyError(
            f"face ids must be an integer array (V, H, W), got {ids.dtype} {ids.shape}"
        )
    if ids.size and ids.min() < 0:
        raise EntropyError("face ids must be >= 0 (0 = background)")
    n_bins = (int(ids.max()) if n_faces is None else int(n_faces)) + 1
    if ids.size and ids.max() >= n_bins:
        raise EntropyError(f"face id {int(ids.max()) - 1} is not below n_faces={n_faces}")
    v, h, w = ids.shape
    hist = _Histograms(v, n_bins)
    hist(0, ids)
    return hist.entropy_visible(h * w)


class _Histograms:
    """Per-view face histograms, filled block by block (:meth:`__call__`, the
    ``each_block`` of :func:`snapcore.render.buffers.face_id_blocks`; blocks of
    different views may be filled from different threads), then reduced to entropies.

    One small histogram per view (n_bins counts, cache-sized), not one over
    view-offset int64 keys (V x n_bins counts, ~70 MB for the bench's 162 views of 53k
    faces): 72 -> 47 ms there. Only the bins that occur enter the sum (a view shows a
    few thousand of the faces). The terms are summed per view in the same order as
    before (background, then faces by index, one bincount accumulating sequentially),
    so the entropies are bit-identical to those of one bincount over all views.
    """

    def __init__(self, n_views: int, n_bins: int) -> None:
        self.n_bins = n_bins
        self.hits: list = [None] * n_views
        self.counts: list = [None] * n_views

    def __call__(self, first: int, ids) -> None:
        for k, image in enumerate(ids):
            c = np.bincount(image.reshape(-1).astype(np.intp, copy=False), minlength=self.n_bins)
            hit = np.flatnonzero(c)
            self.hits[first + k] = hit
            self.counts[first + k] = c[hit]

    def entropy_visible(self, n_pixels: int) -> tuple[np.ndarray, np.ndarray]:
        """Entropy (bits) and visible faces per view, (V,) each."""
        v = len(self.hits)
        n_hit = np.fromiter((len(x) for x in self.hits), np.int64, count=v)
        view = np.repeat(np.arange(v), n_hit)
        p = (np.concatenate(self.counts) if v else np.empty(0)) / float(n_pixels)
        entropy = -np.bincount(view, weights=p * np.log2(p), minlength=v)
        background = np.fromiter((len(x) > 0 and x[0] == 0 for x in self.hits), np.int64, v)
        return entropy, n_hit - background


@dataclass
class EntropySelection:
    """The viewpoint-entropy view of one frame.

    Attributes
    ----------
    view : ndarray of shape (3,)
        Unit vector from the mesh centre to the camera with the highest entropy.
    score : float
        Its entropy, bits.
    views : ndarray of shape (V, 3)
        All sample views.
    scores : ndarray of shape (V,)
        Entropy of every view (bits; NaN for views below ``min_elevation_deg``, which
        were not rendered unless ``score_all``).
    frame : int
        Internal index of the posed mesh (``scene.source_frame(frame)`` is the file's
        frame number, what the JSON reports).
    n_faces : int
        Faces of the posed mesh.
    resolution : int
        Face-id image side, pixels.
    visible_faces : ndarray of shape (V,)
        Faces with at least one pixel, per view (0 where not rendered).
    """

    view: np.ndarray
    score: float
    views: np.ndarray
    scores: np.ndarray
    frame: int
    n_faces: int
    resolution: int
    visible_faces: np.ndarray

    def to_dict(self) -> dict:
        """JSON-ready summary (internal frame; callers convert with ``source_frame``)."""
        return {
            "view": [float(x) for x in self.view],
            "score": float(self.score),
            "n_views": int(self.views.shape[0]),
            "n_faces": int(self.n_faces),
            "resolution": int(self.resolution),
        }


def select_view_entropy(
    scene,
    index: int,
    *,
    n_views: int = VE_VIEWS,
    resolution: int = VE_RESOLUTION,
    min_elevation_deg: float | None = MIN_ELEVATION_DEG,
    score_all: bool = False,
    body: BodyKind = DEFAULT_BODY,
    mesh=None,
) -> EntropySelection:
    """The view of maximal viewpoint entropy of the posed body at ``index``.

    Parameters
    ----------
    scene : Scene
    index : int
        Internal index of the pose (``Snapshot.index``: source frame minus
        ``scene.frame_offset``).
    n_views : int
        Sample views (:func:`snapcore.select.view.view_sphere`; 162 by default).
    resolution : int
        Face-id image side in pixels (:data:`VE_RESOLUTION`; keep it fixed when
        comparing: entropy grows with it).
    min_elevation_deg : float or None
        The pick is not more than this far below the horizon
        (:data:`MIN_ELEVATION_DEG`); None allows the whole sphere.
    score_all : bool
        Render and score the views below ``min_elevation_deg`` too (for maps); by
        default they are skipped (NaN scores).
    body : {"human", "mannequin"}
        The body kind whose posed mesh is scored (:data:`snapcore.render.bodies.BodyKind`;
        ignored with ``mesh``).
    mesh : object with ``vertices`` (N, 3) and ``faces`` (M, 3), optional
        The mesh to use instead of :func:`snapcore.render.bodies.posed_mesh` of the scene.

    Returns
    -------
    EntropySelection
        Ties go to the first view in the sphere's order (deterministic).
    """
    if mesh is None:
        if not 0 <= int(index) < scene.n_frames:
            raise EntropyError(f"index {index} is outside 0..{scene.n_frames - 1}")
        mesh = posed_mesh(scene, int(index), kind=body)
    vertices, faces = np.asarray(mesh.vertices, float), np.asarray(mesh.faces)
    if len(faces) == 0:
        raise EntropyError("the posed mesh has no faces")
    views = view_sphere(n_views)
    allowed = np.ones(len(views), dtype=bool)
    if min_elevation_deg is not None:
        allowed = views[:, 1] >= math.sin(math.radians(min_elevation_deg)) - 1e-12
    keep = np.ones(len(views), dtype=bool) if score_all else allowed
    # the histograms are taken block by block as the views are read back (pixel order
    # does not matter to them): no (V, H, W) id array
    hist = _Histograms(int(keep.sum()), len(faces) + 1)
    face_id_blocks(vertices, faces, views[keep], hist, resolution=resolution)
    scores = np.full(len(views), np.nan)
    visible = np.zeros(len(views), dtype=np.int64)
    scores[keep], visible[keep] = hist.entropy_visible(resolution * resolution)
    best = int(np.nanargmax(np.where(allowed, scores, np.nan)))
    return EntropySelection(
        view=views[best].copy(),
        score=float(scores[best]),
        views=views,
        scores=scores,
        frame=int(index),
        n_faces=int(len(faces)),
        resolution=int(resolution),
        visible_faces=visible,
    )
