"""The paper's pose selector: pose entropy (paper §3.1, METHOD §1; method ``paper``).

The informative pose of a motion is the frame of highest *pose entropy*

    H(i) = w_local H*_local(i) + w_global H*_global(i)            (eq. 8-9)

where ``H*`` is min-max normalisation over the frames of the scene and

- the **local** term measures how sharply the joints turn, weighted by limb length
  and by how fast the joint rotates (eq. 3-5):
  ``p_i = sum_j l_j |dm_ji| kappa_ji``, normalised to ``sum_i p_i = 1``, and
  ``H_local(i) = -p_i log2 p_i``;
- the **global** term counts interaction events (eq. 6-7): joint j has interaction
  probability ``p_j = N_interaction(j) / F`` and
  ``H_global(i) = -sum_{j with an event at i} p_j log2 p_j``; events come from
  :mod:`snapcore.select.contacts`.

Several characters: per-character terms are summed per frame before normalising.
The selected pose is the argmax; :func:`select_pose_paper` also returns the top-k
distinct peaks (:func:`~snapcore.select.pose_selection.top_peaks`). It is not the
default selector (that is :mod:`snapcore.select.story`); what every selector returns
lives in :mod:`snapcore.select.pose_selection`; the trajectory smoothing and min-max
normalisation it shares with them in :mod:`snapcore.select.signals`.

Everything is vectorised over frames and joints (one Python loop over characters).
"""

from __future__ import annotations

import math
import time
import warnings

import numpy as np

from snapcore.errors import SelectionError
from snapcore.motion.anatomy import REFERENCE_STATURE_M
from snapcore.motion.kinematics import matrix_to_quat
from snapcore.select.contacts import (
    DEFAULT_TOLERANCES,
    ContactParams,
    Interactions,
    detect_interactions,
)
from snapcore.select.pose_selection import (
    MIN_SEPARATION_S,
    PoseEntropy,
    PoseScores,
    PoseSelection,
    top_peaks,
)
from snapcore.select.signals import (
    SAVGOL_POLYORDER,
    SMOOTH_S,
    minmax,
    savgol_matrix,
    smooth_positions,
    window_frames,
)

__all__ = [
    "REST_SPEED",
    "EVENT_MODES",
    "ZERO_INFORMATION",
    "joint_curvature",
    "rotation_change",
    "limb_lengths",
    "local_information",
    "local_entropy",
    "global_entropy",
    "pose_entropy",
    "select_pose_paper",
]

#: Below this speed (m/s, for a 1.70 m person; scaled with stature) a joint is at rest
#: and its curvature is 0: the direction of a jittering, resting joint means nothing.
REST_SPEED = 0.05
#: What counts as an event in the global term: onset/release (default) or the whole
#: interaction.
EVENT_MODES = ("transitions", "state")
#: Per-frame information (m rad) at or below which a clip counts as having none: far
#: below any real motion (a 1 mm/frame turn of a 5 cm finger gives ~1e-6).
ZERO_INFORMATION = 1e-12
#: Stature (m) the rest speed is given for.
#: Numbers per chunk when working through a clip in pieces (see _chunk_frames): 1 MB
#: arrays, measured fastest for the local term of the salsa pair (smaller chunks pay
#: per-call overhead, whole clips leave the cache; 2 MB was as fast with the allocator
#: tuned, see snapcore._memory, but up to 2x slower without).
_CHUNK_VALUES = 131072


# ----------------------------------------------------------------------- local term


