"""Fast, certified maximisation of ``Σ_k |b_k · v|`` over view directions.

The numeric engine behind :func:`snapcore.select.view.select_view` (PMA and motion area are
both this sum, for different vectors ``b_k``). Pure functions over arrays:

- the sample sphere (icosphere or Fibonacci, antipodally symmetric) and its neighbours;
- the exact evaluator (:func:`abs_dot_sums`, blocks of views × vectors);
- the fixed-point ascent ``v ← normalise(Σ_k sign(b_k·v) b_k)`` tracked on the vectors
  near the plane ⟂ v only (:class:`LocalScores`, :func:`refine_exact`);
- a lower bound over all samples from ~2° octahedral bins of the folded vectors, with a
  per-sample upper bound on its gap (:func:`sphere_search`), so the search can certify
  that no sample beats its answer.

Everything here works on chunks of :data:`CHUNK` vectors: fresh multi-megabyte
temporaries cost more in page faults than in arithmetic on this kind of machine.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import ParamSpec, TypeVar

import numpy as np
from threadpoolctl import ThreadpoolController

from snapcore.select import kernels

__all__ = [
    "ICOSPHERE_COUNTS",
    "RefineResult",
    "SearchResult",
    "LocalScores",
    "abs_dot_sums",
    "refine_exact",
    "sphere_samples",
    "sphere_search",
    "one_blas_thread",
    "chunk_slices",
]

#: Icosphere vertex counts (10·4^k + 2) → subdivision level. Other counts give an
#: antipodally symmetric Fibonacci set.
ICOSPHERE_COUNTS = {10 * 4**k + 2: k for k in range(8)}
#: Octahedral bins per side of the hemisphere map of triangle normals (R² bins, each
#: ~2° across): the fast lower bound over the sample sphere.
BIN_RESOLUTION = 48
#: Local maxima of the binned score refined from (distinct basins of the sphere).
N_STARTS = 6
#: Best distinct binned optima refined exactly on the triangles (the best always;
#: the others only when their binned score is within the bound's gap of the best).
N_POLISH = 3
#: Cap on fixed-point iterations (each one never lowers the score; convergence is
#: reached when the sign pattern repeats, typically in < 10 steps).
REFINE_MAX_ITER = 100
#: Sines of the angles around the current view within which the exact refinement
#: tracks signs on the near triangles only (a few percent of them), nested: the outer
#: window (8.6°) needs a full pass and also serves the certificate (it covers the
#: sample sphere's neighbours of the answer); the inner one (2.3°) is re-derived from
#: the outer one's triangles when the view leaves it.
OUTER_WINDOW = 0.15
REFINE_WINDOW = 0.04
#: Two refined views closer than this (degrees, up to sign) are the same optimum.
SAME_VIEW_DEG = 0.5
#: Rounds of the certificate (each scores the flagged samples exactly and climbs from
#: the best one if it beats the answer; one round suffices in practice).
CERT_ROUNDS = 5
#: Relative slack of the certificate (covers float32 rounding of the binned bound).
CERT_SLACK = 1e-5
#: Views × triangles per block of the exact evaluator (one reused buffer, 2 MB:
#: ~0.65 ns per view and triangle on one core).
SCORE_BLOCK = (16, 16384)
#: Triangles per chunk of the element-wise kernels: temporaries of this size stay in
#: cache and are recycled (fresh multi-MB temporaries cost more in page faults than
#: the arithmetic; measured 3x on the salsa pair).
CHUNK = 32768

#: float32 products per block of the grid bound (512 KB: in cache; fewer NumPy calls
#: than :data:`CHUNK`, 1.28 -> 1.06 ms on the salsa pair, the same sums row by row).
GRID_BLOCK = 131072

_BLAS = None
_P = ParamSpec("_P")
_R = TypeVar("_R")


def one_blas_thread(func: Callable[_P, _R]) -> Callable[_P, _R]:
    """Run ``func`` with one BLAS thread: its products are small (inner dimension 3),
    and multi-threaded OpenBLAS made them ~20x slower on a busy 2-core machine."""

    @functools.wraps(func)
    def wrapper(*args: _P.args, **kwargs: _P.kwargs) -> _R:
        global _BLAS
        if _BLAS is None:  # built on first use: it inspects the loaded BLAS libraries
            _BLAS = ThreadpoolController()
        with _BLAS.limit(limits=1, user_api="blas"):
            return func(*args, **kwargs)

    return wrapper


# ----------------------------------------------------------------------- sphere


#: trimesh's icosphere vertices for 0..4 subdivisions (12..2562 points), stored bit for
#: bit (tests/test_sphere_views.py compares them with trimesh): importing trimesh costs
#: ~0.6 s (networkx, scipy.spatial), which ``snapshot select`` paid for this sphere alone.
_ICOSPHERE_FILE = Path(__file__).with_name("icosphere_vertices.npz")


def _icosphere_vertices(subdivisions: int) -> np.ndarray:
    """Vertices (n, 3) of ``trimesh.creation.icosphere(subdivisions)``, unit radius.

    From :data:`_ICOSPHERE_FILE` up to 4 subdivisions, else from trimesh (imported only
    then). Its vertices agree to 3e-16 with a hand-written subdivision of the same
    icosahedron, but not bit for bit, and their order decides ties between views.
    """
    key = f"subdivisions_{int(subdivisions)}"
    with np.load(_ICOSPHERE_FILE) as stored:
        if key in stored.files:
            return np.array(stored[key], dtype=np.float64)
    import trimesh

    return np.asarray(trimesh.creation.icosphere(subdivisions=int(subdivisions)).vertices)


@lru_cache(maxsize=8)
def _sphere(n: int) -> np.ndarray:
    """Unit views, shape (n, 3), read-only; rows n/2.. are the antipodes of rows ..n/2."""
    if n in ICOSPHERE_COUNTS:
        v = _icosphere_vertices(ICOSPHERE_COUNTS[n])
        tol = 1e-9
        upper = (v[:, 1] > tol) | (
            (np.abs(v[:, 1]) <= tol)
            & ((v[:, 2] > tol) | ((np.abs(v[:, 2]) <= tol) & (v[:, 0] > 0)))
        )
        half = v[upper]
        if half.shape[0] != n // 2:  # pragma: no cover - the icosphere is centrally symmetric
            raise RuntimeError(f"icosphere of {n} points is not antipodally symmetric")
    else:
        m = n // 2
        i = np.arange(m) + 0.5
        y = i / m  # the upper hemisphere, (0, 1)
        r = np.sqrt(1.0 - y * y)
        phi = np.arange(m) * math.pi * (3.0 - math.sqrt(5.0))  # golden angle
        half = np.stack([r * np.sin(phi), y, r * np.cos(phi)], axis=1)
    out = np.concatenate([half, -half])
    out.setflags(write=False)
    return out


def sphere_samples(n: int) -> np.ndarray:
    """The cached, read-only sample sphere of ``n`` views (see ``snapcore.select.view.view_sphere``)."""
    return _sphere(int(n))


@lru_cache(maxsize=8)
def _neighbours(n: int) -> np.ndarray:
    """Indices of the 6 nearest other views of every view, shape (n, 6).

    Stored in :data:`_ICOSPHERE_FILE` for the icosphere counts up to 2,562 (computing
    them for 2,562 views is ~2,600 × 2,600 dot products and a partition: ~50 ms of
    every ``snapshot select`` and ``render``), equal to :func:`_nearest_six`'s, which
    computes any other count.
    """
    with np.load(_ICOSPHERE_FILE) as stored:
        if f"neighbours_{n}" in stored.files:
            return np.array(stored[f"neighbours_{n}"], dtype=np.intp)
    return _nearest_six(n)


def _nearest_six(n: int) -> np.ndarray:
    """:func:`_neighbours` computed: per block of 256 views, the 6 largest dot products
    with the other views (``np.argpartition``: their order within the 6 is its own)."""
    v = _sphere(n)
    out = np.empty((n, 6), dtype=np.intp)
    for i in range(0, n, 256):
        d = v[i : i + 256] @ v.T
        d[np.arange(d.shape[0]), np.arange(i, i + d.shape[0])] = -np.inf  # not itself
        out[i : i + 256] = np.argpartition(-d, 6, axis=1)[:, :6]
    return out


def chunk_slices(n: int, size: int = CHUNK):
    """Slices covering ``range(n)`` in steps of ``size``."""
    return [slice(i, min(n, i + size)) for i in range(0, n, size)]


# ------------------------------------------------------------------ exact scores


def abs_dot_sums(views, b) -> np.ndarray:
    """``Σ_k |b_k · v|`` for every view: views (V, 3), b (3, K) → (V,).

    One matrix product per block of views × vectors (:data:`SCORE_BLOCK`, a reused
    buffer); no loop over single views.
    """
    out = np.zeros(views.shape[0])
    rows, cols = SCORE_BLOCK
    buf = np.empty(SCORE_BLOCK)
    for i in range(0, views.shape[0], rows):
        vi = views[i : i + rows]
        for z in chunk_slices(b.shape[1], cols):
            blk = buf[: vi.shape[0], : z.stop - z.start]
            np.matmul(vi, b[:, z], out=blk)
            np.abs(blk, out=blk)
            out[i : i + rows] += blk.sum(axis=1)
    return out


@dataclass(frozen=True)
class RefineResult:
    """Outcome of :func:`refine_view`: the view (unit), its exact score, the number of
    fixed-point steps, and whether the sign pattern repeated (a true fixed point)."""

    view: np.ndarray
    score: float
    iterations: int
    converged: bool


class LocalScores:
    """Exact scores near a centre view ``v0``, from the triangles near its ⟂ plane.

    A triangle with ``|n_k·v0| ≥ sin θ`` keeps its sign for every ``u`` within θ of
    ``v0``, so there ``score(u) = g_out·u + Σ_{k near} |b_k·u|`` with ``g_out`` the signed
    sum of the others: one pass builds it, then each evaluation touches only the near
    triangles (a few percent of them). Built from a ``parent`` it passes over the
    parent's near triangles only, and covers what both windows cover.
    """

    def __init__(self, v0, b, bn, sin_t, parent=None, bins=None):
        self.v0 = v0
        self.cos_t = math.sqrt(1.0 - sin_t * sin_t)
        self.parent = parent
        if parent is None and bins is not None:
            self._from_bins(v0, b, bn, sin_t, bins)
            return
        if parent is None:
            g = np.zeros(3)
        else:
            b, bn, g = parent.bc, parent.bcn, parent.g_out.copy()
        near = []
        for z in chunk_slices(b.shape[1]):
            t = v0 @ b[:, z]
            g += b[:, z] @ np.sign(t)
            np.abs(t, out=t)
            near.append(np.flatnonzero(t < sin_t * bn[z]) + z.start)
        idx = np.concatenate(near) if near else np.zeros(0, dtype=np.intp)
        self.bc, self.bcn = np.take(b, idx, axis=1), np.take(bn, idx)
        self.g_out = g - self.bc @ np.sign(v0 @ self.bc)
        self.score0 = float(g @ v0)  # Σ_k sign(b_k·v0) b_k·v0 = Σ_k |b_k·v0|

    def _from_bins(self, v0, b, bn, sin_t, bins) -> None:
        """The full pass replaced by the bins (a :class:`Bins`).

        Every member of bin j lies within ``r_j`` of its centre ``c_j``, so when the
        centre is at least ``θ + r_j`` from the plane ⟂ v0, all members keep the sign of
        ``c_j·v0`` over the window and the bin's signed sum is ``sign(c_j·v0) G_j`` (the
        fold does not change ``b_k sign(b_k·v0)``). Only the members of the other bins
        are gathered and tracked: a superset of the near vectors (the extra ones are
        tracked exactly too), found by a table look-up instead of a product per vector.
        """
        c = bins.centres @ v0
        alpha = np.arcsin(np.minimum(np.abs(c), 1.0))
        far = alpha >= math.asin(sin_t) + bins.radius
        if kernels.compiled():  # a count and a gather instead of four passes
            self.bc, self.bcn = kernels.near_columns(bins.index, ~far, b, bn)
        else:
            sel = np.flatnonzero(np.take(~far, bins.index))
            self.bc, self.bcn = np.take(b, sel, axis=1), np.take(bn, sel)
        self.g_out = np.sign(c[far]) @ bins.gen[far]
        self.score0 = float(self.g_out @ v0 + np.abs(v0 @ self.bc).sum())

    def covers(self, u) -> np.ndarray:
        """Whether ``u`` (3,) or (m, 3) lies strictly within the window(s)."""
        ok = u @ self.v0 > self.cos_t
        return ok if self.parent is None else ok & self.parent.covers(u)

    def scores(self, u) -> np.ndarray:
        """Exact scores of views ``u`` (m, 3) that :meth:`covers` accepts."""
        # in blocks with a reused buffer: a fresh (m, near) product is megabytes
        return u @ self.g_out + abs_dot_sums(u, self.bc)


def refine_exact(v, b, bn, max_iter, outer=None, bins=None):
    """Fixed-point ascent from unit ``v`` → (RefineResult, outer LocalScores around the end).

    Signs are tracked on the triangles of a small window (:data:`REFINE_WINDOW`) inside
    a larger one (:data:`OUTER_WINDOW`); each is re-centred when the view leaves it.
    ``bins`` (a :class:`Bins` of ``b``) lets the outer window skip the full pass.
    """
    if outer is None or not outer.covers(v):
        outer = LocalScores(v, b, bn, OUTER_WINDOW, bins=bins)
    loc = LocalScores(v, b, bn, REFINE_WINDOW, parent=outer)
    t = v @ loc.bc
    s = np.sign(t)
    score = float(loc.g_out @ v + np.abs(t).sum())
    it = 0
    converged = False
    while it < max_iter:
        g = loc.g_out + loc.bc @ s
        ng = float(np.linalg.norm(g))
        if ng == 0.0:
            converged = True
            break
        v_new = g / ng
        same_loc = bool(loc.covers(v_new))
        if not same_loc:  # moved out of the window: re-centre
            if not outer.covers(v_new):
                outer = LocalScores(v_new, b, bn, OUTER_WINDOW, bins=bins)
            loc = LocalScores(v_new, b, bn, REFINE_WINDOW, parent=outer)
        t = v_new @ loc.bc
        s_new = np.sign(t)
        score_new = float(loc.g_out @ v_new + np.abs(t).sum())
        it += 1
        if score_new < score:  # float rounding only (the step cannot lower the score)
            converged = True
            break
        repeat = same_loc and np.array_equal(s_new, s)
        v, s, score = v_new, s_new, score_new
        if repeat:
            converged = True
            break
    if not outer.covers(v):
        outer = LocalScores(v, b, bn, OUTER_WINDOW, bins=bins)
    return RefineResult(view=v, score=score, iterations=it, converged=converged), outer


# ------------------------------------------------- binned bound over the sphere


@lru_cache(maxsize=4)
def _bin_geometry(res: int):
    """Centres (B, 3) and angular radii (B,) of the octahedral hemisphere bins."""
    edges = np.linspace(-1.0, 1.0, res + 1)
    mids = 0.5 * (edges[1:] + edges[:-1])

    def unmap(s, t):
        px, pz = 0.5 * (s - t), 0.5 * (s + t)
        d = np.stack([px, 1.0 - np.abs(px) - np.abs(pz), pz], axis=-1)
        return d / np.linalg.norm(d, axis=-1, keepdims=True)

    si, ti = np.meshgrid(mids, mids, indexing="ij")
    centres = unmap(si, ti).reshape(-1, 3)
    # A cell's pieces (split by the octant kinks along its corners' diagonals) are
    # spherical triangles whose farthest point from the centre is a corner.
    radius = np.zeros(res * res)
    for di in (0, 1):
        for dj in (0, 1):
            sc, tc = np.meshgrid(edges[di : res + di], edges[dj : res + dj], indexing="ij")
            cos = np.einsum("ij,ij->i", centres, unmap(sc, tc).reshape(-1, 3))
            radius = np.maximum(radius, np.arccos(np.clip(cos, -1.0, 1.0)))
    radius += 1e-9  # rounding of the bin index at cell borders
    return centres, radius


@lru_cache(maxsize=4)
def _straddle_factors(n: int, res: int):
    """Bound factors (rows, cols, values) of the bins a view's ⟂ plane may cut.

    For bin j with radius r and centre at angle α from the plane ⟂ v (α < r), the gap
    between ``Σ_k |b_k·v|`` and ``|Σ_k b_k·v|`` over the bin is twice the minority
    side's sum, at most ``W_j min(2 sin(r - α), sin(r + α))`` (``W_j = Σ_k |b_k|``).
    """
    centres, radius = _bin_geometry(res)
    half = _sphere(n)[: n // 2]
    rows, cols, vals = [], [], []
    for i in range(0, half.shape[0], 128):
        alpha = np.arcsin(np.clip(np.abs(half[i : i + 128] @ centres.T), 0.0, 1.0))
        r_i, c_i = np.nonzero(alpha < radius)
        a, r = alpha[r_i, c_i], radius[c_i]
        rows.append(r_i + i)
        cols.append(c_i)
        vals.append(np.minimum(2.0 * np.sin(r - a), np.sin(np.minimum(r + a, np.pi / 2))))
    return np.concatenate(rows), np.concatenate(cols), np.concatenate(vals)


def _gap_bound(n: int, res: int, weight) -> np.ndarray:
    """Upper bound of ``score - lower`` for each of the n/2 sample views, shape (n/2,)."""
    rows, cols, vals = _straddle_factors(n, res)
    first = _row_starts(n, res)
    out = np.zeros(n // 2)
    if first.size:  # rows are sorted: per-row sums of contiguous runs (3x bincount's speed)
        out[rows[first]] = np.add.reduceat(vals * np.take(weight, cols), first)
    return out


@lru_cache(maxsize=4)
def _row_starts(n: int, res: int):
    """Where each row's run starts in :func:`_straddle_factors` (its rows are sorted)."""
    rows = _straddle_factors(n, res)[0]
    if not rows.size:
        return rows
    return np.flatnonzero(np.r_[True, rows[1:] != rows[:-1]])


