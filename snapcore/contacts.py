"""Interaction events: a joint resting against the ground, another character, or a prop.

The global term of pose entropy (METHOD §1, paper §3.1.2) counts *interactions*: a
joint j and an object o interact while

1. the joint is within a distance tolerance of the object, and
2. the joint's position *relative to the object* stays within a displacement
   tolerance of where the interaction started,

and an interaction is only recognised once both have held for a minimum duration;
after that it is propagated forward frame by frame until either fails ("until the
relative position between the joint and environment exceeds the tolerance", paper).

Objects are the ground plane (``scene.ground``), the body of every *other* character
(its bones as capsules: segment distance to the bone axis) and the static props of
the scene manifest (sphere, box, capsule; metres). The position of a joint relative
to the ground or a prop is its world position (those objects do not move); relative
to another body it is the position in the frame of the touched bone, the bone nearest
the joint when the interaction starts (so a hand held by a dancing partner is at rest
relative to the partner's hand even while both move).

Every numeric step is vectorised over frames and joints; the only Python loops run
over characters, objects, the frames of the minimum duration (a handful) and the
rounds of the propagation (how many interactions one uninterrupted stretch of
contact holds; usually 1–3).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from .errors import SceneError

__all__ = [
    "GROUND",
    "ContactTolerances",
    "DEFAULT_TOLERANCES",
    "Event",
    "Interactions",
    "bone_radii",
    "detect_interactions",
    "merge_adjacent",
    "scan_interactions",
    "segment_distance",
    "prop_distance",
]

#: Object name of the ground plane in events.
GROUND = "ground"

#: Bones per bounding-box group in the broad phase of body contacts (see
#: :func:`_body_near`). Small groups prune more, large groups cost fewer box tests.
_GROUP_SIZE = 8
#: Seconds per time block of that broad phase (a joint's swept box over the block).
_BLOCK_S = 0.1
#: Below this many runs still being scanned, :func:`scan_interactions` walks them one
#: at a time (scalar steps beat a round of array code on a handful of runs).
_FEW_RUNS = 4
#: Elements per chunk in the exact narrow phase.
_CHUNK = 8192


@dataclass(frozen=True)
class ContactTolerances:
    """Tolerances of interaction detection, metres and seconds.

    Lengths are given for a person of :attr:`reference_stature` and scaled by the
    scene's mean stature over it (set ``reference_stature=None`` for absolute metres),
    so a scene in the wrong unit, or a child, gets proportionate tolerances and the
    result does not depend on the unit. Durations are converted to frames with the
    scene's fps, so the result does not depend on the sampling rate.

    Attributes
    ----------
    ground_distance : float
        A joint is *near* the ground while its height above the ground plane is at most
        this (m). Generous, because joints are bone centres: a standing ankle is
        7–12 cm up, and CMU floors drift by a few cm over a clip.
    body_distance : float
        A joint is near another character while its distance to the surface of one
        of that character's bones is at most this (m). Bones are capsules with the
        radii of the rendered body (:func:`bone_radii`: torso ~0.13 m, forearm
        ~0.04 m, finger 0.01 m); the tolerance covers the toucher's own flesh (a
        joint is a bone centre, 1-3 cm under the skin of a hand) and capture noise.
    prop_distance : float
        A joint is near a prop while its distance to the prop's surface is at most
        this (m); inside counts as 0.
    displacement : float
        The joint's position relative to the object may drift this far (m) from where
        the interaction started; beyond it the interaction ends.
    min_duration : float
        Both conditions must hold this long (s) before an interaction is recognised.
    reference_stature : float or None
        Stature (m) the lengths above are meant for; None: do not scale.
    """

    ground_distance: float = 0.15
    body_distance: float = 0.03
    prop_distance: float = 0.05
    displacement: float = 0.04
    min_duration: float = 0.1
    reference_stature: float | None = 1.70

    def __post_init__(self):
        for name in ("ground_distance", "body_distance", "prop_distance", "displacement",
                     "min_duration"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"ContactTolerances.{name} must be a positive number, got {v}")
        if self.reference_stature is not None and not self.reference_stature > 0:
            raise ValueError("ContactTolerances.reference_stature must be positive or None")

    def length_scale(self, scene) -> float:
        """Factor applied to the lengths for ``scene`` (mean stature / reference)."""
        if self.reference_stature is None:
            return 1.0
        h = float(np.mean([c.height for c in scene.characters]))
        return h / self.reference_stature if np.isfinite(h) and h > 0 else 1.0

    def min_frames(self, fps: float) -> int:
        """Frames the conditions must hold: ``min_duration`` at ``fps``, at least 2."""
        return max(2, int(math.ceil(self.min_duration * fps - 1e-9)))

    def scaled(self, factor: float) -> ContactTolerances:
        """A copy with every length multiplied by ``factor`` and no further scaling."""
        return replace(
            self,
            ground_distance=self.ground_distance * factor,
            body_distance=self.body_distance * factor,
            prop_distance=self.prop_distance * factor,
            displacement=self.displacement * factor,
            reference_stature=None,
        )


#: The defaults used everywhere unless a caller passes its own.
DEFAULT_TOLERANCES = ContactTolerances()


@dataclass(frozen=True)
class Event:
    """One interaction: ``character``'s joint ``joint`` rests against ``object``.

    Frames are *internal* indices (0 = the scene's first frame); ``end`` is the last
    frame of the interaction (inclusive). ``part`` names the touched bone of another
    character (by its parent joint), else None.
    """

    character: int
    joint: int
    object: str
    start: int
    end: int
    part: str | None = None

    @property
    def n_frames(self) -> int:
        return self.end - self.start + 1


@dataclass
class Interactions:
    """Interaction events of a scene.

    Attributes
    ----------
    events : list of Event
        Sorted by character, object, joint, start.
    active : list of ndarray of bool, shape (F, J_c)
        Per character: joint in an interaction with any object at that frame.
    objects : list of str
        Object names considered (ground, other characters, props).
    n_frames : int
    fps : float
    tolerances : ContactTolerances
        The tolerances actually used (already scaled, in metres).
    """

    events: list[Event]
    active: list[np.ndarray]
    objects: list[str]
    n_frames: int
    fps: float
    tolerances: ContactTolerances
    timings_s: dict = field(default_factory=dict)

    def for_character(self, c: int) -> list[Event]:
        return [e for e in self.events if e.character == c]

    def records(self, scene) -> list[dict]:
        """Events as JSON-ready dicts with names and SOURCE frame numbers."""
        out = []
        for e in self.events:
            ch = scene.characters[e.character]
            rec = {
                "character": ch.name,
                "joint": ch.joint_names[e.joint],
                "object": e.object,
                "start": int(scene.source_frame(e.start)),
                "end": int(scene.source_frame(e.end)),
            }
            if e.part is not None:
                rec["part"] = e.part
            out.append(rec)
        return out

    def counts(self, scene) -> dict[tuple[str, str], int]:
        """Number of events per (character name, object)."""
        out: dict[tuple[str, str], int] = {}
        for e in self.events:
            key = (scene.characters[e.character].name, e.object)
            out[key] = out.get(key, 0) + 1
        return out


# ----------------------------------------------------------------------- geometry


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


def prop_distance(points: np.ndarray, prop: dict) -> np.ndarray:
    """Distance (m) from ``points`` ``(..., 3)`` to a prop's surface; 0 inside.

    ``prop`` is a scene-manifest prop: ``type`` sphere (``center``, ``radius``), box
    (axis-aligned, ``center``, ``size`` = full edge lengths) or capsule (``a``, ``b``,
    ``radius``).
    """
    kind = prop.get("type")
    try:
        if kind == "sphere":
            c = np.asarray(prop["center"], dtype=float)
            d = np.linalg.norm(points - c, axis=-1) - float(prop["radius"])
        elif kind == "box":
            c = np.asarray(prop["center"], dtype=float)
            half = 0.5 * np.asarray(prop["size"], dtype=float)
            q = np.maximum(np.abs(points - c) - half, 0.0)
            d = np.sqrt((q * q).sum(-1))
        elif kind == "capsule":
            a = np.asarray(prop["a"], dtype=float)
            b = np.asarray(prop["b"], dtype=float)
            d = segment_distance(points, a, b) - float(prop["radius"])
        else:
            raise SceneError(f"prop '{prop.get('name', '?')}': unknown type {kind!r} "
                             "(expected sphere, box or capsule)")
    except KeyError as err:
        raise SceneError(f"prop '{prop.get('name', '?')}' ({kind}): missing field {err}") from None
    return np.maximum(d, 0.0)


# ----------------------------------------------------------------------- the scan


def scan_interactions(near: np.ndarray, displacement, *, min_frames: int, tolerance: float):
    """Interactions of every joint with one object: the seed-and-propagate rule.

    Parameters
    ----------
    near : ndarray of bool, shape (F, J)
        Joint within the distance tolerance of the object.
    displacement : callable
        ``displacement(j, s, g) -> ndarray (n,)``: distance (m) between the joint's
        position relative to the object at frame ``g`` and at the start frame ``s``,
        vectorised over equal-length integer arrays ``j, s, g``. Optional methods,
        used when present because they avoid gathers: ``span(j, s, lo, hi)``, the same
        for frames ``lo:hi`` of one joint; ``shifted(k, cols)``, the displacement
        between every frame ``f`` and ``f + k`` for the joints ``cols``, shape
        ``(F - k, len(cols))``.
    min_frames : int
        The conditions must hold on ``min_frames`` consecutive frames to start.
    tolerance : float
        Largest allowed relative displacement (m).

    Returns
    -------
    joints, starts, ends : ndarray of int
        One entry per interaction; ``ends`` inclusive. Sorted by joint, then start.

    Notes
    -----
    Scanning forward, an interaction starts at the first frame ``s`` where
    ``near[s:s+m]`` holds and every relative position in it is within ``tolerance``
    of the one at ``s``; it lasts while the joint stays near and within
    ``tolerance`` of its position at ``s``; the scan resumes at the first frame
    after it. Start frames are found for all frames at once; the propagation runs in
    rounds over all uninterrupted stretches of nearness (*runs*) together, each round
    testing the next few frames of every run, so the Python loop count is about the
    number of interactions in the busiest run, not the number of frames.
    """
    near = np.asarray(near, dtype=bool)
    n_f = near.shape[0]
    m = int(min_frames)
    empty = np.zeros(0, dtype=np.int64)
    # Only joints that come near at all (a handful: feet, hands): all per-joint arrays
    # below are over these columns; ``cols`` maps them back.
    cols = np.flatnonzero(near.any(axis=0))
    if n_f < m or cols.size == 0:
        return empty, empty, empty
    n_cols = near.shape[1]
    inner = displacement
    if cols.size < n_cols:
        near = near[:, cols]

        def displacement(j, s, g):
            return inner(cols[j], s, g)

        if hasattr(inner, "span"):
            displacement.span = lambda j, s, lo, hi: inner.span(int(cols[j]), s, lo, hi)
    n_j = near.shape[1]
    # Seeds: m consecutive near frames (cumulative sums) with a still relative position.
    csum = np.zeros((n_f + 1, n_j), dtype=np.int32)
    np.cumsum(near, axis=0, out=csum[1:])
    window = (csum[m:] - csum[:-m]) == m  # (F - m + 1, J)
    if hasattr(inner, "shifted"):
        # Static objects: compare whole shifted slices instead of gathering frames.
        for k in range(1, m):
            window &= inner.shifted(k, cols)[: n_f - m + 1] <= tolerance
        ff, jj = np.nonzero(window)
    else:
        ff, jj = np.nonzero(window)
        if hasattr(inner, "still"):  # relative positions at the start computed once
            ok = inner.still(cols[jj], ff, m, tolerance)
        else:
            ok = np.ones(ff.size, dtype=bool)
            for k in range(1, m):
                idx = np.flatnonzero(ok)
                if idx.size == 0:
                    break
                ok[idx] = displacement(jj[idx], ff[idx], ff[idx] + k) <= tolerance
        ff, jj = ff[ok], jj[ok]
    if ff.size == 0:
        return empty, empty, empty
    # next_seed[f, j]: first seed frame >= f (n_f if none).
    next_seed = np.full((n_f + 1, n_j), n_f, dtype=np.int64)
    next_seed[ff, jj] = ff
    next_seed = np.minimum.accumulate(next_seed[::-1], axis=0)[::-1]
    # Runs of near frames, joint-major so results come out sorted by joint then time.
    padded = np.zeros((n_j, n_f + 2), dtype=np.int8)
    padded[:, 1:-1] = near.T
    edges = np.flatnonzero(np.diff(padded, axis=1).ravel() != 0)
    # np.diff over a (J, F+2) array ravelled: row r holds F+1 entries.
    run_j, pos_in_row = np.divmod(edges, n_f + 1)
    run_j = run_j[::2]
    run_start, run_end = pos_in_row[::2], pos_in_row[1::2]  # end exclusive
    # Keep only runs that contain a seed.
    seed = next_seed[run_start, run_j]
    keep = seed < run_end
    run_j, run_end, seed = run_j[keep], run_end[keep], seed[keep]
    look = seed + m  # next frame to test; frames before it hold by the seed condition
    block = max(4 * m, 16)  # frames tested per run and round
    out_j, out_s, out_e = [], [], []
    while run_j.size > _FEW_RUNS:
        length = np.minimum(run_end - look, block)
        total = int(length.sum())
        ext = np.full(run_j.size, -1, dtype=np.int64)  # first failing frame, if found
        if total:
            seg = np.repeat(np.arange(run_j.size), length)
            first = np.cumsum(length) - length
            g = np.arange(total) - np.repeat(first, length) + np.repeat(look, length)
            hit = np.flatnonzero(displacement(run_j[seg], seed[seg], g) > tolerance)
            if hit.size:  # hits are sorted: each run's first one
                seg_hit = seg[hit]
                firsts = np.r_[True, seg_hit[1:] != seg_hit[:-1]]
                ext[seg_hit[firsts]] = g[hit[firsts]]
        exhausted = (ext < 0) & (look + length >= run_end)  # held to the end of the run
        ext[exhausted] = run_end[exhausted]
        done = ext >= 0
        out_j.append(run_j[done])
        out_s.append(seed[done])
        out_e.append(ext[done] - 1)
        # Runs still searching look further; finished ones seek their next seed.
        look = np.where(done, 0, look + length)
        nxt = next_seed[np.where(done, ext, 0), run_j]
        seed = np.where(done, nxt, seed)
        look = np.where(done, nxt + m, look)
        keep = seed < run_end
        run_j, run_end, seed, look = run_j[keep], run_end[keep], seed[keep], look[keep]
    # The last few runs (the busiest: a foot sliding on the floor for the whole clip)
    # one at a time: a round of array code costs more than these few scalar steps.
    for j, end, sd, lk in zip(run_j.tolist(), run_end.tolist(), seed.tolist(), look.tolist()):
        pieces_s, pieces_e = [], []
        while sd < end:
            ext = end
            while lk < end:
                hi = min(lk + block, end)
                if hasattr(displacement, "span"):
                    dist = displacement.span(j, sd, lk, hi)
                else:
                    g = np.arange(lk, hi)
                    dist = displacement(np.full(g.size, j), np.full(g.size, sd), g)
                far = np.flatnonzero(dist > tolerance)
                if far.size:
                    ext = lk + int(far[0])
                    break
                lk = hi
            pieces_s.append(sd)
            pieces_e.append(ext - 1)
            sd = int(next_seed[ext, j])
            lk = sd + m
        out_j.append(np.full(len(pieces_s), j, dtype=np.int64))
        out_s.append(np.array(pieces_s, dtype=np.int64))
        out_e.append(np.array(pieces_e, dtype=np.int64))
    joints = cols[np.concatenate(out_j)]
    starts = np.concatenate(out_s)
    ends = np.concatenate(out_e)
    order = np.lexsort((starts, joints))
    return joints[order], starts[order], ends[order]


# ----------------------------------------------------------------------- objects


class _StaticDisplacement:
    """Relative displacement against a static object: world positions ``x (F, J, 3)``.

    Called with index arrays ``(j, s, g)``; :meth:`span` does one joint and start over
    a range of frames with plain slices (no gathers), for the scalar path of the scan.
    """

    def __init__(self, x: np.ndarray):
        self.x = x

    def __call__(self, j, s, g):
        d = self.x[g, j] - self.x[s, j]
        return np.sqrt(np.einsum("ni,ni->n", d, d))

    def span(self, j: int, s: int, lo: int, hi: int):
        d = self.x[lo:hi, j] - self.x[s, j]
        return np.sqrt(np.einsum("ni,ni->n", d, d))

    def shifted(self, k: int, cols) -> np.ndarray:
        """``|x[f + k, j] - x[f, j]|`` for every frame f and joint j in ``cols``,
        shape (F - k, len(cols))."""
        xc = self.x[:, cols]
        d = xc[k:] - xc[:-k]
        return np.sqrt(np.einsum("fji,fji->fj", d, d))


def _bone_groups(n_links: int, size: int | None = None) -> np.ndarray:
    """Link indices in consecutive groups of ``size`` (the last padded), shape (G, size).

    Links are in BVH (depth-first) order, so consecutive links are neighbours in the
    body and a group's bounding box stays small.
    """
    size = size or _GROUP_SIZE
    n_groups = -(-n_links // size)
    idx = np.arange(n_groups * size)
    return np.minimum(idx, n_links - 1).reshape(n_groups, size)


def _group_padding_mask(n_links: int, size: int | None = None) -> np.ndarray:
    """False where :func:`_bone_groups` repeated a link to pad the last group."""
    size = size or _GROUP_SIZE
    return (np.arange(-(-n_links // size) * size) < n_links).reshape(-1, size)


def _block_boxes(z: np.ndarray, block: int):
    """Per block of ``block`` frames, the min and max of ``z (F, ...)`` over the block.

    Returns two arrays of shape ``(ceil(F / block), ...)``; the last block may be
    short (it repeats its last frame).
    """
    lo = z[0::block].copy()  # block starts: n_b rows
    hi = lo.copy()
    for t in range(1, block):  # elementwise over strided views: faster than a reduction
        rows = z[t::block]
        k = rows.shape[0]
        np.minimum(lo[:k], rows, out=lo[:k])
        np.maximum(hi[:k], rows, out=hi[:k])
    return lo, hi


def _segment_distance_soa(p, a, b):
    """:func:`segment_distance` on component-first arrays ``(3, n)``: fewer temporaries."""
    abx, aby, abz = b[0] - a[0], b[1] - a[1], b[2] - a[2]
    apx, apy, apz = p[0] - a[0], p[1] - a[1], p[2] - a[2]
    den = abx * abx + aby * aby + abz * abz
    num = apx * abx + apy * aby + apz * abz
    with np.errstate(invalid="ignore", divide="ignore"):
        t = np.where(den > 0, num / np.where(den > 0, den, 1.0), 0.0)
    dx, dy, dz = apx - t * abx, apy - t * aby, apz - t * abz
    lo, hi = t <= 0, t >= 1
    if lo.any():
        dx[lo], dy[lo], dz[lo] = apx[lo], apy[lo], apz[lo]
    if hi.any():
        dx[hi], dy[hi], dz[hi] = p[0][hi] - b[0][hi], p[1][hi] - b[1][hi], p[2][hi] - b[2][hi]
    return np.sqrt(dx * dx + dy * dy + dz * dz)


def bone_radii(character) -> np.ndarray:
    """Capsule radius (m) of each bone of ``character.skeleton.links``, shape (L,).

    The radii of the rendered body (:data:`snapcore.body.ROLE_RADII`, the larger
    semi-axis, by the role of the bone read from joint names), scaled with the
    character's stature like the body mesh. Bones the body does not draw (eyes
    inside the head, a floor-level root's bone up to the hips) get ``-inf``: they
    are not part of the surface and never touch anything.
    """
    from .body import DEFAULT_ROLE, REFERENCE_STATURE_M, ROLE_RADII, joint_roles

    sk = character.skeleton
    roles = joint_roles(sk.names, sk.parents)
    k = character.height / REFERENCE_STATURE_M
    out = np.empty(sk.links.shape[0])
    for i, (p, c) in enumerate(np.asarray(sk.links).reshape(-1, 2)):
        rp, rc = roles[p], roles[c]
        if rp == "hidden" or (rc == "hidden" and not sk.end_site[c]):
            out[i] = -np.inf
            continue
        role = rp  # the bone's radius follows its parent joint, as in snapcore.body
        if rp == "pelvis" and rc in ("spine", "chest", "neck"):
            role = "spine"
        elif rp == "spine" and rc in ("clavicle", "upperarm", "neck"):
            role = "chest"
        out[i] = max(ROLE_RADII.get(role, ROLE_RADII[DEFAULT_ROLE])) * k
    return out


def _body_near(x: np.ndarray, other, gap: float, *, radii: np.ndarray | None = None,
               block: int = 3, boxes: dict | None = None):
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
        Frames per block of the broad phase.
    boxes : dict, optional
        Cache of :func:`_block_boxes` results keyed by ``id`` of the positions array
        (a scene's characters are toucher and touched in turn).

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
    A bounding-volume hierarchy in time and space, equal to testing every bone at
    every frame (the tests check it). Per block of frames, each joint's swept box is
    tested against the other's swept whole-body box (bones grown by their reach
    ``radius + gap``), then against boxes of groups of neighbouring bones
    (:func:`_bone_groups`), then against each bone's box; only the surviving (frame,
    joint, bone) triples get the exact segment distance. Two people a metre apart
    keep a few percent.
    """
    n_f, n_j = x.shape[:2]
    links = other.skeleton.links
    n_l = links.shape[0]
    near = np.zeros((n_f, n_j), dtype=bool)
    bone = np.full((n_f, n_j), -1, dtype=np.int64)
    if n_l == 0 or n_f == 0:
        return near, bone
    y = other.positions
    radii = bone_radii(other) if radii is None else np.asarray(radii, dtype=float)
    reach = radii + gap
    # Boxes component-first, (3, B, ...): comparisons then combine three planes instead
    # of reducing over a length-3 axis, which NumPy does slowly.
    if boxes is None:
        boxes = {}
    for z in (x, y):
        if id(z) not in boxes:
            boxes[id(z)] = _block_boxes(z, block)
    jlo, jhi = boxes[id(x)]  # (B, J, 3)
    jlo = np.moveaxis(jlo, -1, 0).copy()  # (3, B, J)
    jhi = np.moveaxis(jhi, -1, 0).copy()
    ylo, yhi = boxes[id(y)]  # (B, Jo, 3)
    # Bone boxes arranged by group, (3, B, G, S): the last level gathers whole rows.
    g_links = _bone_groups(n_l)  # (G, S)
    la, lb = links[g_links, 0], links[g_links, 1]
    g_reach = reach[g_links]  # (G, S); -inf for bones that never touch
    llo = np.moveaxis(np.minimum(ylo[:, la], ylo[:, lb]) - g_reach[..., None], -1, 0).copy()
    lhi = np.moveaxis(np.maximum(yhi[:, la], yhi[:, lb]) + g_reach[..., None], -1, 0).copy()
    glo, ghi = llo.min(axis=3), lhi.max(axis=3)  # (3, B, G) group boxes
    blo, bhi = glo.min(axis=2), ghi.max(axis=2)  # (3, B) whole body
    n_g, size = g_links.shape

    def overlap(alo, ahi, olo, ohi):
        return ((ahi[0] >= olo[0]) & (alo[0] <= ohi[0]) & (ahi[1] >= olo[1])
                & (alo[1] <= ohi[1]) & (ahi[2] >= olo[2]) & (alo[2] <= ohi[2]))

    inside = overlap(jlo, jhi, blo[:, :, None], bhi[:, :, None])  # (B, J)
    cand = np.flatnonzero(inside)  # flat (block, joint)
    if cand.size == 0:
        return near, bone
    bi = cand // n_j
    lo_n = jlo.reshape(3, -1)[:, cand]  # (3, n)
    hi_n = jhi.reshape(3, -1)[:, cand]
    ov = overlap(lo_n[:, :, None], hi_n[:, :, None], glo[:, bi], ghi[:, bi])  # (n, G)
    n2, g2 = np.nonzero(ov)
    bg = bi[n2] * n_g + g2  # flat (block, group)
    ov3 = overlap(lo_n[:, n2, None], hi_n[:, n2, None],
                  llo.reshape(3, -1, size)[:, bg], lhi.reshape(3, -1, size)[:, bg])  # (n2, S)
    ov3 &= _group_padding_mask(n_l)[g2]  # the last group repeats its last bone
    r3, c3 = np.nonzero(ov3)
    if r3.size == 0:
        return near, bone
    link3, bj3 = g_links[g2[r3], c3], cand[n2[r3]]
    blk3, j3 = np.divmod(bj3, n_j)
    f4 = (blk3[:, None] * block + np.arange(block)).ravel()
    j4 = np.repeat(j3, block)
    l4 = np.repeat(link3, block)
    ok = f4 < n_f
    f4, j4, l4 = f4[ok], j4[ok], l4[ok]
    # Exact distances in chunks: small temporaries stay in cache (and, on machines
    # where fresh pages are expensive, in already-mapped memory).
    d = np.empty(f4.size)
    xf, yf = x.reshape(-1, 3), y.reshape(-1, 3)
    n_jo = y.shape[1]
    pi = f4 * n_j + j4
    ai = f4 * n_jo + links[l4, 0]
    bi = f4 * n_jo + links[l4, 1]
    for s in range(0, f4.size, _CHUNK):
        sl = slice(s, s + _CHUNK)
        d[sl] = _segment_distance_soa(xf.take(pi[sl], axis=0).T, yf.take(ai[sl], axis=0).T,
                                      yf.take(bi[sl], axis=0).T)
    d -= radii[l4]  # distance to the capsule surface
    hit = np.flatnonzero(d <= gap)
    if hit.size == 0:
        return near, bone
    # Nearest bone per (frame, joint). Candidates were generated in link order for
    # each (block, joint), so a stable sort by (frame, joint) keeps links ascending
    # and the first minimum is the lowest link among equal distances.
    key = f4[hit] * n_j + j4[hit]
    order = hit[np.argsort(key, kind="stable")]
    key = f4[order] * n_j + j4[order]
    starts = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
    dmin = np.minimum.reduceat(d[order], starts)
    at_min = np.flatnonzero(d[order] == np.repeat(dmin, np.diff(np.r_[starts, key.size])))
    seg = key[at_min]
    sel = order[at_min[np.r_[True, seg[1:] != seg[:-1]]]]  # first minimum of each
    near[f4[sel], j4[sel]] = True
    bone[f4[sel], j4[sel]] = l4[sel]
    return near, bone


class _BodyDisplacement:
    """Relative displacement in the frame of the bone nearest at the start frame.

    The position of joint j relative to bone (p → c) of ``other`` at frame g is
    ``R_p(g)^T (x_j(g) - y_p(g))``, with ``R_p`` the world rotation of the bone's
    parent joint (the bone moves rigidly with it). Same interface as
    :class:`_StaticDisplacement`.
    """

    def __init__(self, x: np.ndarray, other, bone: np.ndarray):
        self.x, self.bone = x, bone
        self.parent_of = other.skeleton.links[:, 0]
        self.y, self.rot = other.positions, other.rotations

    def _rel(self, frames, j, parent):
        return np.einsum("nki,nk->ni", self.rot[frames, parent],
                         self.x[frames, j] - self.y[frames, parent])

    def __call__(self, j, s, g):
        parent = self.parent_of[self.bone[s, j]]
        d = self._rel(g, j, parent) - self._rel(s, j, parent)
        return np.sqrt(np.einsum("ni,ni->n", d, d))

    def still(self, j, s, m: int, tolerance: float) -> np.ndarray:
        """For start frames ``s`` of joints ``j``: all of frames ``s+1 .. s+m-1`` within
        ``tolerance`` of the relative position at ``s``, shape (n,)."""
        parent = self.parent_of[self.bone[s, j]]
        start = self._rel(s, j, parent)
        ok = np.ones(s.size, dtype=bool)
        for k in range(1, m):
            idx = np.flatnonzero(ok)
            if idx.size == 0:
                break
            d = self._rel(s[idx] + k, j[idx], parent[idx]) - start[idx]
            ok[idx] = np.sqrt(np.einsum("ni,ni->n", d, d)) <= tolerance
        return ok

    def span(self, j: int, s: int, lo: int, hi: int):
        p = int(self.parent_of[self.bone[s, j]])
        start = self.rot[s, p].T @ (self.x[s, j] - self.y[s, p])
        rel = np.einsum("nki,nk->ni", self.rot[lo:hi, p], self.x[lo:hi, j] - self.y[lo:hi, p])
        d = rel - start
        return np.sqrt(np.einsum("ni,ni->n", d, d))


# ----------------------------------------------------------------------- public


def merge_adjacent(joints, starts, ends):
    """Join interactions of one joint that follow each other without a free frame.

    When an interaction ends because the relative position drifted beyond the
    tolerance and a new one starts on the very next frame, the joint never left the
    object: the contact slid and re-anchored (a landing foot settling, a pivot). The
    interaction *state* is continuous, so its onset and release are those of the
    union. Inputs sorted by joint, then start (as :func:`scan_interactions` returns).

    Returns
    -------
    joints, starts, ends, first : ndarray of int
        The merged interactions and, for each, the index of its first input piece.
    """
    if joints.size == 0:
        return joints, starts, ends, np.zeros(0, dtype=np.int64)
    new = np.r_[True, (joints[1:] != joints[:-1]) | (starts[1:] != ends[:-1] + 1)]
    first = np.flatnonzero(new)
    last = np.r_[first[1:] - 1, joints.size - 1]
    return joints[first], starts[first], ends[last], first


def detect_interactions(scene, *, tolerances: ContactTolerances = DEFAULT_TOLERANCES,
                        ground: bool = True, bodies: bool = True, props: bool = True,
                        merge: bool = True) -> Interactions:
    """Interaction events of every joint of every character in ``scene``.

    Parameters
    ----------
    scene : Scene
    tolerances : ContactTolerances, optional
        Distances in metres for a person of ``tolerances.reference_stature`` (scaled
        to the scene's people), durations in seconds.
    ground, bodies, props : bool, optional
        Which kinds of object to test (all by default).
    merge : bool, optional
        Join back-to-back interactions of one joint and object (:func:`merge_adjacent`).
        METHOD's rule alone splits one foot contact into two when the landing foot
        settles by more than the tolerance, which would put a spurious release and
        onset inside the stance; merging makes events the maximal stretches of
        continuous interaction. ``False`` gives the rule's raw pieces.

    Returns
    -------
    Interactions
        Events with internal frame indices; ``Interactions.records(scene)`` gives
        them with names and source frame numbers.

    Notes
    -----
    Every joint may touch anything (hands on the floor, a knee on a partner); the
    joints of one foot produce correlated events, which METHOD accepts: the
    probability of eq. 6 is per joint. Another character's body is its bones
    (``skeleton.links``) as capsules with the radii of the rendered body
    (:func:`bone_radii`); characters do not touch themselves.
    """
    import time

    t0 = time.perf_counter()
    tol = tolerances.scaled(tolerances.length_scale(scene))
    m = tol.min_frames(scene.fps)
    block = max(1, int(round(_BLOCK_S * scene.fps)))
    n_f = scene.n_frames
    events: list[Event] = []
    active = [np.zeros((n_f, c.n_joints), dtype=bool) for c in scene.characters]
    prop_list = list(scene.props) if props else []
    prop_names = [str(p.get("name", f"prop{i}")) for i, p in enumerate(prop_list)]
    objects = ([GROUND] if ground else []) + (
        [c.name for c in scene.characters] if bodies and scene.n_characters > 1 else []
    ) + prop_names

    def add(ci, name, found, part_of=None):
        js, ss, es = found
        first = np.arange(js.size)
        if merge:
            js, ss, es, first = merge_adjacent(js, ss, es)
        act = active[ci]
        for j, s, e, k in zip(js.tolist(), ss.tolist(), es.tolist(), first.tolist()):
            events.append(Event(ci, j, name, s, e, part_of(k) if part_of else None))
            act[s:e + 1, j] = True

    radii = [bone_radii(c) for c in scene.characters] if bodies else []
    boxes: dict = {}  # block boxes per character, shared by both directions
    for ci, c in enumerate(scene.characters):
        x = c.positions
        static = _StaticDisplacement(x)
        if ground:
            near = x[..., 1] - scene.ground <= tol.ground_distance
            add(ci, GROUND, scan_interactions(near, static, min_frames=m,
                                              tolerance=tol.displacement))
        if bodies:
            for oi, other in enumerate(scene.characters):
                if oi == ci:
                    continue
                near, bone = _body_near(x, other, tol.body_distance, radii=radii[oi],
                                        block=block, boxes=boxes)
                found = scan_interactions(near, _BodyDisplacement(x, other, bone),
                                          min_frames=m, tolerance=tol.displacement)
                parent = other.skeleton.links[:, 0]
                js, ss = found[0], found[1]

                def part_of(k, js=js, ss=ss, bone=bone, parent=parent, names=other.joint_names):
                    return names[parent[bone[ss[k], js[k]]]]

                add(ci, other.name, found, part_of)
        for name, prop in zip(prop_names, prop_list):
            near = prop_distance(x, prop) <= tol.prop_distance
            add(ci, name, scan_interactions(near, static, min_frames=m,
                                            tolerance=tol.displacement))
    rank = {name: i for i, name in enumerate(objects)}
    events.sort(key=lambda e: (e.character, rank.get(e.object, 0), e.joint, e.start))
    timings = {"contacts": time.perf_counter() - t0}
    return Interactions(events, active, objects, n_f, float(scene.fps), tol, timings)