def joint_curvature(
    positions: np.ndarray, *, fps: float, smooth_s: float = SMOOTH_S, rest_speed: float = REST_SPEED
) -> np.ndarray:
    """Discrete curvature ``kappa = sin(theta / 2)`` of every joint trajectory.

    Parameters
    ----------
    positions : ndarray of shape (F, J, 3)
        World positions, metres.
    fps : float
    smooth_s : float
        Savitzky-Golay window in seconds (:func:`smooth_positions`); 0 for none.
    rest_speed : float
        Speed (m/s) below which a joint is at rest: where either edge at a vertex is
        shorter than ``rest_speed / fps``, ``kappa = 0``.

    Returns
    -------
    ndarray of shape (F, J)
        In [0, 1]; 0 at the first and last frame (no turning angle there).

    Notes
    -----
    Edges ``e_i = m_{i+1} - m_i``, unit tangents ``t_i``, turning angle ``theta_i``
    between ``t_{i-1}`` and ``t_i``. ``sin(theta/2) = |t_i - t_{i-1}| / 2`` (chord of
    the unit circle), which is exact for every angle and needs no ``arccos``. It
    equals eq. 3's ``n . e / |e|`` with ``n`` the unit bisector normal. Points on a
    circle, N per revolution, give ``theta = 2 pi / N`` and ``kappa = sin(pi / N)``.
    """
    x = smooth_positions(positions, fps=fps, smooth_s=smooth_s)
    n_f, n_j = x.shape[:2]
    kappa = np.zeros((n_f, n_j))
    if n_f < 3:
        return kappa
    floor = rest_speed / fps
    flat = x.reshape(n_f, n_j * 3)
    ones = np.ones(3)
    step = _chunk_frames(n_j * 3)
    for a in range(0, n_f - 2, step):  # vertices a+1 .. b; frames a .. b+1
        b = min(a + step, n_f - 2)
        e = flat[a + 1 : b + 2] - flat[a : b + 1]  # edges a .. b, (n+1, J*3)
        length = np.sqrt((e * e).reshape(-1, 3) @ ones).reshape(-1, n_j)
        moving = length >= floor
        e = e.reshape(-1, n_j, 3)
        # the same division, but by a contiguous array (a broadcast over a last axis of
        # 3 runs element by element)
        e /= np.repeat(np.where(moving, length, 1.0), 3).reshape(e.shape)  # unit tangents
        dt = e[1:] - e[:-1]
        chord = np.sqrt((dt * dt).reshape(-1, 3) @ ones).reshape(-1, n_j)
        chord *= 0.5
        chord[~(moving[1:] & moving[:-1])] = 0.0
        kappa[a + 1 : b + 1] = chord
    return kappa


def rotation_change(local_rotations: np.ndarray) -> np.ndarray:
    """Geodesic angle (radians) of each joint's rotation change from frame i to i + 1.

    Parameters
    ----------
    local_rotations : ndarray of shape (F, J, 3, 3)

    Returns
    -------
    ndarray of shape (F, J)
        Row i is the angle between frames i and i + 1; the last row is 0.

    Notes
    -----
    ``|R_i - R_{i+1}|_F = 2 sqrt(2) sin(theta / 2)`` for rotations, so
    ``theta = 2 arcsin(|R_i - R_{i+1}|_F / (2 sqrt 2))``: accurate for the small
    angles between frames, where ``arccos((trace - 1) / 2)`` loses half the digits.
    """
    r = np.asarray(local_rotations, dtype=float)
    n_f, n_j = r.shape[:2]
    out = np.zeros((n_f, n_j))
    if n_f < 2:
        return out
    flat = r.reshape(n_f, n_j * 9)
    ones = np.ones(9)
    scale = 1.0 / (2.0 * math.sqrt(2.0))
    step = _chunk_frames(n_j * 9)
    for a in range(0, n_f - 1, step):
        b = min(a + step, n_f - 1)
        d = flat[a + 1 : b + 1] - flat[a:b]
        d *= d
        s = np.sqrt(d.reshape(-1, 9) @ ones)  # row sums via BLAS, faster than sum(-1)
        s *= scale
        np.minimum(s, 1.0, out=s)
        out[a:b] = np.arcsin(s).reshape(b - a, n_j)
    out *= 2.0
    return out