@dataclass(frozen=True)
class Bins:
    """The octahedral bins of the folded vectors (:func:`_bin_generators`).

    ``gen`` (B, 3): per-bin sums of the folded vectors; ``index`` (K,) int32: each
    vector's bin; ``centres`` (B, 3) and ``radius`` (B,, radians): every member of bin j
    is within ``radius[j]`` of ``centres[j]`` (folded).
    """

    gen: np.ndarray
    index: np.ndarray
    centres: np.ndarray
    radius: np.ndarray


def _bin_generators(b, res, index=None):
    """Fold ``b`` (3, K) onto y ≥ 0 and sum it per octahedral bin → G (B, 3), W (B,).

    The bin of a folded unit normal ``n`` is its octahedral map
    ``(s, t) = ((n_x + n_z), (n_z - n_x)) / (|n_x| + n_y + |n_z|)`` in [-1, 1]² on an
    ``res × res`` grid. ``W_j ≥ Σ_k |b_k|`` over bin j (for the certificate's gap bound)
    is ``G_j·c_j / cos r_j``: every member is within the bin radius ``r_j`` of its centre
    ``c_j``, so ``b_k·c_j ≥ |b_k| cos r_j``. ``index`` (K,) int32, if given, receives
    each vector's bin.
    """
    gen = np.zeros((res * res, 3))
    if index is None:
        index = np.empty(b.shape[1], np.int32)
    if kernels.compiled():  # one pass instead of ~20, the same sums in the same order
        kernels.bin_vectors(b, res, CHUNK, index, gen)
    else:
        _bin_sums(b, res, index, gen)
    centres, radius = _bin_geometry(res)
    weight = np.maximum(np.einsum("ij,ij->i", gen, centres), 0.0) / np.cos(radius)
    return gen, weight


