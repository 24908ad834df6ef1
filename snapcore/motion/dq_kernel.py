"""Dual-quaternion skinning as sparse array work: the kernel behind
:func:`snapcore.motion.skinning.dq_skin`.

Dual-quaternion blending (Kavan et al. 2008) normalises each vertex's blended dual
quaternion ``b = Σ_k a_k d_k`` (``a_k = w_k s_k``, ``s_k = ±1`` putting bone ``k``'s
quaternion in the hemisphere of the vertex's heaviest bone, its *pivot*) and moves the
vertex by the rigid motion ``b / |b_0|``. Its moved point is a ratio of two quadratic
forms of ``b``::

    x' = N(b) [x; 1] / |b_0|²,   N(b) = [ R(b_0) | t(b) ]  (3 × 4)

with ``R(q) = (w² - v·v) I + 2 v vᵀ + 2 w [v]×`` (a rotation matrix times ``|q|²``) and
``t(b) = 2 (w v_ε - w_ε v + v × v_ε)`` for ``b = (w, v; w_ε, v_ε)``. Both are quadratic,
so with the symmetric bilinear forms ``N(d_k, d_l)`` and ``c(d_k, d_l) = q_k · q_l``::

    N(b) = Σ_k w_k² T_k + Σ_{k<l} 2 w_k w_l s_k s_l N(d_k, d_l)
    |b_0|² = Σ_k w_k² + Σ_{k<l} 2 w_k w_l s_k s_l c(d_k, d_l)

where ``T_k = N(d_k, d_k)`` is bone ``k``'s rigid transform. The sums run over *pair
keys* ``(k, l, pivot)`` that many vertices share (a body of 13,380 vertices has a few
hundred), each with a (3 × 4) matrix and a scalar per frame computed once. Per vertex
and frame, the blend is then what linear blend skinning does: one sparse product of
per-vertex coefficients ``w_k w_l`` with the keys' matrices, one matrix-vector product
and a division — exact algebra, no approximation. A vertex on one bone with weight 1
moves by its bone's matrix ``M_k`` alone (the rigid part and the rest agree there), so
it needs no dual quaternion at all: on a body that is most vertices.

The signs ``s_k s_l`` depend only on the quaternions and the pivot: for a pair holding
the pivot it is ``sign(q_k · q_l)`` (the key drops the pivot), otherwise
``sign(q_k · q_p) sign(q_l · q_p)``.
"""

from __future__ import annotations

import hashlib
import threading
from collections import OrderedDict
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from scipy import sparse

__all__ = [
    "DQPlan",
    "dq_plan",
    "dq_skin_planned",
    "polar_rotation",
    "KERNEL_FRAMES",
    "KERNEL_CHUNK_BYTES",
]

#: Frames per sparse product: its inner loop runs over 3 × this many columns (SciPy's
#: products ran at 6.8 GFMA/s with 57 columns, 9.5-9.7 with 192-384; the whole skin
#: case 3-5% faster with 128 frames than with 64).
KERNEL_FRAMES = 128
#: Memory budget (bytes) of one block of skinned vertices (rows × frames × 3 of the
#: dtype): the products' output stays in cache for the transposing copy into the
#: (F, V, 3) layout, so the mesh's rows are taken in blocks (1.5 MB: 1,024 vertices
#: of 128 frames in float32; 1-2 MB measured alike).
KERNEL_CHUNK_BYTES = 3 * 2**19
#: Output columns (vertex coordinates) per strip of the transposing copy.
TRANSPOSE_STRIP = 2048
#: A vertex whose one weight is within this of 1 moves by its bone's matrix alone.
ONE_BONE_TOL = 1e-6
#: Plans kept per process (:func:`dq_plan`), the most recently asked for: a library
#: batch poses a body per scene, and its scenes share a few rigs (the 300-scene bench
#: library: one mesh plan and three sole plans for all of its generated clips).
PLAN_CACHE_SIZE = 8


