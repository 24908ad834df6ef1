"""Bones as capsules: point-segment distances, capsule radii, body-to-body proximity.

:func:`body_near` answers, for every frame and every joint of one character, whether
the joint is within a gap of another character's body, whose bones are capsules
(segments with the radii of the rendered body, :func:`bone_radii`), and which bone
is nearest. It is the hot path of interaction detection (:mod:`snapcore.select.contacts`):
the brute force tests every (frame, joint, bone) triple, 7 million for the salsa pair.

The layout of the arrays follows the cost of NumPy operations, not elegance:
coordinates are kept component-first (``(3, ...)``), because reductions over a short
last axis of length 3 run ten times slower than the same arithmetic on three
contiguous planes, and gathers take whole rows with :meth:`numpy.ndarray.take`.
"""

from __future__ import annotations

import numpy as np

from snapcore.motion.anatomy import DEFAULT_ROLE, ROLE_RADII, bone_role
from snapcore.select.signals import nonzero_rows

__all__ = ["segment_distance", "bone_radii", "body_near", "BODY_BLOCK_S"]

#: Seconds of motion per time block of the broad phase of :func:`body_near` (a joint's
#: swept box over the block is tested, then the block's frames one by one).
BODY_BLOCK_S = 0.1
#: Bones per bounding-box group in that broad phase. Links come in depth-first order,
#: so consecutive bones are neighbours in the body and a group's box stays small.
_GROUP_SIZE = 8
#: Rows (joint block x bone) per chunk of the narrow phase of :func:`body_near`.
_CHUNK_ROWS = 4096
#: Relative slack of the reach in the cheap squared-distance filter before the exact
#: distance: far above the filter's rounding (~1e-15 of the squared body size), far
#: below any tolerance; the exact distance decides.
_FILTER_SLACK = 1e-6


def segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance from points to segments, broadcast over leading axes.

    Parameters
    ----------
    p, a, b : ndarray of shape (..., 3)
        Points and segment end points (broadcastable).

    Returns
    -------
    ndarray of shape (...)
        ``min_t |p - (a + t (b - a))|`` over ``t`` in [0, 1]. A zero-length segment
        is the point ``a``.

    Notes
    -----
    The closest point is taken as exactly ``a`` or ``b`` when the projection falls
    outside the segment, so two bones sharing a joint give bit-identical distances
    to points nearest that joint (ties resolve to the lower bone index everywhere).
    """
    ab = b - a
    ap = p - a
    den = (ab * ab).sum(-1)
    num = (ap * ab).sum(-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        t = np.where(den > 0, num / np.where(den > 0, den, 1.0), 0.0)
    d_in = ap - t[..., None] * ab
    d_a = ap
    d_b = p - b
    d = np.where((t <= 0)[..., None], d_a, np.where((t >= 1)[..., None], d_b, d_in))
    return np.sqrt((d * d).sum(-1))


def _segment_distance_planes(p, a, b) -> np.ndarray:
    """:func:`segment_distance` on component-first arrays ``(3, ...)``: the same
    arithmetic (bit-identical results) on contiguous planes."""
    ab = b - a
    ap = p - a
    den = ab[0] * ab[0] + ab[1] * ab[1] + ab[2] * ab[2]
    num = ap[0] * ab[0] + ap[1] * ab[1] + ap[2] * ab[2]
    pos = den > 0
    t = np.where(pos, num / np.where(pos, den, 1.0), 0.0)
    d = np.where(t <= 0, ap, np.where(t >= 1, p - b, ap - t * ab))
    d *= d
    return np.sqrt(d[0] + d[1] + d[2])


def bone_radii(character) -> np.ndarray:
    """Capsule radius (m) of each bone of ``character.skeleton.links``, shape (L,).

    The radii of the rendered body (:data:`snapcore.motion.anatomy.ROLE_RADII`, the larger
    semi-axis, by the role of the bone read from joint names), scaled with the
    character's stature like the body mesh. Bones the body does not draw (eyes
    inside the head, a floor-level root's bone up to the hips) get ``-inf``: they
    are not part of the surface and never touch anything.
    """
    sk = character.skeleton
    roles = sk.roles
    k = character.height  # radii are fractions of the stature
    out = np.empty(sk.links.shape[0])
    for i, (p, c) in enumerate(np.asarray(sk.links).reshape(-1, 2)):
        rp, rc = roles[p], roles[c]
        if rp == "hidden" or (rc == "hidden" and not sk.end_site[c]):
            out[i] = -np.inf
            continue
        role = bone_role(rp, rc)  # the same radius as the rendered body's capsule
        out[i] = max(ROLE_RADII.get(role, ROLE_RADII[DEFAULT_ROLE])) * k
    return out


def _swept(z: np.ndarray, block: int):
    """Positions ``z (F, J, 3)`` prepared for :func:`body_near` in blocks of frames.

    Returns
    -------
    lo, hi : ndarray of shape (3, J, B)
        Bounding box of each joint over each block, component-first, joint-major;
        ``B = ceil(F / block)``.
    rows : ndarray of shape (3, J * B, block)
        Positions, row ``j * B + b`` holding block b of joint j (the short last block
        repeats the last frame): the narrow phase gathers whole rows.
    """
    n_f, n_j = z.shape[:2]
    n_full, n_b = n_f // block, -(-n_f // block)
    flat = z.reshape(n_f, n_j * 3)
    lo, hi = np.empty((n_b, n_j * 3)), np.empty((n_b, n_j * 3))
    if n_full:  # elementwise over the frames of the blocks: reductions over a short
        main = flat[: n_full * block].reshape(n_full, block, n_j * 3)  # axis are slower
        lo[:n_full], hi[:n_full] = main[:, 0], main[:, 0]
        for k in range(1, block):
            np.minimum(lo[:n_full], main[:, k], out=lo[:n_full])
            np.maximum(hi[:n_full], main[:, k], out=hi[:n_full])
    if n_b > n_full:
        np.min(flat[n_full * block :], axis=0, out=lo[n_full])
        np.max(flat[n_full * block :], axis=0, out=hi[n_full])
    rows = np.empty((3, n_j, n_b * block))
    rows[:, :, :n_f] = z.transpose(2, 1, 0)
    rows[:, :, n_f:] = rows[:, :, n_f - 1 : n_f]
    return (
        np.ascontiguousarray(lo.reshape(n_b, n_j, 3).transpose(2, 1, 0)),
        np.ascontiguousarray(hi.reshape(n_b, n_j, 3).transpose(2, 1, 0)),
        rows.reshape(3, n_j * n_b, block),
    )


def _overlap(alo, ahi, blo, bhi) -> np.ndarray:
    """Boxes ``[alo, ahi]`` and ``[blo, bhi]`` (sequences of 3 planes) intersect."""
    r = ahi[0] >= blo[0]
    r &= alo[0] <= bhi[0]
    for c in (1, 2):
        r &= ahi[c] >= blo[c]
        r &= alo[c] <= bhi[c]
    return r


def body_near(
    x: np.ndarray,
    other,
    gap: float,
    *,
    radii: np.ndarray | None = None,
    block: int = 3,
    cache: dict | None = None,
):
    """Which joints of one character touch another's body (bones as capsules).

    Parameters
    ----------
    x : ndarray of shape (F, J, 3)
        Joint positions of the toucher, metres.
    other : Character
        The touched character; its bones are ``other.skeleton.links``.
    gap : float
        Largest distance (m) from a joint to a capsule's surface that counts.
    radii : ndarray of shape (L,), optional
        Capsule radius of each bone (default :func:`bone_radii`).
    block : int
        Frames per time block of the broad phase.
    cache : dict, optional
        Prepared positions (:func:`_swept`) keyed by ``id`` of the array and
        ``block``: pass the same dict to the calls of one scene, where each character
        is toucher and touched in turn.

    Returns
    -------
    near : ndarray of bool, shape (F, J)
        Some bone's axis is within ``radius + gap`` of the joint.
    bone : ndarray of int, shape (F, J)
        Index into ``other.skeleton.links`` of the bone whose surface is nearest
        (``axis distance - radius``; the lowest index among equals) where near, -1
        elsewhere.

    Notes
    -----
    Equal to testing every bone at every frame (the tests check it): a
    bounding-volume hierarchy in time and space prunes. Per block of frames, each
    joint's swept box is tested against the other's swept whole-body box (bones
    grown by their reach ``radius + gap``), then against boxes of groups of
    neighbouring bones, then against each bone's box. The surviving (frame, joint,
    bone) triples get a cheap squared distance (``|ap|^2 - t (2 ap.ab - t |ab|^2)``,
    no branches), and those within reach the exact distance of
    :func:`segment_distance`, so decisions and ties are those of the plain formula.
    Two people a metre apart keep a few percent of the triples.
    """
    n_f, n_j = x.shape[:2]
    links = np.asarray(other.skeleton.links, dtype=np.int64).reshape(-1, 2)
    n_l = links.shape[0]
    near = np.zeros((n_f, n_j), dtype=bool)
    bone = np.full((n_f, n_j), -1, dtype=np.int64)
    if n_l == 0 or n_f == 0:
        return near, bone
    y = other.positions
    radii = bone_radii(other) if radii is None else np.asarray(radii, dtype=float)
    reach = radii + gap  # -inf for bones that never touch: their boxes are empty
    if cache is None:
        cache = {}
    for z in (x, y):
        if (id(z), block) not in cache:
            cache[(id(z), block)] = _swept(z, block)
    jlo, jhi, xrows = cache[(id(x), block)]  # (3, J, B), (3, J * B, block)
    ylo, yhi, yrows = cache[(id(y), block)]
    n_b = jlo.shape[2]
    # Bone boxes grown by their reach, in groups of consecutive links (the last group
    # padded by repeating its last link): (3, G, S, B), rows of blocks.
    size = _GROUP_SIZE
    n_g = -(-n_l // size)
    g_links = np.minimum(np.arange(n_g * size), n_l - 1)
    la, lb = links[:, 0].take(g_links), links[:, 1].take(g_links)
    g_reach = reach.take(g_links)[:, None]
    llo = np.minimum(ylo.take(la, axis=1), ylo.take(lb, axis=1))
    llo -= g_reach
    lhi = np.maximum(yhi.take(la, axis=1), yhi.take(lb, axis=1))
    lhi += g_reach
    glo = llo.reshape(3, n_g, size, n_b).min(axis=2)  # (3, G, B) group boxes
    ghi = lhi.reshape(3, n_g, size, n_b).max(axis=2)
    blo, bhi = glo.min(axis=1), ghi.max(axis=1)  # (3, B) whole body

    # Level 1: joint boxes against the whole body.
    cand = np.flatnonzero(_overlap(jlo, jhi, blo[:, None], bhi[:, None]))  # j * B + b
    if cand.size == 0:
        return near, bone
    bi = cand % n_b
    lo_n = [jlo[c].reshape(-1).take(cand) for c in range(3)]
    hi_n = [jhi[c].reshape(-1).take(cand) for c in range(3)]
    # Level 2: against the groups of that block, (n, G).
    glo, ghi = (np.ascontiguousarray(v.transpose(0, 2, 1)) for v in (glo, ghi))  # (3, B, G)
    ov = _overlap(
        [v[:, None] for v in lo_n],
        [v[:, None] for v in hi_n],
        [glo[c].take(bi, axis=0) for c in range(3)],
        [ghi[c].take(bi, axis=0) for c in range(3)],
    )
    n2, g2 = nonzero_rows(ov)  # np.nonzero of a 2-D mask is ~3x slower here
    # Level 3: against the bones of those groups, (n2, S).
    llo, lhi = (
        np.ascontiguousarray(v.transpose(0, 2, 1)).reshape(3, n_b * n_g, size) for v in (llo, lhi)
    )  # rows b * G + g
    bg = bi.take(n2) * n_g + g2
    ov3 = _overlap(
        [v.take(n2)[:, None] for v in lo_n],
        [v.take(n2)[:, None] for v in hi_n],
        [llo[c].take(bg, axis=0) for c in range(3)],
        [lhi[c].take(bg, axis=0) for c in range(3)],
    )
    if n_g * size > n_l:  # padding repeats the last link: test it once
        ov3 &= (np.arange(n_g * size) < n_l).reshape(n_g, size).take(g2, axis=0)
    r3, c3 = nonzero_rows(ov3)
    if r3.size == 0:
        return near, bone
    link3 = g_links.take(g2.take(r3) * size + c3)
    jb3 = cand.take(n2.take(r3))  # j * B + b
    # Narrow phase, rows of ``block`` frames, in chunks whose temporaries stay in cache:
    # a cheap filter, then the exact distance of the few within reach.
    idx = np.concatenate(
        [  # row * block + frame in block
            _within_reach(
                xrows,
                yrows,
                links,
                reach,
                jb3[s : s + _CHUNK_ROWS],
                link3[s : s + _CHUNK_ROWS],
                n_b,
            )
            + s * block
            for s in range(0, jb3.size, _CHUNK_ROWS)
        ]
    )
    row, k = np.divmod(idx, block)
    lk, jb = link3.take(row), jb3.take(row)
    b = jb % n_b
    d = _segment_distance_planes(  # the points, gathered from the flattened rows
        xrows.reshape(3, -1).take(jb * block + k, axis=1),
        yrows.reshape(3, -1).take((links[:, 0].take(lk) * n_b + b) * block + k, axis=1),
        yrows.reshape(3, -1).take((links[:, 1].take(lk) * n_b + b) * block + k, axis=1),
    )
    d -= radii.take(lk)
    hit = np.flatnonzero(d <= gap)
    if hit.size == 0:
        return near, bone
    d, lk, k, jb = d.take(hit), lk.take(hit), k.take(hit), jb.take(hit)
    j, b = np.divmod(jb, n_b)
    f = b * block + k
    ok = f < n_f  # not a repeat of the last frame
    key = (f * n_j + j)[ok]
    d, lk = d[ok], lk[ok]
    # Nearest bone per (frame, joint): the smallest distance, then the lowest link.
    best = np.full(n_f * n_j, np.inf)
    np.minimum.at(best, key, d)
    at = d == best.take(key)
    flat_bone = bone.reshape(-1)
    flat_bone[key[at]] = n_l
    np.minimum.at(flat_bone, key[at], lk[at])
    near.reshape(-1)[key] = True
    return near, bone


def _within_reach(xrows, yrows, links, reach, jb, link, n_b) -> np.ndarray:
    """The frames of (joint row, bone) pairs where the joint may be within reach.

    A squared distance without branches, ``|ap|^2 - t (2 ap.ab - t |ab|^2)`` with t
    clipped to [0, 1], against the reach grown by :data:`_FILTER_SLACK`. Returns the
    flat indices ``row * block + frame in block`` that pass (rows of this chunk).
    """
    b = jb % n_b
    p = _rows(xrows, jb)  # (3, n, block)
    ya = _rows(yrows, links[:, 0].take(link) * n_b + b)
    ab = _rows(yrows, links[:, 1].take(link) * n_b + b)
    # In place, with ya's first plane as scratch once it is used: fewer temporaries
    # (~10% of this function); the sums run in the same order, (x + y) + z.
    ab -= ya
    ap = p
    ap -= ya
    tmp = ya[0]
    den = ab[0] * ab[0]
    den += np.multiply(ab[1], ab[1], out=tmp)
    den += np.multiply(ab[2], ab[2], out=tmp)
    num = ap[0] * ab[0]
    num += np.multiply(ap[1], ab[1], out=tmp)
    num += np.multiply(ap[2], ab[2], out=tmp)
    d2 = ap[0] * ap[0]
    d2 += np.multiply(ap[1], ap[1], out=tmp)
    d2 += np.multiply(ap[2], ap[2], out=tmp)
    t = num / np.where(den > 0, den, np.inf)  # 0 for a zero-length bone
    np.clip(t, 0.0, 1.0, out=t)
    num *= 2.0
    num -= np.multiply(t, den, out=tmp)
    num *= t
    d2 -= num
    lim = reach.take(link) * (1.0 + _FILTER_SLACK)  # reach > 0 (bones that touch)
    lim *= lim
    return np.flatnonzero(d2 <= lim[:, None])


def _rows(rows: np.ndarray, index: np.ndarray) -> np.ndarray:
    """Rows ``index`` of component-first rows ``(3, R, block)``: shape (3, n, block)."""
    out = np.empty((3, index.size, rows.shape[2]))
    for c in range(3):
        rows[c].take(index, axis=0, out=out[c], mode="clip")  # "raise" would buffer
    return out