def _bin_sums(b, res, index, gen) -> None:
    """:func:`_bin_generators`' pass in NumPy (the reference of
    ``kernels.bin_vectors``): each vector's bin to ``index`` (K,), the folded vectors
    added per bin to ``gen`` (res², 3), per chunk of :data:`CHUNK` vectors."""
    nb = res * res
    # (1 - 1e-9) keeps (s + 1)·h below res, so no index needs clipping
    h, h_in = res / 2.0, res / 2.0 * (1.0 - 1e-9)
    for z in chunk_slices(b.shape[1]):
        bx, by, bz = b[:, z]
        sg = np.copysign(1.0, by)
        fx, fy, fz = bx * sg, np.abs(by), bz * sg
        den = np.abs(fx)
        den += fy
        den += np.abs(fz)
        den += 1e-300  # zero vectors (skipped quads) add nothing to any bin
        np.divide(h_in, den, out=den)
        i = fx + fz
        i *= den
        i += h
        j = fz - fx
        j *= den
        j += h
        idx = i.astype(np.intp)
        idx *= res
        idx += j.astype(np.intp)
        index[z] = idx
        gen[:, 0] += np.bincount(idx, fx, nb)
        gen[:, 1] += np.bincount(idx, fy, nb)
        gen[:, 2] += np.bincount(idx, fz, nb)