@dataclass(frozen=True, eq=False)
class DQPlan:
    """Dual-quaternion skinning of one mesh, prepared: sparse coefficient matrices.

    Each product has the vertex's ``[x, y, z, 1]`` folded into its coefficients, so a
    product with a table of matrices' columns gives moved points directly (no
    per-vertex matrix is formed).

    Attributes
    ----------
    n_vertices, n_bones, n_shifts : int
        V, K and S (the columns of ``shift_weights``; 0 without).
    pair_keys : ndarray of int, shape (P, 3)
        ``(k, l, p)`` per key, ``k <= l``; ``p = -1`` where the sign needs no pivot
        (``k == l``, or the pair holds the vertex's pivot).
    dq_rows : ndarray of int, shape (D,)
        Vertices with a dual-quaternion part (all but those on one bone with weight 1
        and those without weights).
    pair_x : scipy.sparse.csr_matrix of shape (D, 4P)
        ``α_vp x̃_vj`` at column ``4p + j``: ``α = w_k²`` or ``2 w_k w_l``, times the
        vertex's share ``1 - linear`` of dual-quaternion skinning.
    pair_w : scipy.sparse.csr_matrix of shape (D, P)
        ``α_vp`` (the squared norm of the blended quaternion is ``pair_w @ c``).
    lin_x : scipy.sparse.csr_matrix of shape (V, 4(2K + 1) + S)
        The linear part over the table ``[M_k - T_k; M_k; I; shifts]``, times ``x̃``:
        ``w (1 - linear)`` and ``w linear``; 1 on ``M_k`` for a vertex on one bone; 1 on
        the identity for a vertex without weights (it stays where it is).
    dtype : numpy dtype
    """

    n_vertices: int
    n_bones: int
    n_shifts: int
    pair_keys: np.ndarray
    dq_rows: np.ndarray
    pair_x: sparse.csr_matrix
    pair_w: sparse.csr_matrix
    lin_x: sparse.csr_matrix
    dtype: np.dtype
    _blocks: dict = field(default_factory=dict, repr=False)

    def row_blocks(self, size: int) -> list[tuple]:
        """The plan in blocks of ``size`` vertices (made once per size): per block
        ``(first, stop, lin, pair_x rows, pair_w rows, first and stop of its
        dual-quaternion rows)``, the pair parts None where it has none.

        ``lin`` is ``[lin_x rows | S]``: ``S`` (rows, D) puts 1 at each of the block's
        dual-quaternion vertices' row of the blended part, so one product over the
        stacked columns ``[linear table; blended part]`` adds both (no scatter).
        """
        import scipy.sparse as sp

        if size not in self._blocks:
            v, d, out = self.n_vertices, len(self.dq_rows), list[tuple]()
            for r0 in range(0, v, size):
                r1 = min(v, r0 + size)
                lx = self.lin_x[r0:r1]
                j0, j1 = (int(i) for i in np.searchsorted(self.dq_rows, [r0, r1]))
                sel = sp.csr_matrix(
                    (np.ones(j1 - j0), (self.dq_rows[j0:j1] - r0, np.arange(j0, j1))),
                    shape=(r1 - r0, d),
                )
                lin = sp.hstack([lx, sel], format="csr").astype(self.dtype)
                lin.sort_indices()
                if j1 == j0:
                    out.append((r0, r1, lin, None, None, j0, j1))
                else:
                    out.append((r0, r1, lin, self.pair_x[j0:j1], self.pair_w[j0:j1], j0, j1))
            self._blocks[size] = out
        return self._blocks[size]


def _times_point(rows, cols, coef, xh, shape):
    """Sparse matrix with ``coef · xh[:, j]`` at ``(rows, 4 cols + j)``, j = 0..3
    (one entry per ``rows[i]``, ``cols[i]``, ``coef[i]``, ``xh[i]`` of shape (n, 4))."""
    import scipy.sparse as sp

    r = np.repeat(rows, 4)
    c = (4 * cols[:, None] + np.arange(4)).ravel()
    d = (coef[:, None] * xh).ravel()
    keep = d != 0
    m = sp.csr_matrix((d[keep], (r[keep], c[keep])), shape=shape)
    m.sum_duplicates()
    return m