def _chunk_frames(values_per_frame: int) -> int:
    """Frames per chunk so that a chunk holds about :data:`_CHUNK_VALUES` numbers.

    Working through long clips in chunks keeps temporaries in cache; on machines
    where fresh memory pages are expensive (virtual machines) it is several times
    faster than whole-array expressions.
    """
    return max(8, _CHUNK_VALUES // max(values_per_frame, 1))


def limb_lengths(skeleton) -> np.ndarray:
    """Length (m) of the link from each joint to its child, the longest if several.

    End sites and joints whose children all sit on them get 0: a joint without a
    limb carries no weight in eq. 4.
    """
    lengths = np.linalg.norm(np.asarray(skeleton.offsets, dtype=float), axis=1)
    parents = np.asarray(skeleton.parents)
    out = np.zeros(len(parents))
    has_parent = parents >= 0
    np.maximum.at(out, parents[has_parent], lengths[has_parent])
    return out


def local_information(
    character, *, smooth_s: float = SMOOTH_S, rest_speed: float = REST_SPEED
) -> np.ndarray:
    """``p_i = sum_j l_j |dm_ji| kappa_ji`` of one character (eq. 4-5), shape (F,).

    Parameters
    ----------
    character : Character
    smooth_s : float
        Savitzky-Golay window (s) for the trajectories, 0 for none.
    rest_speed : float
        Rest threshold (m/s) in the character's units (callers scale it by stature).

    Notes
    -----
    Equal to ``(joint_curvature(X) * rotation_change(R)) @ limb_lengths`` (the tests
    check it), computed in chunks of frames that stay in cache: smoothing
    (:func:`savgol_matrix`), curvature, rotation change and the weighted sum per chunk.
    The rotation change is measured on ``character.local_quaternions`` (four numbers
    per joint instead of nine; converted from the matrices when a character lacks
    them). Joints without a limb (``l_j = 0``) add exactly 0: they are left out when
    they are more than a tenth of the joints, else computed anyway (the gather would
    cost more than the arithmetic on them).
    """
    n_f = character.n_frames
    weight = limb_lengths(character.skeleton)
    p = np.zeros(n_f)
    if not weight.any() or n_f < 3:
        return p
    pos, quat = character.positions, character.local_quaternions
    if quat is None:  # a character built without them
        quat = matrix_to_quat(character.local_rotations)
    limbs = np.flatnonzero(weight > 0)
    skip = limbs.size < 0.9 * weight.size  # joints without a limb add exactly 0
    if skip:
        pos, weight = pos.take(limbs, axis=1), weight.take(limbs)
    n_j = weight.size
    w = window_frames(smooth_s, character.fps, n_f, SAVGOL_POLYORDER) if smooth_s > 0 else 0
    h = w // 2
    if w:
        from numpy.lib.stride_tricks import sliding_window_view

        mat = savgol_matrix(w, SAVGOL_POLYORDER)
        taps = mat[h]  # interior: y_i = sum_k taps_k x_{i-h+k}
        head = mat[:h] @ pos[:w].reshape(w, n_j * 3)  # smoothed frames 0 .. h-1
        tail = mat[h + 1 :] @ pos[n_f - w :].reshape(w, n_j * 3)  # F-h .. F-1
    floor = rest_speed / character.fps
    ones3, ones4 = np.ones(3), np.ones(4)
    step = _chunk_frames(n_j * 9)
    for a in range(0, n_f - 2, step):
        b = min(a + step, n_f - 2)  # vertices a+1 .. b use smoothed frames a .. b+1
        lo, hi = a, b + 2
        if w:
            # interior frames of [lo, hi) from a window of raw frames around them
            i0, i1 = max(lo, h), min(hi, n_f - h)
            x = np.empty((hi - lo, n_j * 3))
            if i1 > i0:
                raw = pos[i0 - h : i1 + h].reshape(i1 - i0 + 2 * h, n_j * 3)
                x[i0 - lo : i1 - lo] = sliding_window_view(raw, w, axis=0) @ taps
            if lo < h:
                x[: min(h, hi) - lo] = head[lo : min(h, hi)]
            if hi > n_f - h:
                k = max(lo, n_f - h)
                x[k - lo :] = tail[k - (n_f - h) : hi - (n_f - h)]
        else:
            x = pos[lo:hi].reshape(hi - lo, n_j * 3)
        # curvature at vertices a+1 .. b (see joint_curvature), as the chord
        # |t_i - t_{i-1}| = 2 kappa
        e = x[1:] - x[:-1]
        length = np.sqrt(np.square(e).reshape(-1, 3) @ ones3).reshape(-1, n_j)
        moving = length >= floor
        e = e.reshape(-1, n_j, 3)
        # the same division, but by a contiguous array (a broadcast over a last axis of
        # 3 runs element by element)
        e /= np.repeat(np.where(moving, length, 1.0), 3).reshape(e.shape)
        dt = e[1:] - e[:-1]
        dt *= dt
        chord = np.sqrt(dt.reshape(-1, 3) @ ones3).reshape(-1, n_j)
        chord *= moving[1:] & moving[:-1]
        # rotation change from frame i to i+1 for i = a+1 .. b (see rotation_change),
        # on quaternions: |q_i - q_i+1| = 2 sin(theta / 4) for the nearer of +-q_i+1
        # (|q - q'|^2 + |q + q'|^2 = 4), so theta / 4 = arcsin(|dq| / 2), accurate
        # for the small angles between frames
        q = quat[a + 1 : b + 2]
        q = (q.take(limbs, axis=1) if skip else q).reshape(b + 1 - a, n_j * 4)
        d = q[1:] - q[:-1]
        d *= d
        s2 = d.reshape(-1, 4) @ ones4
        np.minimum(s2, 4.0 - s2, out=s2)
        s = np.sqrt(s2, out=s2)
        s *= 0.5
        np.minimum(s, 1.0, out=s)
        quarter_dm = np.arcsin(s, out=s).reshape(b - a, n_j)
        # kappa * dm = (chord / 2) * (4 quarter_dm): the factor 2 is applied at the end
        chord *= quarter_dm
        p[a + 1 : b + 1] = chord @ weight
    p *= 2.0
    return p


def local_entropy(information: np.ndarray) -> np.ndarray:
    """``-p log2 p`` of the per-frame information normalised to sum 1 (eq. 5).

    Returns zeros (not NaN) when the information is 0 everywhere, numerically: at most
    :data:`ZERO_INFORMATION` (rounding in the smoothing of a straight path leaves
    curvatures of 1e-15, which normalisation would blow up into a random
    distribution). The caller warns.
    """
    p = np.asarray(information, dtype=float)
    total = p.sum()
    if not (total > 0 and p.max() > ZERO_INFORMATION):
        return np.zeros_like(p)
    p = p / total
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(p > 0, -p * np.log2(np.where(p > 0, p, 1.0)), 0.0)


# ----------------------------------------------------------------------- global term


def global_entropy(
    active: np.ndarray, joints, starts, ends, *, mode: str = "transitions"
) -> np.ndarray:
    """Event entropy of one character per frame (eq. 6-7), shape (F,).

    Parameters
    ----------
    active : ndarray of bool, shape (F, J)
        Joint in any interaction at that frame.
    joints, starts, ends : array-like of int
        The character's interactions (internal frames, ``ends`` inclusive).
    mode : {"transitions", "state"}
        ``"transitions"``: joint j has an event at frame i when one of its
        interactions starts or ends there (onset at ``start``, release at ``end``;
        an interaction already running at the first frame or still running at the
        last has no onset or release there: the clip cut it, nothing happened).
        ``"state"``: while any of its interactions holds.

    Notes
    -----
    ``p_j = N_interaction(j) / F`` counts the frames joint j interacts with anything
    (eq. 6); ``H(i) = -sum_{j with an event at i} p_j log2 p_j`` (eq. 7), each
    joint counted once per frame.
    """
    if mode not in EVENT_MODES:
        raise SelectionError(f"mode must be one of {', '.join(EVENT_MODES)}, got {mode!r}")
    active = np.asarray(active, dtype=bool)
    n_f, n_j = active.shape
    p = active.sum(axis=0) / max(n_f, 1)
    with np.errstate(divide="ignore", invalid="ignore"):
        h = np.where(p > 0, -p * np.log2(np.where(p > 0, p, 1.0)), 0.0)
    if mode == "state":
        return active.astype(float) @ h
    joints = np.asarray(joints, dtype=np.int64)
    starts = np.asarray(starts, dtype=np.int64)
    ends = np.asarray(ends, dtype=np.int64)
    mark = np.zeros((n_f, n_j), dtype=bool)
    on = starts > 0
    mark[starts[on], joints[on]] = True
    off = ends < n_f - 1
    mark[ends[off], joints[off]] = True
    return mark.astype(float) @ h


# ----------------------------------------------------------------------- combination


def _rest_speed_for(scene, rest_speed: float) -> float:
    h = float(np.mean([c.height for c in scene.characters]))
    return rest_speed * (h / REFERENCE_STATURE_M if np.isfinite(h) and h > 0 else 1.0)


def pose_entropy(
    scene,
    *,
    w_local: float = 1.0,
    w_global: float = 1.0,
    events: str = "transitions",
    smooth_s: float = SMOOTH_S,
    rest_speed: float = REST_SPEED,
    tolerances: ContactParams = DEFAULT_TOLERANCES,
    interactions: Interactions | None = None,
) -> PoseEntropy:
    """Pose entropy of every frame of ``scene``.

    Parameters
    ----------
    scene : Scene
    w_local, w_global : float
        Weights of the normalised terms (eq. 9), both 1 by default.
    events : {"transitions", "state"}
        What counts as an event in the global term (:func:`global_entropy`).
    smooth_s : float
        Savitzky-Golay window (s) for the trajectories; 0 for none.
    rest_speed : float
        Rest threshold (m/s) for a 1.70 m person, scaled by the scene's mean stature
        so the result does not depend on the unit.
    tolerances : ContactParams
        For :func:`snapcore.select.contacts.detect_interactions`.
    interactions : Interactions, optional
        Precomputed events (skips detection).

    Returns
    -------
    PoseEntropy

    Warns
    -----
    UserWarning
        When a term is constant over the clip (no motion along curves, no events):
        it is set to 0 rather than NaN.
    """
    if events not in EVENT_MODES:
        raise SelectionError(f"events must be one of {', '.join(EVENT_MODES)}, got {events!r}")
    for name, w in (("w_local", w_local), ("w_global", w_global)):
        if not (np.isfinite(w) and w >= 0):
            raise SelectionError(f"{name} must be a non-negative number, got {w}")
    timings = {}
    t0 = time.perf_counter()
    if interactions is None:
        interactions = detect_interactions(scene, tolerances=tolerances)
    t1 = time.perf_counter()
    timings["contacts"] = t1 - t0
    n_c, n_f = scene.n_characters, scene.n_frames
    rest = _rest_speed_for(scene, rest_speed)
    info = np.zeros((n_c, n_f))
    h_local = np.zeros((n_c, n_f))
    for ci, c in enumerate(scene.characters):
        info[ci] = local_information(c, smooth_s=smooth_s, rest_speed=rest)
        h_local[ci] = local_entropy(info[ci])
    t2 = time.perf_counter()
    timings["local"] = t2 - t1
    h_global = np.zeros((n_c, n_f))
    by_char: list[list] = [[] for _ in range(n_c)]
    for e in interactions.events:
        by_char[e.character].append((e.joint, e.start, e.end))
    for ci in range(n_c):
        arr = np.array(by_char[ci], dtype=np.int64).reshape(-1, 3)
        h_global[ci] = global_entropy(
            interactions.active[ci], arr[:, 0], arr[:, 1], arr[:, 2], mode=events
        )
    timings["global"] = time.perf_counter() - t2
    if not info.max(initial=0.0) > ZERO_INFORMATION:
        warnings.warn(
            "no joint moves along a curve (static clip?): the local term is 0", stacklevel=2
        )
    local = minmax(h_local.sum(axis=0), name="local pose entropy")
    if h_global.any():
        glob = minmax(h_global.sum(axis=0), name="global pose entropy (interaction events)")
    else:
        # No interaction event carries information (one figure walking, a punch into
        # the air): the global term is 0 by construction, which is expected, not a
        # symptom worth a warning.
        glob = np.zeros(n_f)
    total = w_local * local + w_global * glob
    return PoseEntropy(
        local=local,
        global_=glob,
        total=total,
        local_by_character=h_local,
        global_by_character=h_global,
        information=info,
        interactions=interactions,
        weights=(float(w_local), float(w_global)),
        events_mode=events,
        fps=float(scene.fps),
        timings_s=timings,
    )


def select_pose_paper(
    scene, *, k: int = 3, min_separation_s: float = MIN_SEPARATION_S, **options
) -> PoseSelection:
    """The paper's most informative pose of ``scene`` and the top-k distinct runners-up.

    This is the ``paper`` method of :func:`snapcore.select.pose_methods.select_pose`,
    which checks ``k`` and ``min_separation_s`` and documents the result: the top-k peaks
    of :func:`pose_entropy`, to which ``**options`` are passed (``w_local``,
    ``w_global``, ``events``, ``smooth_s``, ``rest_speed``, ``tolerances``,
    ``interactions``). A constant entropy (a static clip) warns and gives the first frame.
    """
    t0 = time.perf_counter()
    entropy = pose_entropy(scene, **options)
    t1 = time.perf_counter()
    total = entropy.total
    constant = not float(total.max()) > float(total.min())
    sep = int(round(min_separation_s * scene.fps))
    frames = top_peaks(total, int(k), min_separation=sep)
    if constant:
        warnings.warn(
            "pose entropy is the same at every frame (static clip?); choosing the first frame",
            stacklevel=3,
        )
    t2 = time.perf_counter()
    timings = dict(entropy.timings_s)
    timings["select"] = t2 - t1
    timings["total"] = t2 - t0
    scores = PoseScores(
        method="paper",
        total=total,
        terms={
            "local": entropy.weights[0] * entropy.local,
            "global": entropy.weights[1] * entropy.global_,
        },
        unit="normalised entropy",
        interactions=entropy.interactions,
        fps=entropy.fps,
    )
    return PoseSelection(
        index=int(frames[0]),
        indices=[int(f) for f in frames],
        scores=scores,
        min_separation_s=float(min_separation_s),
        timings_s=timings,
        entropy=entropy,
    )