def _grid_lower(views, gen):
    """``Σ_j |G_j·v|`` for every view (float32, in blocks that stay in cache)."""
    g32 = np.ascontiguousarray(gen.T, dtype=np.float32)
    v32 = views.astype(np.float32)
    out = np.empty(views.shape[0])
    rows = max(1, GRID_BLOCK // max(g32.shape[1], 1))
    buf = np.empty((rows, g32.shape[1]), np.float32)
    for i in range(0, v32.shape[0], rows):
        blk = buf[: min(rows, v32.shape[0] - i)]
        np.matmul(v32[i : i + rows], g32, out=blk)
        np.abs(blk, out=blk)
        out[i : i + rows] = blk.sum(axis=1)
    return out


def _refine_binned(starts, gen, max_iter=REFINE_MAX_ITER):
    """Fixed-point ascent of ``Σ_j |G_j·v|`` from every start at once → views, scores."""
    v = starts.copy()
    for _ in range(max_iter):
        g = np.sign(v @ gen.T) @ gen
        g /= np.maximum(np.linalg.norm(g, axis=1, keepdims=True), 1e-300)
        if np.allclose(g, v, rtol=0, atol=1e-13):
            break
        v = g
    return v, np.abs(v @ gen.T).sum(axis=1)


@dataclass
class SearchResult:
    """Outcome of :func:`sphere_search`.

    Attributes
    ----------
    view : ndarray of shape (3,)
        The best view found (sign arbitrary: the score is even).
    score : float
        Its exact score.
    grid_index : int
        Row of the best sample (of the upper half of the sphere).
    score_grid : float
        That sample's exact score.
    scores : ndarray of shape (n,)
        Per sample: the binned lower bound, or the exact score where the certificate
        computed it.
    iterations : int
        Exact fixed-point steps taken.
    certified : bool
        True when no sample's upper bound exceeds ``score``.
    """

    view: np.ndarray
    score: float
    grid_index: int
    score_grid: float
    scores: np.ndarray
    iterations: int
    certified: bool


@one_blas_thread
def sphere_search(b, bn, n: int, *, refine: bool = True) -> SearchResult:
    """Maximise ``Σ_k |b_k · v|`` over the ``n``-sample sphere, then refine exactly.

    Parameters
    ----------
    b : ndarray of shape (3, K)
        The vectors (zero vectors allowed; at least one non-zero).
    bn : ndarray of shape (K,)
        Their norms.
    n : int
        Sample count of the sphere (:func:`sphere_samples`).
    refine : bool
        Climb from the best samples with the exact fixed-point step.

    Returns
    -------
    SearchResult

    Notes
    -----
    1. The vectors are folded to a hemisphere (``|b·v| = |-b·v|``) and summed in ~2°
       octahedral bins: ``A(v) = Σ_bins |G_j·v| ≤ score(v)`` (triangle inequality),
       equal except for bins the plane ⟂ v cuts, whose gap is bounded
       (:func:`_straddle_factors`). ``A`` over the samples is one (n/2 × B) product.
    2. The best local maxima of ``A`` are refined on the bins, the best distinct results
       exactly on the vectors (:func:`refine_exact`).
    3. Certificate: every sample whose upper bound exceeds the answer is scored exactly
       (near the answer on the near vectors only) and climbed from if it is better, so
       the answer is never below any sample.
    """
    views = _sphere(n)
    m = n // 2
    half = views[:m]
    index = np.empty(b.shape[1], dtype=np.int32)
    gen, weight = _bin_generators(b, BIN_RESOLUTION, index)
    bins = Bins(gen, index, *_bin_geometry(BIN_RESOLUTION))
    gen_k = gen[weight > 0]
    lower = _grid_lower(half, gen_k)
    upper = lower + _gap_bound(n, BIN_RESOLUTION, weight) + CERT_SLACK * weight.sum()
    scores = np.concatenate([lower, lower])

    best_v, iters = half[int(np.argmax(lower))], 0
    if refine:
        # local maxima of the bound on the whole sphere, best first (rows of the half)
        is_max = scores >= scores[_neighbours(n)].max(axis=1)
        cand = np.flatnonzero(is_max[:m])
        cand = cand[np.argsort(-lower[cand])][:N_STARTS]
        rv, rs = _refine_binned(half[cand], gen_k)
        picked: list[np.ndarray] = []
        cos_same = math.cos(math.radians(SAME_VIEW_DEG))
        rs_picked = []
        for i in np.argsort(-rs):
            if all(abs(float(rv[i] @ p)) < cos_same for p in picked):
                picked.append(rv[i])
                rs_picked.append(float(rs[i]))
        gap_max = float((upper - lower).max())
        best_s, loc = -1.0, None
        for i, v0 in enumerate(picked[:N_POLISH]):
            if i and rs_picked[i] + gap_max < rs_picked[0]:
                break  # no point of this basin can beat the first one's binned optimum
            r, loc_i = refine_exact(v0, b, bn, REFINE_MAX_ITER, bins=bins)
            iters += r.iterations
            if r.score > best_s:
                best_v, best_s, loc = r.view, r.score, loc_i
        if loc is None:  # the bound's best sample is a local maximum: never empty
            raise RuntimeError("internal: no local maximum of the view score was refined")
    else:
        loc = LocalScores(best_v, b, bn, OUTER_WINDOW, bins=bins)
        best_s = loc.score0
    # certificate: score exactly every sample whose upper bound beats the answer
    exact = np.zeros(m, dtype=bool)
    certified = False
    for _ in range(CERT_ROUNDS):
        flagged = np.flatnonzero((upper > best_s) & ~exact)
        if flagged.size == 0:
            certified = True
            break
        u = half[flagged] * np.where(half[flagged] @ best_v < 0, -1.0, 1.0)[:, None]
        near = loc.covers(u)
        ex = np.empty(flagged.size)
        ex[near] = loc.scores(u[near])
        ex[~near] = abs_dot_sums(u[~near], b)
        scores[flagged] = scores[flagged + m] = upper[flagged] = ex
        exact[flagged] = True
        k = int(np.argmax(ex))
        if ex[k] <= best_s * (1.0 + 1e-12):
            certified = True
            break
        if refine:
            r, loc = refine_exact(half[flagged[k]], b, bn, REFINE_MAX_ITER, bins=bins)
            iters += r.iterations
            best_v, best_s = r.view, r.score
        else:
            best_v, best_s = half[flagged[k]], float(ex[k])
            loc = LocalScores(best_v, b, bn, OUTER_WINDOW, bins=bins)
    i_grid = int(np.argmax(scores[:m]))
    grid_view = half[i_grid]
    if exact[i_grid]:
        score_grid = float(scores[i_grid])
    else:
        score_grid = float(abs_dot_sums(grid_view[None], b)[0])
    return SearchResult(
        view=best_v,
        score=best_s,
        grid_index=i_grid,
        score_grid=score_grid,
        scores=scores,
        iterations=iters,
        certified=certified,
    )