_PLANS: OrderedDict[bytes, DQPlan] = OrderedDict()
_PLANS_LOCK = threading.Lock()


def _digest(*parts) -> bytes:
    """A digest of arrays and sparse matrices by content (kind, dtype, shape, values)."""
    h = hashlib.blake2b(digest_size=20)
    for x in parts:
        if x is None:
            h.update(b"none;")
        elif hasattr(x, "tocsr"):  # sparse: its stored entries, as they are
            m = x.tocsr()
            h.update(f"csr{m.shape}{m.data.dtype}{m.indices.dtype};".encode())
            for a in (m.data, m.indices, m.indptr):
                h.update(np.ascontiguousarray(a).data)
        else:
            a = np.ascontiguousarray(x)
            h.update(f"arr{a.shape}{a.dtype};".encode())
            h.update(a.data)
    return h.digest()


def dq_plan(
    rest: np.ndarray,
    weights,
    linear: np.ndarray | None = None,
    *,
    shift_weights=None,
    dtype=np.float64,
) -> DQPlan:
    """The :class:`DQPlan` of a mesh: rest vertices, weights, linear shares.

    A plan depends on its inputs' values alone, so the last :data:`PLAN_CACHE_SIZE`
    are kept by a digest of them (BLAKE2b of every value, ~1 ms for a 13,380-vertex
    body against ~15 ms to plan it): the scenes of a library that share a rig share
    one plan (and its row blocks). A plan is read-only; callers must not change its
    arrays.

    Parameters
    ----------
    rest : ndarray of shape (V, 3)
        Vertices in the bind pose.
    weights : sparse or dense matrix of shape (V, K)
        Skin weights (:func:`snapcore.motion.skinning.weight_matrix`).
    linear : ndarray of shape (V,), optional
        Per vertex, the share (0-1) of linear blend skinning mixed in.
    shift_weights : sparse matrix of shape (V, S), optional
        Coefficients of per-frame translations added to the result
        (``shifts`` of :func:`dq_skin_planned`).
    dtype : numpy dtype
        Precision of the per-vertex arithmetic.
    """
    key = _digest(rest, weights, linear, shift_weights) + np.dtype(dtype).str.encode()
    with _PLANS_LOCK:
        plan = _PLANS.get(key)
        if plan is not None:
            _PLANS.move_to_end(key)
            return plan
    plan = _make_plan(rest, weights, linear, shift_weights, dtype)
    with _PLANS_LOCK:
        _PLANS[key] = plan
        while len(_PLANS) > PLAN_CACHE_SIZE:
            _PLANS.popitem(last=False)
    return plan


