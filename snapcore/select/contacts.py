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
(its bones as capsules, :mod:`snapcore.select.capsules`) and the static props of
the scene manifest (sphere, box, capsule; metres). The position of a joint relative
to the ground or a prop is its world position (those objects do not move); relative
to another body it is the position in the frame of the touched bone, the bone nearest
the joint when the interaction starts (so a hand held by a dancing partner is at rest
relative to the partner's hand even while both move).

Every numeric step is vectorised over frames and joints; the only Python loops run
over characters, objects, the frames of the minimum duration (a handful) and the
rounds of the propagation (how many interactions one uninterrupted stretch of
contact holds), which treat every joint and object of the scene at once.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any

import numpy as np

from snapcore.errors import SceneError, SelectionError
from snapcore.motion.anatomy import REFERENCE_STATURE_M
from snapcore.select.capsules import BODY_BLOCK_S, body_near, bone_radii, segment_distance
from snapcore.select.signals import merge_adjacent, nonzero_rows

if TYPE_CHECKING:
    from snapcore.motion.scene import Character, Scene

__all__ = [
    "GROUND",
    "ContactParams",
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

#: Below this many runs still being scanned, :func:`scan_interactions` finishes them
#: from one window of entries and walks their chains one at a time (a round of array
#: code for a handful of runs costs more than those scalar steps).
_FEW_RUNS = 8
#: Entries after the first ``min_frames`` tested at once for every start in those
#: last runs (longer interactions are walked on in slices).
_BAND = 24
#: A coordinate beyond any tolerance (m): stands for "the run has ended".
_FAR = 1e150


@dataclass(frozen=True)
class ContactParams:
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
    reference_stature: float | None = REFERENCE_STATURE_M

    def __post_init__(self) -> None:
        for name in (
            "ground_distance",
            "body_distance",
            "prop_distance",
            "displacement",
            "min_duration",
        ):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise SelectionError(f"ContactParams.{name} must be a positive number, got {v}")
        if self.reference_stature is not None and not self.reference_stature > 0:
            raise SelectionError("ContactParams.reference_stature must be positive or None")

    def length_scale(self, scene: Scene) -> float:
        """Factor applied to the lengths for ``scene`` (mean stature / reference)."""
        if self.reference_stature is None:
            return 1.0
        h = float(np.mean([c.height for c in scene.characters]))
        return h / self.reference_stature if np.isfinite(h) and h > 0 else 1.0

    def min_frames(self, fps: float) -> int:
        """Frames the conditions must hold: ``min_duration`` at ``fps``, at least 2."""
        return max(2, int(math.ceil(self.min_duration * fps - 1e-9)))

    def scaled(self, factor: float) -> ContactParams:
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
DEFAULT_TOLERANCES = ContactParams()


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
    tolerances : ContactParams
        The tolerances actually used (already scaled, in metres).
    """

    events: list[Event]
    active: list[np.ndarray]
    objects: list[str]
    n_frames: int
    fps: float
    tolerances: ContactParams
    timings_s: dict = field(default_factory=dict)

    def for_character(self, c: int) -> list[Event]:
        return [e for e in self.events if e.character == c]

    def records(self, scene: Scene) -> list[dict]:
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

    def counts(self, scene: Scene) -> dict[tuple[str, str], int]:
        """Number of events per (character name, object)."""
        out: dict[tuple[str, str], int] = {}
        for e in self.events:
            key = (scene.characters[e.character].name, e.object)
            out[key] = out.get(key, 0) + 1
        return out


# ----------------------------------------------------------------------- geometry


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
            raise SceneError(
                f"prop '{prop.get('name', '?')}': unknown type {kind!r} "
                "(expected sphere, box or capsule)"
            )
    except KeyError as err:
        raise SceneError(f"prop '{prop.get('name', '?')}' ({kind}): missing field {err}") from None
    return np.maximum(d, 0.0)


# ----------------------------------------------------------------------- the scan


def scan_interactions(
    near: np.ndarray,
    displacement: _StaticDisplacement | _BodyDisplacement,
    *,
    min_frames: int,
    tolerance: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Interactions of every joint with one object: the seed-and-propagate rule.

    Parameters
    ----------
    near : ndarray of bool, shape (F, J)
        Joint within the distance tolerance of the object.
    displacement : callable
        ``displacement(j, s, g) -> ndarray (n,)``: distance (m) between the joint's
        position relative to the object at frame ``g`` and at the start frame ``s``,
        vectorised over equal-length integer arrays ``j, s, g``. Optional methods,
        used when present because they replace gathers by slices:
        ``relative(j, f) -> ndarray (3, n)``, the joint's position relative to the
        object in the reference frame chosen at frame ``f`` (its difference between
        frames is the displacement when both use the same reference), and
        ``reference(j, f) -> ndarray (n,)`` of int naming that reference frame
        (absent: one reference for all, a static object).
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
    after it. See :func:`_scan` for how this sequential rule is vectorised.
    """
    near = np.asarray(near, dtype=bool)
    return _scan([near], [displacement], int(min_frames), float(tolerance))[0]


def _scan(nears: list, displacements: list, m: int, tol: float) -> list:
    """:func:`scan_interactions` of several (near, displacement) problems at once.

    The near frames of all problems become one flat list of *entries* (problem, then
    joint, then frame); an uninterrupted stretch of nearness of one joint is a *run*
    of consecutive entries. Seeds (start frames) are found for all entries at once.
    The propagation runs in rounds over all runs of all problems together, each round
    testing a window of the next entries after every run's current start; a run whose
    interaction ended seeks its next seed. The Python loop count is about the number
    of interactions in the busiest runs, not the number of frames. The last few runs
    (a foot sliding on the floor for the whole clip, say) hold many short
    interactions in a row: for them, where an interaction starting at each of their
    entries would end is found at once within a band of entries, and their chains are
    then followed in Python. Relative positions come once per entry (``relative``)
    where the displacements offer them, so the tests are differences of slices and
    gathers of one array.
    """
    empty = np.zeros(0, dtype=np.int64)
    found = [(empty, empty, empty)] * len(nears)
    parts = []
    for near in nears:
        cols = np.flatnonzero(near.any(axis=0))
        jj, ff = np.divmod(np.flatnonzero(near[:, cols].T.copy()), near.shape[0])
        parts.append((cols.take(jj), ff))  # joint-major, frames ascending
    sizes = [jl.size for jl, _ in parts]
    n = sum(sizes)
    if n == 0:
        return found
    prob = np.repeat(np.arange(len(nears)), sizes)
    joint = np.concatenate([jl for jl, _ in parts])  # column of the problem's near
    frame = np.concatenate([ff for _, ff in parts])
    # Runs: consecutive entries of one problem and joint on consecutive frames.
    new = np.ones(n, dtype=bool)
    new[1:] = (prob[1:] != prob[:-1]) | (joint[1:] != joint[:-1]) | (frame[1:] != frame[:-1] + 1)
    first = np.flatnonzero(new)
    run_stop = np.append(first[1:], n)  # exclusive entry index
    stop = np.repeat(run_stop, run_stop - first)
    dist = _Distances(displacements, sizes, prob, joint, frame)
    # Seeds: m near frames in a row with every relative position within tolerance.
    cand = np.flatnonzero(stop - np.arange(n) >= m)
    cand = cand[dist.still(cand, m, tol)]
    if cand.size == 0:
        return found
    nxt = np.full(n + 1, n, dtype=np.int64)  # nxt[i]: first seed entry >= i
    nxt[cand] = cand
    nxt = np.minimum.accumulate(nxt[::-1])[::-1]
    seed = nxt.take(first)
    keep = seed < run_stop
    seed, run_stop = seed[keep], run_stop[keep]
    look = seed + m  # next entry to test; the seed condition covers those before it
    width = max(4 * m, 16)  # entries tested per run and round
    offsets = np.arange(width)
    out_s, out_e = [], []  # first and last entry of each interaction
    while seed.size > _FEW_RUNS:
        target = look[:, None] + offsets  # (runs, width)
        beyond = target >= run_stop[:, None]  # past the run: where it ends
        np.minimum(target, n - 1, out=target)
        far = dist.far(seed, target, beyond, tol)
        far |= beyond
        k = far.argmax(axis=1)
        done = np.flatnonzero(far.reshape(-1).take(k + offsets.size * np.arange(seed.size)))
        ext = look.take(done) + k.take(done)  # first entry not in the interaction
        out_s.append(seed.take(done))
        out_e.append(ext - 1)
        # Finished runs seek their next seed, the others look further.
        look += width
        seed[done] = nxt.take(ext)
        look[done] = seed.take(done) + m
        keep = seed < run_stop
        seed, run_stop, look = seed[keep], run_stop[keep], look[keep]
    # The last few runs (the busiest: a foot sliding on the floor for the whole clip),
    # where a round of array code would finish one short interaction per run: where
    # every entry of them would end as a start, within a band of the next entries,
    # all at once; then their chains one at a time, walking on past the band where an
    # interaction is longer.
    tail_s, tail_e = [], []
    ends = dist.band_ends(seed, run_stop, m, _BAND, tol).tolist()
    at = np.cumsum(np.r_[0, run_stop - seed]).tolist()  # each run's rows in ``ends``
    for r, (sd, end) in enumerate(zip(seed.tolist(), run_stop.tolist())):
        base = at[r] - sd
        while sd < end:
            ext = ends[base + sd]
            if ext < 0:  # not within the band: walk on in growing slices
                lk, ext, w = sd + m + _BAND, end, width
                while lk < end:
                    hi = min(lk + w, end)
                    far = np.flatnonzero(dist.span(sd, lk, hi) > tol)
                    if far.size:
                        ext = lk + int(far[0])
                        break
                    lk, w = hi, 2 * w
            tail_s.append(sd)
            tail_e.append(ext - 1)
            sd = int(nxt[ext])
    out_s.append(np.array(tail_s, dtype=np.int64))
    out_e.append(np.array(tail_e, dtype=np.int64))
    starts = np.concatenate(out_s)
    order = np.argsort(starts, kind="stable")  # entry order: problem, joint, frame
    starts, ends = starts[order], np.concatenate(out_e)[order]
    bounds = np.searchsorted(prob.take(starts), np.arange(len(nears) + 1))
    for p in range(len(nears)):
        s, e = starts[bounds[p] : bounds[p + 1]], ends[bounds[p] : bounds[p + 1]]
        found[p] = (joint.take(s), frame.take(s), frame.take(e))
    return found


class _Distances:
    """Relative displacement between entries of :func:`_scan` (same problem and run).

    With every displacement offering ``relative``, the relative positions of all
    entries are computed once, component-first ``(3, n)``; the distance between two
    entries is then that of their positions, except where their reference frames
    differ (a joint that slid from one bone of a partner to the next), which asks
    the displacement itself. Otherwise every distance asks the displacement.
    """

    def __init__(self, displacements: list, sizes: list, prob: Any, joint: Any, frame: Any) -> None:
        self.displacements, self.prob, self.joint, self.frame = displacements, prob, joint, frame
        self.offsets = np.cumsum([0] + list(sizes))
        self.rel = self.ref = None
        if all(hasattr(d, "relative") for d in displacements):
            bounds = list(zip(self.offsets[:-1], self.offsets[1:]))
            self.rel = np.concatenate(
                [d.relative(joint[a:b], frame[a:b]) for d, (a, b) in zip(displacements, bounds)],
                axis=1,
            )
            if any(hasattr(d, "reference") for d in displacements):
                self.ref = np.concatenate(
                    [
                        d.reference(joint[a:b], frame[a:b])
                        if hasattr(d, "reference")
                        else np.zeros(b - a, dtype=np.int64)
                        for d, (a, b) in zip(displacements, bounds)
                    ]
                )

    def _ask(self, s: np.ndarray, g: np.ndarray) -> np.ndarray:
        """Distances from the displacements themselves (entries ``s``, ``g``)."""
        if s.size == 0:
            return np.zeros(0)
        prob = self.prob.take(s)
        if prob.min() == prob.max():  # the usual case: one problem
            p = int(prob[0])
            return self.displacements[p](self.joint.take(s), self.frame.take(s), self.frame.take(g))
        out = np.empty(s.size)
        for p in np.unique(prob).tolist():
            sel = np.flatnonzero(prob == p)
            ss, gg = s.take(sel), g.take(sel)
            out[sel] = self.displacements[p](
                self.joint.take(ss), self.frame.take(ss), self.frame.take(gg)
            )
        return out

    def far(self, s: np.ndarray, t: np.ndarray, skip: np.ndarray, tol: float) -> np.ndarray:
        """``distance(s[r], t[r, c]) > tol`` for entries ``s (R,)``, ``t (R, W)``; pairs
        where ``skip`` is set may be anything (not asked of the displacements)."""
        if self.rel is None:
            out = np.ones(t.shape, dtype=bool)
            r, c = nonzero_rows(~skip)
            out[r, c] = self._ask(s.take(r), t[r, c]) > tol
            return out
        d = self.rel.take(t, axis=1)  # (3, R, W)
        d -= self.rel.take(s, axis=1)[:, :, None]
        d = _norm(d)
        if self.ref is not None:
            r, c = nonzero_rows((self.ref.take(t) != self.ref.take(s)[:, None]) & ~skip)
            if r.size:
                d[r, c] = self._ask(s.take(r), t[r, c])
        return d > tol

    def still(self, s: np.ndarray, m: int, tol: float) -> np.ndarray:
        """Entries ``s`` whose next ``m - 1`` entries (in their run) all lie within
        ``tol`` of them, shape (len(s),) of bool."""
        ok = np.ones(s.size, dtype=bool)
        if self.rel is None:
            for k in range(1, m):
                idx = np.flatnonzero(ok)
                ok[idx] = self._ask(s.take(idx), s.take(idx) + k) <= tol
            return ok
        n = self.rel.shape[1]
        within, bad = [], []
        for k in range(1, m):  # shifted slices, no gathers
            within.append(_norm(self.rel[:, k:] - self.rel[:, :-k]).take(s) <= tol)
            if self.ref is not None:  # pairs in different reference frames
                bad.append(np.flatnonzero((self.ref[k:] != self.ref[: n - k]).take(s)))
        if bad and sum(b.size for b in bad):  # ask those all at once
            i = np.concatenate(bad)
            shift = np.repeat(np.arange(1, m), [b.size for b in bad])
            asked = self._ask(s.take(i), s.take(i) + shift) <= tol
            for kk, b, a in zip(
                range(1, m), bad, np.split(asked, np.cumsum([b.size for b in bad])[:-1])
            ):
                within[kk - 1][b] = a
        for w in within:
            ok &= w
        return ok

    def band_ends(self, starts: Any, stops: Any, m: int, band: int, tol: float) -> np.ndarray:
        """Where an interaction starting at each entry of some runs would end.

        For every entry ``i`` of ``starts[r] .. stops[r] - 1`` of each run r (runs
        concatenated): the first entry of ``i + m .. i + m + band - 1`` farther than
        ``tol`` from ``i``, or ``stops[r]`` when the run ends first; -1 if neither.
        """
        lengths = stops - starts
        total = int(lengths.sum())
        if total == 0:
            return np.zeros(0, dtype=np.int64)
        gap = m + band  # columns after each run standing for its end
        first = np.cumsum(np.r_[0, lengths[:-1] + gap])  # each run's first column
        col = np.arange(total) + np.repeat(first - np.cumsum(np.r_[0, lengths[:-1]]), lengths)
        entry = np.arange(total) + np.repeat(starts - np.cumsum(np.r_[0, lengths[:-1]]), lengths)
        n_cols = int(first[-1] + lengths[-1] + gap)
        if self.rel is None:  # ask the displacements for each offset in the band
            far = np.ones((total, band), dtype=bool)
            stop_of = np.repeat(stops, lengths)
            for step in range(band):
                t = entry + m + step
                inside = np.flatnonzero(t < stop_of)
                far[inside, step] = self._ask(entry.take(inside), t.take(inside)) > tol
        else:
            from numpy.lib.stride_tricks import sliding_window_view

            # The runs side by side with far-away columns between them (beyond every
            # tolerance: the end of the run), so the band is a view, not a gather.
            buf = np.full((3, n_cols), _FAR)
            buf[:, col] = self.rel.take(entry, axis=1)
            d = (
                sliding_window_view(buf, band, axis=1)[:, m : m + n_cols - gap]
                - buf[:, : n_cols - gap, None]
            )
            d *= d
            d2 = d[0] + d[1]
            d2 += d[2]
            far = (np.sqrt(d2, out=d2) > tol)[col]  # (total, band)
            if self.ref is not None:
                ref = self.ref.take(entry)
                row0 = np.cumsum(np.r_[0, lengths[:-1]])  # each run's first row
                varies = np.flatnonzero(
                    np.minimum.reduceat(ref, row0) != np.maximum.reduceat(ref, row0)
                )
                if varies.size:  # a joint slid to another bone: ask where references differ
                    stop_of = np.repeat(stops, lengths)
                    for r in varies.tolist():
                        rows = np.arange(row0[r], row0[r] + lengths[r])
                        t = entry.take(rows)[:, None] + m + np.arange(band)
                        ok = t < stop_of.take(rows)[:, None]
                        bad = ok & (
                            self.ref.take(np.minimum(t, self.ref.size - 1))
                            != ref.take(rows)[:, None]
                        )
                        i, k = nonzero_rows(bad)
                        if i.size:
                            far[rows[i], k] = self._ask(entry.take(rows[i]), t[i, k]) > tol
        k = far.argmax(axis=1)
        ends = entry + m + k
        np.minimum(ends, np.repeat(stops, lengths), out=ends)
        ends[~far[np.arange(total), k]] = -1
        return ends

    def span(self, s: int, lo: int, hi: int) -> np.ndarray:
        """Distances from entry ``s`` to entries ``lo .. hi - 1``."""
        if self.rel is None:
            return self._ask(np.full(hi - lo, s), np.arange(lo, hi))
        d = self.rel[:, lo:hi] - self.rel[:, s : s + 1]
        d = _norm(d)
        if self.ref is not None:
            bad = np.flatnonzero(self.ref[lo:hi] != self.ref[s])
            if bad.size:
                d[bad] = self._ask(np.full(bad.size, s), bad + lo)
        return d


def _norm(d: np.ndarray) -> np.ndarray:
    """Euclidean norm of component-first vectors ``(3, n)`` (overwrites ``d``)."""
    d *= d
    out = d[0] + d[1]
    out += d[2]
    return np.sqrt(out, out=out)


# ----------------------------------------------------------------------- objects


class _StaticDisplacement:
    """Relative displacement against a static object: world positions ``x (F, J, 3)``."""

    def __init__(self, x: np.ndarray) -> None:
        self.x = x

    def __call__(self, j: np.ndarray, s: np.ndarray, g: np.ndarray) -> np.ndarray:
        d = self.x[g, j] - self.x[s, j]
        return np.sqrt(np.einsum("ni,ni->n", d, d))

    def relative(self, j: np.ndarray, f: np.ndarray) -> np.ndarray:
        return np.ascontiguousarray(self.x.reshape(-1, 3).take(f * self.x.shape[1] + j, axis=0).T)


class _BodyDisplacement:
    """Relative displacement in the frame of the bone nearest at the start frame.

    The position of joint j relative to bone (p → c) of ``other`` at frame g is
    ``R_p(g)^T (x_j(g) - y_p(g))``, with ``R_p`` the world rotation of the bone's
    parent joint (the bone moves rigidly with it). Same interface as
    :class:`_StaticDisplacement`, plus ``reference``: the parent joint p of the bone
    nearest at that frame.
    """

    def __init__(self, x: np.ndarray, other: Character, bone: np.ndarray) -> None:
        self.x, self.bone = x, bone
        self.parent_of = other.skeleton.links[:, 0]
        self.y, self.rot = other.positions, other.rotations

    def _rel(self, frames: np.ndarray, j: np.ndarray, parent: np.ndarray) -> np.ndarray:
        """``R_p^T (x_j - y_p)`` at ``frames``, component-first (3, n)."""
        rows = frames * self.y.shape[1] + parent
        # Copied component-first, so the products below run on contiguous rows (on the
        # transposed views they stride by 9 and 3 doubles: ~30% slower in all).
        r = self.rot.reshape(-1, 9).take(rows, axis=0).T.copy()  # r[3k + i] = R[k, i]
        v = (
            self.x.reshape(-1, 3).take(frames * self.x.shape[1] + j, axis=0)
            - self.y.reshape(-1, 3).take(rows, axis=0)
        ).T.copy()
        out = r[0:3] * v[0]
        out += r[3:6] * v[1]
        out += r[6:9] * v[2]
        return out

    def __call__(self, j: np.ndarray, s: np.ndarray, g: np.ndarray) -> np.ndarray:
        n = np.size(j)
        parent = np.tile(self.parent_of.take(self.bone[s, j]), 2)
        rel = self._rel(np.concatenate([g, s]), np.tile(j, 2), parent)  # both frames at once
        return _norm(rel[:, :n] - rel[:, n:])

    def reference(self, j: np.ndarray, f: np.ndarray) -> np.ndarray:
        return self.parent_of.take(self.bone[f, j])

    def relative(self, j: np.ndarray, f: np.ndarray) -> np.ndarray:
        return self._rel(f, j, self.reference(j, f))


# ----------------------------------------------------------------------- public


def detect_interactions(
    scene: Scene,
    *,
    tolerances: ContactParams = DEFAULT_TOLERANCES,
    ground: bool = True,
    bodies: bool = True,
    props: bool = True,
    merge: bool = True,
) -> Interactions:
    """Interaction events of every joint of every character in ``scene``.

    Parameters
    ----------
    scene : Scene
    tolerances : ContactParams, optional
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

    Examples
    --------
    In the synthetic push the pusher's palms touch the other person's chest from
    ``PUSH_CONTACT_S`` = 1.3 s to ``PUSH_CONTACT_END_S`` = 1.6 s:

    >>> from snapcore import detect_interactions
    >>> from snapcore.motion.synth import synth_scene
    >>> scene = synth_scene("push")
    >>> found = detect_interactions(scene)
    >>> found.objects
    ['ground', 'pusher', 'pushed']
    >>> pusher = scene.characters[0]
    >>> [(round(e.start / scene.fps, 2), round(e.end / scene.fps, 2))
    ...  for e in found.for_character(0)
    ...  if e.object == "pushed" and pusher.joint_names[e.joint] == "RightHand"]
    [(1.3, 1.6)]
    """
    import time

    t0 = time.perf_counter()
    tol = tolerances.scaled(tolerances.length_scale(scene))
    m = tol.min_frames(scene.fps)
    block = max(1, int(round(BODY_BLOCK_S * scene.fps)))
    n_f = scene.n_frames
    prop_list = list(scene.props) if props else []
    prop_names = [str(p.get("name", f"prop{i}")) for i, p in enumerate(prop_list)]
    objects = (
        ([GROUND] if ground else [])
        + ([c.name for c in scene.characters] if bodies and scene.n_characters > 1 else [])
        + prop_names
    )
    # Every (character, object) pair is one scan problem; all are scanned together.
    # character, object, and for a body the nearest bone (F, J) and that character
    problems: list[tuple[int, str, tuple[np.ndarray, Character] | None]] = []
    nears: list[np.ndarray] = []
    displacements: list[_StaticDisplacement | _BodyDisplacement] = []
    radii = [bone_radii(c) for c in scene.characters] if bodies else []
    cache: dict = {}  # prepared positions per character, shared by both directions
    for ci, c in enumerate(scene.characters):
        x = c.positions
        static = _StaticDisplacement(x)
        if ground:
            problems.append((ci, GROUND, None))
            nears.append(x[..., 1] - scene.ground <= tol.ground_distance)
            displacements.append(static)
        if bodies:
            for oi, other in enumerate(scene.characters):
                if oi == ci:
                    continue
                near, bone = body_near(
                    x, other, tol.body_distance, radii=radii[oi], block=block, cache=cache
                )
                problems.append((ci, other.name, (bone, other)))
                nears.append(near)
                displacements.append(_BodyDisplacement(x, other, bone))
        for name, prop in zip(prop_names, prop_list):
            problems.append((ci, name, None))
            nears.append(prop_distance(x, prop) <= tol.prop_distance)
            displacements.append(static)
    events: list[Event] = []
    active = [np.zeros((n_f, c.n_joints), dtype=bool) for c in scene.characters]
    for (ci, name, touched), (js, ss, es) in zip(
        problems, _scan(nears, displacements, m, tol.displacement)
    ):
        if merge:
            js, ss, es, _ = merge_adjacent(js, ss, es)
        parts = [None] * js.size
        if touched is not None:  # the touched bone (by its parent joint) at the start
            bone, other = touched
            names = other.joint_names
            parts = [names[p] for p in other.skeleton.links[bone[ss, js], 0].tolist()]
        act = active[ci]
        for j, s, e, part in zip(js.tolist(), ss.tolist(), es.tolist(), parts):
            events.append(_event(ci, j, name, s, e, part))
            act[s : e + 1, j] = True
    if len(set(objects)) < len(objects):  # else already in order: problems were made
        rank = {name: i for i, name in enumerate(objects)}  # by character and object
        events.sort(key=lambda e: (e.character, rank.get(e.object, 0), e.joint, e.start))
    timings = {"contacts": time.perf_counter() - t0}
    return Interactions(events, active, objects, n_f, float(scene.fps), tol, timings)


def _event(character: int, joint: int, obj: str, start: int, end: int, part: str | None) -> Event:
    """``Event(character, joint, obj, start, end, part)`` without the frozen dataclass's
    per-field ``object.__setattr__`` (a third of the time for the hundreds of events of
    a long clip); the object is the same."""
    ev = object.__new__(Event)
    d = ev.__dict__
    d["character"], d["joint"], d["object"] = character, joint, obj
    d["start"], d["end"], d["part"] = start, end, part
    return ev
