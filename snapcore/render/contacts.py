"""Two human bodies in a close hold: skin pushed out of the partner's body.

Motion capture puts partners' joints where their skeletons were; the MakeHuman body
fitted to each has its own girth, so in a salsa hold a hand resting on the partner's
back sank 8-10 cm into it (CMU 60_01 / 61_01), where the capsule mannequins on the
same skeletons overlapped 5 cm. After skinning, :func:`push_out` moves each body's
vertices that lie inside the other out along the partner's surface normal, by their
depth (up to :data:`REACH_M`): fully for the arms and hands (a hand rests *on* a
back), by half for the rest (two chests pressed together meet half-way, both
moving). The displacement is smoothed over the vertex's neighbours so the skin
dents instead of spiking.

"Inside" is judged against the nearest partner vertex: below its tangent plane (the
offset along its outward normal is negative) and within :data:`REACH_M` of it. On a
closed, fine mesh this is the signed distance for the shallow depths that matter;
deeper than the reach (a skeleton's own overlap of a limb's width) nothing moves.
"""

from __future__ import annotations

import numpy as np
from scipy import sparse

__all__ = [
    "push_out",
    "penetration",
    "resolve_contacts",
    "contact_yield",
    "vertex_neighbours",
    "REACH_M",
    "HALF_YIELD",
    "YIELDING_BONES",
]

#: Deepest penetration resolved, metres; and the distance to the nearest partner vertex
#: beyond which a vertex is not tested.
REACH_M = 0.12
#: The share of its depth a vertex not on an arm moves out by (the partner's skin
#: moves the other half).
HALF_YIELD = 0.5
#: Rig bones whose skin yields fully: what rests on a partner in a hold.
YIELDING_BONES = tuple(
    f"{side}{b}" for side in ("Left", "Right") for b in ("Arm", "ForeArm", "Hand", "FingerBase")
) + ("LThumb", "RThumb", "LeftHandFinger1", "RightHandFinger1")


def penetration(va: np.ndarray, vb: np.ndarray, nb: np.ndarray, reach: float = REACH_M):
    """How deep each point of ``va`` (P, 3) lies inside the body with vertices ``vb``
    (Q, 3) and unit outward normals ``nb`` (Q, 3): (depth (P,) metres, 0 outside;
    the nearest partner vertex (P,), -1 beyond ``reach``)."""
    from scipy.spatial import cKDTree

    d, i = cKDTree(vb).query(va, distance_upper_bound=reach)
    ok = np.isfinite(d)
    depth = np.zeros(len(va))
    near = np.where(ok, i, -1)
    s = np.einsum("ij,ij->i", va[ok] - vb[i[ok]], nb[i[ok]])
    depth[ok] = np.clip(-s, 0.0, reach)
    return depth, near


def _box(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Bounding box (lo (3,), hi (3,)) of points (P, 3). One column at a time: a
    reduction over the long axis of an (P, 3) array runs ~18x slower than over its
    columns (NumPy loops the inner axis of 3 per point)."""
    cols = [v[:, j] for j in range(3)]
    return np.array([c.min() for c in cols]), np.array([c.max() for c in cols])


def _cells(v: np.ndarray, lo: np.ndarray, cell: float, shape) -> tuple:
    """Grid cell indices (3 arrays (P,)) of points ``v`` (P, 3) in a grid of ``shape``
    cells of side ``cell`` metres starting at ``lo``, clipped to it."""
    return tuple(
        np.clip(((v[:, j] - lo[j]) / cell).astype(np.int64), 0, shape[j] - 1) for j in range(3)
    )


def _dilated(cells: tuple, shape) -> np.ndarray:
    """Occupancy grid (shape, bool) of ``cells`` grown by one cell in every direction
    (its 26 neighbours)."""
    g = np.zeros(tuple(s + 2 for s in shape), bool)
    g[tuple(c + 1 for c in cells)] = True
    for ax in range(3):
        g = g | np.roll(g, 1, axis=ax) | np.roll(g, -1, axis=ax)  # padded: no wrap
    return g[1:-1, 1:-1, 1:-1]


def near_pairs(va: np.ndarray, vb: np.ndarray, reach: float) -> tuple[np.ndarray, np.ndarray]:
    """Broad phase of :func:`push_out`: indices (ia, ib) of the points of ``va`` (P, 3)
    that may have a point of ``vb`` (Q, 3) within ``reach`` metres, and of the points
    of ``vb`` that may be that nearest point.

    Exact, not a guess: every pair within ``reach`` is kept. The points are binned in
    a grid of ``reach``-sided cells over the two bodies' overlap (their boxes grown by
    ``reach``); a point within ``reach`` of another lies in its cell or one of the 26
    around it, so a point of A is kept where a point of B is in its 3x3x3 block, and a
    point of B where a kept point of A is. In a hold the bodies' boxes overlap almost
    whole; the cells keep only the arms, hands and chests that meet.
    """
    (alo, ahi), (blo, bhi) = _box(va), _box(vb)
    none = np.zeros(0, np.int64)
    lo = np.maximum(alo, blo) - reach
    hi = np.minimum(ahi, bhi) + reach
    if np.any(lo > hi):
        return none, none  # apart: the boxes do not meet
    ia = np.flatnonzero(_inside(va, lo, hi))
    ib = np.flatnonzero(_inside(vb, lo, hi))
    if not (ia.size and ib.size):
        return none, none
    cell = reach * 1.01  # a little over the reach: rounding cannot part a pair by 2 cells
    shape = tuple(int(n) for n in np.ceil((hi - lo) / cell) + 1)
    ca, cb = _cells(va[ia], lo, cell, shape), _cells(vb[ib], lo, cell, shape)
    keep = _dilated(cb, shape)[ca]
    if not keep.any():
        return none, none
    ia, ca = ia[keep], tuple(c[keep] for c in ca)
    ib = ib[_dilated(ca, shape)[cb]]
    return ia, ib


def _inside(v: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Which points (P, 3) lie in the box [lo, hi] (P,) bool (column by column: see
    :func:`_box`)."""
    m = (v[:, 0] >= lo[0]) & (v[:, 0] <= hi[0])
    for j in (1, 2):
        m &= (v[:, j] >= lo[j]) & (v[:, j] <= hi[j])
    return m