def _make_plan(rest, weights, linear, shift_weights, dtype) -> DQPlan:
    """:func:`dq_plan`, computed."""
    import scipy.sparse as sp

    w = sp.csr_matrix(weights, dtype=np.float64, copy=True)  # pruned below: not theirs
    w.eliminate_zeros()
    w.sort_indices()
    v, k = w.shape
    xh = np.concatenate([np.asarray(rest, dtype=np.float64), np.ones((v, 1))], axis=1)
    lin = np.zeros(v) if linear is None else np.asarray(linear, dtype=np.float64).ravel()
    count = np.diff(w.indptr)
    rows_all = np.repeat(np.arange(v), count)
    first = w.data[w.indptr[:-1].clip(max=max(w.nnz - 1, 0))] if w.nnz else np.zeros(v)
    one = (count == 1) & (np.abs(first - 1.0) <= ONE_BONE_TOL)
    empty = count == 0
    dq = ~one & ~empty
    dq_rows = np.flatnonzero(dq)
    # pivot: the heaviest bone, the first of equals (as np.argmax over the dense row)
    pivot = np.argmax(w.toarray(), axis=1)

    # -- pair coefficients: for each vertex with n bones, its n(n+1)/2 pairs
    parts = []
    for n in np.unique(count[dq]):
        rows = np.flatnonzero(dq & (count == n))
        at = w.indptr[rows][:, None]
        iu, ju = np.triu_indices(n)
        alpha = w.data[at + iu] * w.data[at + ju] * np.where(iu == ju, 1.0, 2.0)
        parts.append((np.repeat(rows, len(iu)), w.indices[at + iu], w.indices[at + ju], alpha))
    prow, pk, pl, palpha = (
        np.concatenate([p[i].ravel() for p in parts]) if parts else np.zeros(0, int)
        for i in range(4)
    )
    piv = pivot[prow]
    ppiv = np.where((pk == pl) | (pk == piv) | (pl == piv), -1, piv)
    code = (pk * k + pl) * (k + 1) + (ppiv + 1)
    uniq, key_of = np.unique(code, return_inverse=True)
    keys = np.stack([uniq // (k + 1) // k, uniq // (k + 1) % k, uniq % (k + 1) - 1], axis=1)
    key_of = key_of.ravel()
    slot = np.full(v, -1)
    slot[dq_rows] = np.arange(len(dq_rows))
    d, p = len(dq_rows), len(uniq)
    pair_w = sp.csr_matrix((palpha, (slot[prow], key_of)), shape=(d, p))
    pair_w.sum_duplicates()
    pair_x = _times_point(slot[prow], key_of, palpha * (1.0 - lin[prow]), xh[prow], (d, 4 * p))

    # -- linear part over [M - T (K); M (K); identity (1)] and the shifts
    in_dq = dq[rows_all]
    coef = np.concatenate(
        [
            (w.data * (1.0 - lin[rows_all]))[in_dq],
            (w.data * lin[rows_all])[in_dq],
            np.ones(int(one.sum())),
            np.ones(int(empty.sum())),
        ]
    )
    lrow = np.concatenate(
        [rows_all[in_dq], rows_all[in_dq], np.flatnonzero(one), np.flatnonzero(empty)]
    )
    lcol = np.concatenate(
        [w.indices[in_dq], k + w.indices[in_dq], k + pivot[one], np.full(int(empty.sum()), 2 * k)]
    )
    n_table = 4 * (2 * k + 1)
    lin_x = _times_point(lrow, lcol, coef, xh[lrow], (v, n_table))
    s = 0
    if shift_weights is not None:
        sw = sp.csr_matrix(shift_weights, dtype=np.float64, copy=True)
        sw.eliminate_zeros()
        s = sw.shape[1]
        lin_x = sp.hstack([lin_x, sw], format="csr")
    return DQPlan(
        n_vertices=v,
        n_bones=k,
        n_shifts=s,
        pair_keys=keys,
        dq_rows=dq_rows,
        pair_x=pair_x.astype(dtype),
        pair_w=pair_w.astype(dtype),
        lin_x=lin_x.astype(dtype),
        dtype=np.dtype(dtype),
    )


def polar_rotation(a: np.ndarray, *, tol: float = 1e-13, max_iter: int = 30) -> np.ndarray:
    """The rotation ``R`` of the polar decomposition ``A = R S`` of (..., 3, 3) matrices.

    Newton's iteration ``X <- (g X + X^-T / g) / 2`` with the determinant scaling
    ``g = |det X|^(-1/3)`` (Higham 1986), vectorised with the cofactor inverse: a few
    passes over the array where a batched SVD takes microseconds per matrix. A matrix
    with ``det A <= 0`` (a mirror, or singular) gets the SVD's nearest rotation, as the
    dual-quaternion skinning always did.
    """
    x = np.array(a, dtype=np.float64, copy=True)
    shape = x.shape
    x = x.reshape(-1, 3, 3)
    det = np.linalg.det(x)
    good = det > 1e-12 * np.maximum(np.abs(x).max(axis=(1, 2), initial=0.0) ** 3, 1e-300)
    y = x[good]
    for _ in range(max_iter):
        r0, r1, r2 = y[:, 0], y[:, 1], y[:, 2]
        cof = np.stack([_cross(r1, r2), _cross(r2, r0), _cross(r0, r1)], axis=1)
        d = np.einsum("ni,ni->n", r0, cof[:, 0])
        g = np.abs(d) ** (-1.0 / 3.0)
        new = 0.5 * (g[:, None, None] * y + cof / (g * d)[:, None, None])
        step = np.abs(new - y).max(initial=0.0)
        y = new
        if step < tol:
            break
    out = np.empty_like(x)
    out[good] = y
    if not good.all():
        u, _, vt = np.linalg.svd(x[~good])
        flip = np.linalg.det(u @ vt) < 0
        u[flip, :, -1] *= -1
        out[~good] = u @ vt
    return out.reshape(shape)


def _quaternions(r: np.ndarray) -> np.ndarray:
    """Quaternions ``(w, x, y, z)`` of rotation matrices (..., 3, 3), component first:
    (4, ...).

    Shepperd's method: of the four ways to read a quaternion off the matrix, each
    matrix takes the one whose square root is of the largest of ``1 + tr R`` and
    ``1 + 2 R_ii - tr R`` (at least 1: no cancellation). Either sign of a quaternion
    serves (the kernel signs every pair itself). SciPy's ``from_matrix`` gave the same
    quaternions to 1e-16 at four times the cost (it also checks and projects).
    """
    r00, r01, r02 = r[..., 0, 0], r[..., 0, 1], r[..., 0, 2]
    r10, r11, r12 = r[..., 1, 0], r[..., 1, 1], r[..., 1, 2]
    r20, r21, r22 = r[..., 2, 0], r[..., 2, 1], r[..., 2, 2]
    tr = r00 + r11 + r22
    # 4 q_i q_j of the quaternion, off the diagonal: skew and symmetric parts of R
    wx, wy, wz = r21 - r12, r02 - r20, r10 - r01
    xy, xz, yz = r01 + r10, r02 + r20, r12 + r21
    big = np.stack([1 + tr, 1 + 2 * r00 - tr, 1 + 2 * r11 - tr, 1 + 2 * r22 - tr])
    which = np.argmax(big, axis=0)
    q = np.stack([big[0], wx, wy, wz])  # 4 w q: most matrices (|angle| < 120°)
    for i, row in ((1, (wx, big[1], xy, xz)), (2, (wy, xy, big[2], yz)), (3, (wz, xz, yz, big[3]))):
        at = which == i  # 4 q_i q
        if at.any():
            q[:, at] = np.stack([c[at] for c in row])
    q /= 2 * np.sqrt(big.max(axis=0))
    return q


def _pair_table(q, qd, keys, rigid, dtype) -> tuple[np.ndarray, np.ndarray]:
    """Each key's signed bilinear forms per frame, componentwise over (P, F) arrays.

    Parameters
    ----------
    q, qd : ndarray of shape (4, K, F)
        The bones' real and dual quaternions ``(w, x, y, z)``, component first.
    keys : ndarray of int, shape (P, 3)
    rigid : ndarray of shape (F, K, 3, 4)
        The bones' rigid transforms: the diagonal keys' forms, exactly.
    dtype : numpy dtype
        Of the returned tables (the signs are decided in float64).

    Returns
    -------
    n : ndarray of shape (P, 4, 3, F)
        ``σ N(d_k, d_l)``: column ``j``, row ``i``, frame (the products' layout).
    c : ndarray of shape (P, F)
        ``σ q_k · q_l``.
    """
    k, j, p = keys[:, 0], keys[:, 1], keys[:, 2]
    # the signs first, in float64: s_k s_l; with the pivot in the pair (or k == l),
    # sign(q_k · q_l); the far pairs' from every pair's dot product per frame (a
    # (K, K) Gram matrix per frame)
    c64 = np.einsum("apf,apf->pf", q[:, k], q[:, j])
    sign = np.where(c64 < 0, -1.0, 1.0)
    far = np.flatnonzero(p >= 0)
    if far.size:
        gram = np.matmul(q.transpose(2, 1, 0), q.transpose(2, 0, 1))  # (F, K, K)
        sk = gram[:, k[far], p[far]].T < 0
        sl = gram[:, j[far], p[far]].T < 0
        sign[far] = np.where(sk ^ sl, -1.0, 1.0)
    diag = np.flatnonzero(k == j)
    sign[diag] = 1.0
    n = np.empty((len(keys), 4, 3, q.shape[2]), dtype=dtype)
    u = np.concatenate([q, qd]).astype(dtype)  # (8, K, F)
    # the sign folded into one factor of each product
    w1, x1, y1, z1, e1, a1, b1, c1 = u[:, k] * sign.astype(dtype)
    w2, x2, y2, z2, e2, a2, b2, c2 = u[:, j]  # dual parts: (w_e, x_e, y_e, z_e)
    o = n
    xx, yy, zz = x1 * x2, y1 * y2, z1 * z2
    s = w1 * w2 - (xx + yy + zz)
    wx, wy, wz = w1 * x2 + w2 * x1, w1 * y2 + w2 * y1, w1 * z2 + w2 * z1
    xy, xz, yz = x1 * y2 + x2 * y1, x1 * z2 + x2 * z1, y1 * z2 + y2 * z1
    # R(q, q') = (w w' - v·v') I + v v'ᵀ + v' vᵀ + w [v']× + w' [v]×
    o[:, 0, 0] = s + 2 * xx
    o[:, 1, 0] = xy - wz
    o[:, 2, 0] = xz + wy
    o[:, 0, 1] = xy + wz
    o[:, 1, 1] = s + 2 * yy
    o[:, 2, 1] = yz - wx
    o[:, 0, 2] = xz - wy
    o[:, 1, 2] = yz + wx
    o[:, 2, 2] = s + 2 * zz
    # t(d, d') = w v_ε' + w' v_ε - w_ε v' - w_ε' v + v × v_ε' + v' × v_ε
    o[:, 3, 0] = w1 * a2 + w2 * a1 - e1 * x2 - e2 * x1 + (y1 * c2 - z1 * b2) + (y2 * c1 - z2 * b1)
    o[:, 3, 1] = w1 * b2 + w2 * b1 - e1 * y2 - e2 * y1 + (z1 * a2 - x1 * c2) + (z2 * a1 - x2 * c1)
    o[:, 3, 2] = w1 * c2 + w2 * c1 - e1 * z2 - e2 * z1 + (x1 * b2 - y1 * a2) + (x2 * b1 - y2 * a1)
    n[diag] = _table(rigid[:, k[diag]])  # N(d_k, d_k) = T_k, exactly
    return n, (c64 * sign).astype(dtype)


def _table(m: np.ndarray) -> np.ndarray:
    """Matrices (F, N, 3, 4) as product rows: (N, 4, 3, F): column ``j``, row ``i``, frame."""
    return m.transpose(1, 3, 2, 0)


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a × b`` of (N, 3) arrays (np.cross's checks cost more than the products)."""
    a0, a1, a2 = a[:, 0], a[:, 1], a[:, 2]
    b0, b1, b2 = b[:, 0], b[:, 1], b[:, 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=1)


def dq_skin_planned(
    plan: DQPlan,
    matrices: np.ndarray,
    centres: np.ndarray,
    shifts: np.ndarray | None = None,
    *,
    out: np.ndarray | None = None,
    rotations: np.ndarray | None = None,
) -> np.ndarray:
    """Dual-quaternion skinning (see :func:`snapcore.motion.skinning.dq_skin`) by a plan.

    Parameters
    ----------
    plan : DQPlan
        :func:`dq_plan` of the mesh.
    matrices : ndarray of shape (F, K, 3, 4)
        Each bone's skinning transform.
    centres : ndarray of shape (K, 3)
        Each bone's centre in the rest pose.
    shifts : ndarray of shape (F, S, 3), optional
        Translations added as ``shift_weights @ shifts`` (the plan's ``shift_weights``).
    out : ndarray of shape (F, V, 3), optional
        Where to write the result (of the plan's dtype).
    rotations : ndarray of shape (F, K, 3, 3), optional
        The rotations of the matrices' polar decompositions, when the caller has them
        (the retargeting builds its matrices as rotation × scaling): no polar iteration.

    Returns
    -------
    ndarray of shape (F, V, 3), of the plan's dtype
        Per-vertex arithmetic in that dtype; the bones' own (per frame) in float64.
    """
    m = np.asarray(matrices, dtype=np.float64)
    f, k = m.shape[:2]
    v, dtype = plan.n_vertices, plan.dtype
    if k != plan.n_bones:
        raise ValueError(f"matrices {m.shape} do not fit a plan of {plan.n_bones} bones")
    if out is None:
        out = np.empty((f, v, 3), dtype=dtype)
    elif out.shape != (f, v, 3) or out.strides[1:] != (3 * dtype.itemsize, dtype.itemsize):
        # each frame's vertices are written as one row of coordinates (a view)
        raise ValueError(f"out must be ({f}, {v}, 3) of {dtype}, each frame contiguous")
    if f == 0 or v == 0:
        return out
    # -- per bone and frame (float64, F × K small): rigid part T x = R x + t, tables
    r = polar_rotation(m[..., :3]) if rotations is None else np.asarray(rotations, np.float64)
    t = np.einsum("fkij,kj->fki", m[..., :3] - r, np.asarray(centres, float)) + m[..., 3]
    rigid = np.concatenate([r, t[..., None]], axis=-1)
    rows = [_table(m - rigid), _table(m), _table(np.broadcast_to(np.eye(3, 4), (f, 1, 3, 4)))]
    rows = [x.reshape(-1, 3, f) for x in rows]
    if plan.n_shifts:
        rows.append(np.asarray(shifts, dtype=np.float64).transpose(1, 2, 0))
    lin_table = np.concatenate(rows, axis=0).astype(dtype)  # (rows, 3, F)
    d = len(plan.dq_rows)
    if d:
        q = _quaternions(r).transpose(0, 2, 1)  # (4, K, F)
        tt = t.transpose(2, 1, 0)  # (3, K, F)
        # dual part q_ε = ½ (0, t) q
        qd = 0.5 * np.stack(
            [
                -(tt * q[1:]).sum(axis=0),
                q[0] * tt[0] + tt[1] * q[3] - tt[2] * q[2],
                q[0] * tt[1] + tt[2] * q[1] - tt[0] * q[3],
                q[0] * tt[2] + tt[0] * q[2] - tt[1] * q[1],
            ]
        )
        n_tab, c_tab = _pair_table(q, qd, plan.pair_keys, rigid, dtype)
        pair_table = n_tab.reshape(-1, 3, f)
    # frames in chunks, each product over KERNEL_FRAMES of them; vertices in blocks
    # whose products' output stays in cache for the transposing copy
    nf = min(f, KERNEL_FRAMES)
    size = max(256, int(KERNEL_CHUNK_BYTES // (3 * nf * np.dtype(dtype).itemsize)))
    blocks = plan.row_blocks(size)
    n_lin = lin_table.shape[0]
    for a in range(0, f, nf):
        b = min(f, a + nf)
        # columns (row i of the 3 x 4 matrices, frame): each coordinate is one block;
        # below the linear table, each dual-quaternion vertex's blended part
        cols = np.empty((n_lin + d, 3 * (b - a)), dtype=dtype)
        cols[:n_lin] = lin_table[..., a:b].reshape(-1, 3 * (b - a))
        if d:
            pair_cols = pair_table[..., a:b].reshape(-1, 3 * (b - a))
            den_cols = np.ascontiguousarray(c_tab[:, a:b])
        for r0, r1, lin, pair_x, pair_w, j0, j1 in blocks:
            if pair_x is not None:
                num = (pair_x @ pair_cols).reshape(j1 - j0, 3, b - a)
                part = cols[n_lin + j0 : n_lin + j1].reshape(j1 - j0, 3, b - a)
                np.divide(num, (pair_w @ den_cols)[:, None], out=part)
            y = lin @ cols  # (rows, 3 nf): the linear part plus the blended one
            # to (nf, rows, 3): (rows · 3, nf) → (nf, rows · 3) is a 2-D transpose;
            # copied in column strips (15% faster than in one piece, measured)
            src, dst = y.reshape(-1, b - a), out[a:b, r0:r1].reshape(b - a, -1)
            for c in range(0, src.shape[0], TRANSPOSE_STRIP):
                dst[:, c : c + TRANSPOSE_STRIP] = src[c : c + TRANSPOSE_STRIP].T
    return out
