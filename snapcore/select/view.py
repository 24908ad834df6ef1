"""View selection: the view sphere, Projected Motion Area, motion area and refinement.

The paper's §3.2 (METHOD.md §2-3). Every link of every character sweeps a quad between
two frames; split into two triangles with vector areas ``a_k`` (m²). For a view ``v``
(a unit vector from the scene centre to an orthographic camera) the projected area of
triangle ``k`` is ``|a_k · v|``, so both scores are sums of absolute dot products

    score(v) = Σ_k |b_k · v|,    b_k = a_k / MA_orig(quad of k)   (PMA, eq. 10-11)
                                 b_k = a_k                        (motion area, Kwon & Lee)

and maximising either over the sphere is an L1-norm principal component. This module
evaluates them exactly (:func:`pma_scores`, one matrix product per chunk of views),
refines a view to a local optimum with the fixed-point step
``v ← normalise(Σ_k sign(b_k·v) b_k)`` (:func:`refine_view`, never lowers the score),
and selects the view of a scene fast (:func:`select_view`, the engine is
:mod:`snapcore.select.sphere`): a binned lower bound over the sample sphere, refinement of
its best local maxima on the bins, exact refinement on the true triangles, and a
certificate that no sample beats the answer. Front and
back (``score(v) == score(-v)``) are told apart by the characters' facing
(:mod:`snapcore.motion.facing`).

Conventions: metres, Y up; a view is a unit vector pointing from the scene centre to the
camera; frames are internal indices (``scene.source_frame`` converts for output).
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike

from snapcore.errors import SnapshotError
from snapcore.motion.facing import choose_side, scene_facing
from snapcore.select import kernels
from snapcore.select.sphere import (
    CHUNK,
    ICOSPHERE_COUNTS,
    REFINE_MAX_ITER,
    RefineResult,
    abs_dot_sums,
    chunk_slices,
    one_blas_thread,
    refine_exact,
    sphere_samples,
    sphere_search,
)
from snapcore.select.view_methods import ViewMethod

if TYPE_CHECKING:
    from snapcore.motion.scene import Character, Scene

__all__ = [
    "view_angles_deg",
    "near_duplicate_views",
    "MA_FLOOR_M2",
    "ICOSPHERE_COUNTS",
    "WEIGHTINGS",
    "MotionTriangles",
    "RefineResult",
    "ViewSelection",
    "ViewError",
    "view_sphere",
    "motion_triangles",
    "pma_scores",
    "refine_view",
    "select_view",
    "window_frames",
]

#: Quads whose swept area ``MA_orig`` (m²) is below this are skipped: resting-limb
#: jitter must not vote (each kept quad's PMA ratio weighs as much as a full swing).
#: 1e-5 m² is a 10 cm link moving 0.1 mm between frames; on the shared clips it skips
#: 0-2 % of quads (eye and toe end sites of the salsa and boxing files mostly).
MA_FLOOR_M2 = 1e-5
#: Score weightings: ``"pma"`` (ratio per quad, the paper) and ``"motion_area"`` (m²).
WEIGHTINGS = ("pma", "motion_area")


class ViewError(SnapshotError):
    """A view-selection request that cannot be met (bad window, bad views array)."""


# ----------------------------------------------------------------------- view sphere


def view_sphere(n: int = 2562) -> np.ndarray:
    """Sample views over the unit sphere.

    Parameters
    ----------
    n : int
        Number of views, even and ≥ 12. Icosphere counts (12, 42, 162, 642, 2562,
        10242, ...; ~4° apart at 2562) give icosphere vertices; others a Fibonacci set.

    Returns
    -------
    ndarray of shape (n, 3)
        Unit vectors; the set is antipodally symmetric: row ``i + n/2`` is ``-row i``,
        and rows ``:n/2`` have ``y > 0`` (or lie on the horizon).
    """
    n = int(n)
    if n < 12 or n % 2:
        raise ViewError(f"n_views must be an even number >= 12, got {n}")
    return sphere_samples(n).copy()


# ------------------------------------------------------------------- motion triangles


@dataclass(eq=False)
class MotionTriangles:
    """The triangles swept by every link between consecutive frames.

    Quad ``x_j(i), x_c(i), x_c(i+1), x_j(i+1)`` of link j → c is split along
    ``x_j(i) → x_c(i+1)`` into triangles with vector areas ``a1 = ½ e_i × d`` and
    ``a2 = ½ d × g`` (``e_i = x_c(i) - x_j(i)``, ``d = x_c(i+1) - x_j(i)``,
    ``g = x_j(i+1) - x_j(i)``); ``MA_orig = |a1| + |a2|``.

    Attributes
    ----------
    pma_vectors : ndarray of shape (3, K)
        ``a_k / MA_orig`` of the quad of triangle k, components in rows (fast
        products); zero for quads below the noise floor. Read-only.
    pma_norms : ndarray of shape (K,)
        ``|a_k| / MA_orig`` (0 for skipped quads). Read-only.
    quads : ndarray of shape (Q,)
        ``MA_orig`` of every quad (m², ``Q = K / 2``). Read-only.
    frames : tuple of int
        ``(start, stop)``: internal frames ``start .. stop-1`` were used.
    blocks : list of tuple
        Per character ``(character, offset, n_steps, links)``: its triangles are
        ``offset .. offset + 2·n_steps·L`` in the order (triangle 1|2, step, link), its
        quads ``offset/2 ..`` in the order (step, link).
    floor : float
        The noise floor used (m²).

    Only the PMA vectors and the quad areas are stored (the fast path needs nothing
    else, and every stored megabyte costs page faults); the vector areas and the
    motion-area weighting are derived on demand.
    """

    pma_vectors: np.ndarray
    pma_norms: np.ndarray
    quads: np.ndarray
    frames: tuple[int, int]
    blocks: list
    floor: float
    _cache: dict = field(default_factory=dict, repr=False)

    @property
    def n_triangles(self) -> int:
        return int(self.pma_vectors.shape[1])

    @property
    def n_quads(self) -> int:
        """Quads above the noise floor (the ones that vote)."""
        if "n_quads" not in self._cache:  # asked three times per selection (0.07 ms each)
            self._cache["n_quads"] = int(np.count_nonzero(self.quads >= self.floor))
        return self._cache["n_quads"]

    @property
    def n_skipped(self) -> int:
        """Quads below the noise floor."""
        return int(self.quads.size) - self.n_quads

    @property
    def quad_area(self) -> np.ndarray:
        """``MA_orig`` of the quad of each triangle, shape (K,), m²."""
        if "quad_area" not in self._cache:
            out = np.empty(self.n_triangles)
            for _, off, steps, links in self.blocks:
                n = steps * len(links)
                out[off : off + 2 * n].reshape(2, n)[:] = self.quads[off // 2 : off // 2 + n]
            self._cache["quad_area"] = out
        return self._cache["quad_area"]

    @property
    def areas(self) -> np.ndarray:
        """Vector areas ``a_k`` (m²) of the voting triangles, shape (3, K); zero for
        quads below the noise floor."""
        return self.vectors("motion_area")

    def vectors(self, weighting: str = "pma") -> np.ndarray:
        """``b_k`` of ``score(v) = Σ_k |b_k·v|``, shape (3, K), read-only.

        ``"pma"``: ``a_k / MA_orig`` (dimensionless, each quad contributes ≤ 1);
        ``"motion_area"``: ``a_k`` (m²). Skipped quads give zero vectors.
        """
        _check_weighting(weighting)
        if weighting == "pma":
            return self.pma_vectors
        if "motion_area" not in self._cache:
            q = self.quad_area
            b = np.empty_like(self.pma_vectors)
            bn = np.empty_like(self.pma_norms)
            for z in chunk_slices(self.n_triangles):
                np.multiply(self.pma_vectors[:, z], q[z], out=b[:, z])
                np.multiply(self.pma_norms[z], q[z], out=bn[z])
            b.setflags(write=False)
            bn.setflags(write=False)
            self._cache["motion_area"] = (b, bn)
        return self._cache["motion_area"][0]

    def vector_norms(self, weighting: str = "pma") -> np.ndarray:
        """``|b_k|``, shape (K,), read-only."""
        if weighting == "pma":
            return self.pma_norms
        self.vectors(weighting)
        return self._cache[weighting][1]


def _check_weighting(weighting: str) -> None:
    if weighting not in WEIGHTINGS:
        raise ViewError(f"weighting must be one of {', '.join(WEIGHTINGS)}, got {weighting!r}")


def _weighting_of(method: str) -> str:
    """The triangle weighting a view method searches with.

    :class:`ViewMethod` is the suite's vocabulary for view methods; ``select_view``
    also keeps the weighting names (``"pma"``, ``"motion_area"``) it always took.
    Viewpoint entropy scores rendered bodies, not swept triangles, so it is refused
    here with a pointer to the function that computes it.
    """
    if method == ViewMethod.OURS:
        return "pma"
    if method == ViewMethod.VIEWPOINT_ENTROPY:
        raise ViewError(
            "viewpoint entropy scores a rendered body, not the motion's triangles: "
            "use snapcore.render.viewpoint_entropy.select_view_entropy"
        )
    _check_weighting(method)
    return str(method)


def _motion_sources(
    source: Scene | Character | np.ndarray | Sequence, links: np.ndarray | None
) -> list[tuple[np.ndarray, np.ndarray]]:
    """[(positions (F, J, 3), links (L, 2))] from a Scene, Character, array or list."""
    if hasattr(source, "characters"):
        return [(c.positions, c.skeleton.links) for c in source.characters]
    if hasattr(source, "skeleton"):
        return [(source.positions, source.skeleton.links)]  # type: ignore[union-attr]
    if isinstance(source, np.ndarray):
        if links is None:
            raise ViewError("links (L, 2) are required with a positions array")
        return [(source, links)]
    out = []
    for item in source:
        x, lk = item
        out.append((np.asarray(x, float), np.asarray(lk)))
    return out


def motion_triangles(
    source: Scene | Character | np.ndarray | Sequence,
    links: np.ndarray | None = None,
    *,
    frames: tuple[int, int] | None = None,
    floor: float = MA_FLOOR_M2,
) -> MotionTriangles:
    """Triangles swept by every link between consecutive frames (all characters).

    Parameters
    ----------
    source : Scene, Character, ndarray of shape (F, J, 3), or list of (positions, links)
        World joint positions in metres.
    links : ndarray of int, shape (L, 2), optional
        (parent, child) joint pairs; required when ``source`` is an array.
    frames : tuple of int, optional
        ``(start, stop)``: use frames ``start .. stop-1`` only (default: all).
    floor : float
        Noise floor on a quad's swept area, m² (:data:`MA_FLOOR_M2`).

    Returns
    -------
    MotionTriangles
        ``K = 2 · (frames - 1) · L`` triangles per character.
    """
    items = _motion_sources(source, links)
    n_total = items[0][0].shape[0]
    start, stop = (0, n_total) if frames is None else (int(frames[0]), int(frames[1]))
    if not (0 <= start < stop <= n_total):
        raise ViewError(
            f"frames must satisfy 0 <= start < stop <= {n_total}, got ({start}, {stop})"
        )
    steps = stop - start - 1
    sizes = [2 * steps * np.asarray(lk).reshape(-1, 2).shape[0] for _, lk in items]
    k_total = int(sum(sizes))
    b_pma = np.empty((3, k_total))
    n_pma = np.empty(k_total)
    quads = np.empty(k_total // 2)
    blocks, off = [], 0
    for ci, ((x, lk), size) in enumerate(zip(items, sizes)):
        lk = np.asarray(lk, dtype=np.intp).reshape(-1, 2)
        if x.shape[0] != n_total:
            raise ViewError(f"character {ci} has {x.shape[0]} frames, expected {n_total}")
        blocks.append((ci, off, steps, lk))
        xs = np.asarray(x[start:stop], float)
        # one compiled pass (the same doubles) when built, else NumPy's ~25 passes
        if size and not (
            kernels.compiled() and kernels.swept_block(xs, lk, floor, b_pma, n_pma, quads, off)
        ):
            _swept_block(
                xs,
                lk,
                floor,
                b_pma[:, off : off + size],
                n_pma[off : off + size],
                quads[off // 2 : (off + size) // 2],
            )
        off += size
    b_pma.setflags(write=False)
    n_pma.setflags(write=False)
    quads.setflags(write=False)  # n_quads is cached
    return MotionTriangles(
        pma_vectors=b_pma,
        pma_norms=n_pma,
        quads=quads,
        frames=(start, stop),
        blocks=blocks,
        floor=float(floor),
    )


def _swept_block(
    x: np.ndarray,
    links: np.ndarray,
    floor: float,
    b_pma: np.ndarray,
    n_pma: np.ndarray,
    quads: np.ndarray,
) -> None:
    """Fill one character's PMA vectors (3, K), their norms (K,) and quad areas (K/2,).

    Works on chunks of :data:`CHUNK` triangles so temporaries stay in cache (large
    fresh temporaries cost more in page faults than in arithmetic).
    """
    steps, n_links = x.shape[0] - 1, links.shape[0]
    pb4 = b_pma.reshape(3, 2, steps, n_links)  # views: (component, triangle, step, link)
    pn3 = n_pma.reshape(2, steps, n_links)
    q2 = quads.reshape(steps, n_links)
    xt = np.ascontiguousarray(x.transpose(2, 0, 1))  # (3, F, J): component-major
    cs = max(1, CHUNK // n_links)
    ch = links[:, 1]
    c0 = int(ch[0]) if n_links and np.array_equal(ch, np.arange(ch[0], ch[0] + n_links)) else None
    a = np.empty((3, 2, cs, n_links))
    nrm = np.empty((2, cs, n_links))
    for s0 in range(0, steps, cs):
        s1 = min(steps, s0 + cs)
        ac, nc = a[:, :, : s1 - s0], nrm[:, : s1 - s0]
        xc = xt[:, s0 : s1 + 1]
        p = np.take(xc, links[:, 0], axis=2)
        if c0 is None:
            e = np.take(xc, links[:, 1], axis=2)
            e -= p  # link vectors (3, frames, L)
        else:  # children in a run (BVH order): a slice, no gather
            e = np.subtract(xc[:, :, c0 : c0 + n_links], p)
        g = p[:, 1:] - p[:, :-1]  # parent displacement
        d = e[:, 1:] + g  # diagonal x_c(i+1) - x_j(i)
        # ac, nc and q2x are twice the areas: the ½ is applied once, to the quad areas
        # (scaling by powers of two is exact, so a/MA_orig is the same double)
        _cross_into(e[:, :-1], d, ac[:, 0])
        _cross_into(d, g, ac[:, 1])
        np.square(ac[0], out=nc)
        nc += np.square(ac[1])
        nc += np.square(ac[2])
        np.sqrt(nc, out=nc)
        q2x = nc[0] + nc[1]
        np.multiply(q2x, 0.5, out=q2[s0:s1])
        w = np.zeros_like(q2x)
        np.divide(1.0, q2x, out=w, where=q2x >= 2.0 * floor)
        np.multiply(ac, w, out=pb4[:, :, s0:s1])
        np.multiply(nc, w, out=pn3[:, s0:s1])


def _cross_into(u: np.ndarray, w: np.ndarray, out: np.ndarray) -> None:
    tmp = np.empty_like(out[0])
    for i, j, k in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):
        np.multiply(u[j], w[k], out=out[i])
        np.multiply(u[k], w[j], out=tmp)
        out[i] -= tmp


# -------------------------------------------------------------------- exact scores


def _as_views(views: ArrayLike) -> np.ndarray:
    v = np.asarray(views, dtype=float)
    if v.ndim == 1:
        v = v[None]
    if v.ndim != 2 or v.shape[1] != 3 or not np.all(np.isfinite(v)):
        raise ViewError(
            f"views must be a finite array of shape (n, 3), got shape {np.shape(views)}"
        )
    return v


@one_blas_thread
def pma_scores(
    views: ArrayLike, triangles: MotionTriangles, *, weighting: str = "pma"
) -> np.ndarray:
    """Exact score of every view: ``Σ_k |b_k · v|``.

    Parameters
    ----------
    views : ndarray of shape (V, 3) or (3,)
        Unit view directions (scores are linear in ``|v|``).
    triangles : MotionTriangles
    weighting : {"pma", "motion_area"}
        Projected Motion Area (eq. 10-11, dimensionless: the sum of the per-quad ratios
        ``MA_proj / MA_orig``) or Kwon & Lee's motion area (m²).

    Returns
    -------
    ndarray of shape (V,)

    Notes
    -----
    One matrix product per block of views × triangles (a reused buffer,
    :func:`snapcore.select.sphere.abs_dot_sums`); no loop over single views.
    ``score(v) = score(-v)``.
    """
    return abs_dot_sums(_as_views(views), triangles.vectors(weighting))


@one_blas_thread
def refine_view(
    view: ArrayLike,
    triangles: MotionTriangles,
    *,
    weighting: str = "pma",
    max_iter: int = REFINE_MAX_ITER,
) -> RefineResult:
    """Climb from ``view`` to a local maximum of ``Σ_k |b_k · v|``.

    Parameters
    ----------
    view : array_like of shape (3,)
        Start direction (normalised here; must be non-zero).
    triangles : MotionTriangles
    weighting : {"pma", "motion_area"}
    max_iter : int

    Returns
    -------
    RefineResult

    Notes
    -----
    With ``s_k = sign(b_k·v)`` and ``g = Σ_k s_k b_k``, the step ``v' = g/|g|`` gives
    ``score(v') ≥ g·v' = |g| ≥ g·v = score(v)``: the score never decreases, and the
    iteration stops at a fixed point of the sign pattern (a vertex of the zonotope
    ``Σ_k [-b_k, b_k]``, the L1-PCA optimality condition) after finitely many steps.
    """
    b = triangles.vectors(weighting)
    v = _as_views(view)[0]
    nv = float(np.linalg.norm(v))
    if nv == 0:
        raise ViewError("the start view must be non-zero")
    return refine_exact(v / nv, b, triangles.vector_norms(weighting), max_iter)[0]


# --------------------------------------------------------------------- selection


@dataclass
class ViewSelection:
    """The chosen view of a scene and how it was found.

    Attributes
    ----------
    view : ndarray of shape (3,)
        Unit vector from the scene centre to the camera (refined unless
        ``refine=False``), on the side chosen by :func:`snapcore.motion.facing.choose_side`.
    view_grid : ndarray of shape (3,)
        The best sample of the view sphere (same side rule).
    score, score_grid : float
        Exact scores of ``view`` and ``view_grid`` (PMA: sum of per-quad ratios;
        motion area: m²).
    method : str
        ``"pma"`` or ``"motion_area"``.
    views : ndarray of shape (V, 3)
        The sample sphere.
    scores : ndarray of shape (V,)
        Score of every sample: the binned lower bound (within ``CERT_SLACK``-level
        gaps of the exact score; exact where the certificate had to check a view).
        :func:`pma_scores` gives exact values.
    frames : tuple of int
        ``(start, stop)`` internal frames scored.
    window_s : float or None
        Half-width of the window in seconds (None: whole sequence).
    facing : ndarray of shape (3,)
        Mean horizontal facing over the frames (:func:`snapcore.motion.facing.scene_facing`).
    side_rule : str
        The rule that chose between ``±view`` (:data:`snapcore.motion.facing.SIDE_RULES`).
    n_quads, n_skipped : int
        Quads that voted / fell below the noise floor.
    iterations : int
        Exact fixed-point steps taken.
    certified : bool
        True when every sample's upper bound was at most ``score`` (so no sample of the
        sphere beats the returned view).
    """

    view: np.ndarray
    view_grid: np.ndarray
    score: float
    score_grid: float
    method: str
    views: np.ndarray
    scores: np.ndarray
    frames: tuple[int, int]
    window_s: float | None
    facing: np.ndarray
    side_rule: str
    n_quads: int
    n_skipped: int
    iterations: int = 0
    certified: bool = False

    @property
    def mean_ratio(self) -> float:
        """PMA divided by the number of quads: the mean fraction of swept area seen, in
        [0, 1] (clipped: a planar motion seen face-on gives 1 up to rounding)."""
        return min(1.0, self.score / max(self.n_quads, 1))

    @property
    def facing_note(self) -> str:
        """One line saying how front and back were told apart."""
        return {
            "above": "steep view: camera above the floor",
            "front": "camera on the side the characters face",
            "right side": "profile view: camera sees the characters' right side (they face screen-right)",
            "fallback": "no consistent facing, horizontal view: fixed fallback side",
        }[self.side_rule]

    def to_dict(self) -> dict:
        """JSON-ready summary (internal frames; callers convert with ``source_frame``)."""
        return {
            "method": self.method,
            "view": [float(x) for x in self.view],
            "view_grid": [float(x) for x in self.view_grid],
            "score": float(self.score),
            "score_grid": float(self.score_grid),
            "mean_ratio": float(self.mean_ratio),
            "frames": [int(self.frames[0]), int(self.frames[1])],
            "window_s": self.window_s,
            "facing": [float(x) for x in self.facing],
            "side_rule": self.side_rule,
            "facing_note": self.facing_note,
            "n_views": int(self.views.shape[0]),
            "n_quads": int(self.n_quads),
            "n_skipped": int(self.n_skipped),
            "iterations": int(self.iterations),
            "certified": bool(self.certified),
        }


def window_frames(
    scene: Scene, index: int | None = None, window_s: float | None = None
) -> tuple[int, int]:
    """Internal ``(start, stop)`` indices of the whole sequence or of ``index ± window_s``.

    Parameters
    ----------
    scene : Scene
    index : int, optional
        Internal index of the window's centre (``PoseSelection.index``; required with
        ``window_s``).
    window_s : float, optional
        Half-width in seconds; the window is clipped to the sequence and holds at least
        the frame and one neighbour.
    """
    n = scene.n_frames
    if window_s is None:
        return 0, n
    if index is None:
        raise ViewError("a window needs a frame: pass index= with window_s=")
    if not (np.isfinite(window_s) and window_s >= 0):
        raise ViewError(f"window_s must be a non-negative number of seconds, got {window_s}")
    f = int(index)
    if not 0 <= f < n:
        raise ViewError(f"index {f} is outside 0..{n - 1}")
    half = max(1, int(round(window_s * scene.fps)))
    return max(0, f - half), min(n, f + half + 1)


@one_blas_thread
def select_view(
    scene: Scene,
    *,
    index: int | None = None,
    window_s: float | None = None,
    method: str = "pma",
    n_views: int = 2562,
    refine: bool = True,
    floor: float = MA_FLOOR_M2,
    triangles: MotionTriangles | None = None,
) -> ViewSelection:
    """The view of a scene that maximises PMA (or the motion area).

    Parameters
    ----------
    scene : Scene
    index : int, optional
        Internal index of the window's centre (``Snapshot.index``, ``PoseSelection.index``:
        the source frame minus ``scene.frame_offset``; used only with ``window_s``).
    window_s : float, optional
        Score frames ``index ± window_s`` seconds (the pose-specific view); default the
        whole sequence (the global view, eq. 10).
    method : ViewMethod or {"pma", "motion_area"}
        ``ViewMethod.OURS`` (the same as ``"pma"``) or ``ViewMethod.MOTION_AREA``
        (``"motion_area"``); the returned ``method`` is the weighting name.
    n_views : int
        Samples of the view sphere (:func:`view_sphere`).
    refine : bool
        Refine the best samples exactly (fixed-point L1-PCA step).
    floor : float
        Noise floor on a quad's swept area, m².
    triangles : MotionTriangles, optional
        Precomputed for the same frames (shares work between methods).

    Returns
    -------
    ViewSelection

    Notes
    -----
    1. Triangle vectors ``b_k`` are folded to a hemisphere (``|b·v| = |-b·v|``) and summed
       in ~2° octahedral bins: ``A(v) = Σ_bins |G_j·v| ≤ score(v)`` (triangle inequality),
       equal except for bins the plane ⟂ v cuts, whose gap is bounded
       (``_straddle_factors``). ``A`` over the samples is one (V/2 × B) product.
    2. The best local maxima of ``A`` are refined on the bins, the best distinct results
       exactly on the triangles (:func:`refine_view`).
    3. Certificate: every sample whose upper bound exceeds the answer is scored exactly
       and refined from if it is better, so the answer is never below any sample.
    A clip without motion above the floor returns the facing direction (or +Z) with a
    warning and score 0.

    Examples
    --------
    A person walking along +Z sweeps the largest area seen from the side (±X):

    >>> import numpy as np
    >>> from snapcore import select_view
    >>> from snapcore.motion.synth import synth_scene
    >>> sel = select_view(synth_scene("walk"))
    >>> sel.method, bool(abs(sel.view[0]) > 0.9), round(float(np.linalg.norm(sel.view)), 6)
    ('pma', True, 1.0)
    """
    method = _weighting_of(method)
    frames = window_frames(scene, index, window_s)
    if triangles is None:
        triangles = motion_triangles(scene, frames=frames, floor=floor)
    elif tuple(triangles.frames) != tuple(frames):
        raise ViewError(f"triangles cover frames {triangles.frames}, the request {frames}")
    facing = scene_facing(scene, frames=frames)
    views = view_sphere(n_views)
    n = views.shape[0]
    base: dict[str, Any] = dict(
        method=method,
        views=np.array(views),
        frames=frames,
        window_s=window_s,
        facing=facing,
        n_quads=triangles.n_quads,
        n_skipped=triangles.n_skipped,
    )
    if triangles.n_quads == 0:
        warnings.warn(
            f"no link moves more than the noise floor ({triangles.floor:g} m²) in frames "
            f"{frames[0]}..{frames[1] - 1}: the view defaults to the facing direction",
            stacklevel=2,
        )
        nf = np.linalg.norm(facing)
        v = facing / nf if nf > 0 else np.array([0.0, 0.0, 1.0])
        return ViewSelection(
            view=v,
            view_grid=v.copy(),
            score=0.0,
            score_grid=0.0,
            scores=np.zeros(n),
            side_rule="front" if nf > 0 else "fallback",
            **base,
        )
    found = sphere_search(
        triangles.vectors(method), triangles.vector_norms(method), n, refine=refine
    )
    best_v, grid_view = found.view, views[found.grid_index]
    view, rule = choose_side(best_v, facing)
    view_grid, _ = choose_side(grid_view, facing)
    return ViewSelection(
        view=np.array(view),
        view_grid=np.array(view_grid),
        score=found.score,
        score_grid=found.score_grid,
        scores=found.scores,
        side_rule=rule,
        iterations=found.iterations,
        certified=found.certified,
        **base,
    )


# --------------------------------------------------------------- snapshot stage


def view_angles_deg(directions: dict) -> dict:
    """Angle between every pair of view directions, in degrees.

    Parameters
    ----------
    directions : dict of str to array of shape (3,)
        View directions by name (e.g. method), not necessarily unit length.

    Returns
    -------
    dict of str to float
        ``{"a|b": angle}`` for each pair in the dict's order, in [0, 180].
    """
    names = list(directions)
    unit = {}
    for n in names:
        v = np.asarray(directions[n], dtype=float).reshape(3)
        norm = np.linalg.norm(v)
        if not norm > 0:
            raise ViewError(f"directions[{n!r}] is a zero vector")
        unit[n] = v / norm
    out = {}
    for i, a in enumerate(names):
        for b in names[i + 1 :]:
            c = float(np.clip(unit[a] @ unit[b], -1.0, 1.0))
            out[f"{a}|{b}"] = float(np.degrees(np.arccos(c)))
    return out


def near_duplicate_views(angles: dict, threshold_deg: float) -> list[tuple[str, str]]:
    """Pairs of views that show nearly the same picture.

    Two orthographic views closer than ``threshold_deg`` look alike, and so do two
    nearly opposite ones (over ``180 - threshold_deg``): the second is close to the
    first's mirror image, with the same silhouette.

    Parameters
    ----------
    angles : dict of str to float
        :func:`view_angles_deg` output (degrees).
    threshold_deg : float
        In [0, 90].

    Returns
    -------
    list of (str, str)
        The pairs, in the order of ``angles``.
    """
    if not 0 <= threshold_deg <= 90:
        raise ViewError(f"threshold_deg must be in [0, 90], got {threshold_deg}")
    return [
        tuple(k.split("|", 1))
        for k, a in angles.items()
        if a < threshold_deg or a > 180.0 - threshold_deg
    ]