def push_out(
    va: np.ndarray,
    yield_a: np.ndarray,
    vb: np.ndarray,
    nb: np.ndarray,
    neighbours: sparse.csr_matrix | None = None,
) -> np.ndarray:
    """``va`` (P, 3) with the points inside the partner (``vb``, ``nb``: (Q, 3)) moved
    out along the nearest partner vertex's normal by ``depth x yield_a`` (P,).

    Parameters
    ----------
    neighbours : sparse (P, P), optional
        Row-normalised vertex adjacency of body A: the displacement is averaged over it
        twice, taking the larger of a vertex's own and its neighbours' mean push, so a
        dent is smooth and no penetrating vertex moves less than its own depth asks.
    """
    ia, ib = near_pairs(va, vb, REACH_M)
    if not (ia.size and ib.size):
        return va
    d, near = penetration(va[ia], vb[ib], nb[ib])
    if not np.any(d > 0):
        return va
    depth = np.zeros(len(va))
    depth[ia] = d
    normal = np.zeros_like(va, dtype=float)
    normal[ia] = nb[ib[np.maximum(near, 0)]]
    push = (depth * yield_a)[:, None] * normal
    if neighbours is not None:
        for _ in range(2):
            spread = neighbours @ push
            own = np.linalg.norm(push, axis=1)
            push = np.where((own >= np.linalg.norm(spread, axis=1))[:, None], push, spread)
    return va + push


def contact_yield(asset) -> np.ndarray:
    """Each rest vertex's share of its depth it moves out by (V,): 1 on the arms and
    hands (:data:`YIELDING_BONES`, by skin weight), :data:`HALF_YIELD` elsewhere."""
    cols = [asset.bone(b) for b in YIELDING_BONES]
    arm = np.clip(np.asarray(asset.weights[:, cols].sum(axis=1)).ravel(), 0.0, 1.0)
    return HALF_YIELD + (1.0 - HALF_YIELD) * arm


def vertex_neighbours(faces: np.ndarray, n: int) -> sparse.csr_matrix:
    """Row-normalised adjacency (n, n) of a triangle mesh's vertices (edges of faces)."""
    f = np.asarray(faces, np.int64)
    i = np.concatenate([f[:, 0], f[:, 1], f[:, 2], f[:, 1], f[:, 2], f[:, 0]])
    j = np.concatenate([f[:, 1], f[:, 2], f[:, 0], f[:, 0], f[:, 1], f[:, 2]])
    a = sparse.csr_matrix((np.ones(len(i)), (i, j)), shape=(n, n))
    a.data[:] = 1.0
    deg = np.asarray(a.sum(axis=1)).ravel()
    return sparse.diags(1.0 / np.maximum(deg, 1.0)) @ a


def resolve_contacts(verts: list, normals: list, yields: list, neighbours: list) -> list:
    """Every pair of bodies' skin pushed out of each other (:func:`push_out`), one frame.

    Parameters
    ----------
    verts, normals : lists of arrays (V_i, 3)
        Each body's posed vertices and unit normals.
    yields : list of arrays (V_i,) or None
        Each body's :func:`contact_yield`; None: a body that does not yield (it is not
        moved, but others are pushed out of it).
    neighbours : list of sparse (V_i, V_i) or None

    Returns
    -------
    list of arrays (V_i, 3)
    """
    out = list(verts)
    for a in range(len(out)):
        if yields[a] is None:
            continue
        for b in range(len(out)):
            if b != a:
                out[a] = push_out(out[a], yields[a], out[b], normals[b], neighbours[a])
    return out
