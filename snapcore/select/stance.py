"""The neutral stance and the pose descriptor of the story selector.

A pose is described by quantities that do not change under yaw, translation or a change
of unit (:func:`pose_descriptor`): the heights above the ground of six key joints (head,
pelvis, wrists, ankles), their pairwise distances and their pairwise horizontal
distances, over the character's stature.
:func:`neutral_stance` builds the same joints for the character standing at rest with
its arms down, from its own bone lengths and rigid body measurements, and
:func:`stance_departure` gives the self-information (bits) of departing from it;
:func:`trunk_departure` that of the trunk's flexion (a bow), under the trunk's own,
tighter spread. See :mod:`snapcore.select.story` for how they are used.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from snapcore.motion.anatomy import body_landmarks, stature_of
from snapcore.select.signals import SAVGOL_POLYORDER, smooth_positions, window_frames

__all__ = [
    "key_joints",
    "neutral_stance",
    "key_positions",
    "joint_trajectories",
    "descriptor_of",
    "pose_descriptor",
    "stance_departure",
    "trunk_departure",
    "descriptor_rows",
    "trunk_departure_rows",
    "stance_departure_rows",
]

#: Key joints of the pose descriptor where landmarks are missing: (role, side), the
#: first joint of each found.
_KEY_ROLES = (
    ("head", ""),
    ("pelvis", ""),
    ("hand", "L"),
    ("hand", "R"),
    ("foot", "L"),
    ("foot", "R"),
)
#: The key joints as landmarks (:func:`snapcore.motion.anatomy.body_landmarks`).
_KEY_LANDMARKS = ("head", "pelvis", "wrist_L", "wrist_R", "ankle_L", "ankle_R")
#: Frames (about; evenly spaced) on which :func:`neutral_stance` takes its medians.
_MEASURE_FRAMES = 256
#: How far (statures) a hanging hand lies outside its shoulder joint (:func:`neutral_stance`).
_HAND_OUTSET = 0.04


def key_joints(character) -> np.ndarray:
    """Head, pelvis, left/right wrist and ankle joints, shape (K,).

    The joints of :func:`snapcore.motion.anatomy.body_landmarks` (``head``, ``pelvis``,
    ``wrist_L``, ``wrist_R``, ``ankle_L``, ``ankle_R``) when the skeleton names all six;
    else the first joint of each role (those found); with fewer than four, the root and
    every end joint (a joint without children).
    """
    sk = character.skeleton
    return _key_joints_of(*_skeleton_key(character), sk.roles, sk.sides)


def _skeleton_key(character):
    return tuple(character.joint_names), tuple(np.asarray(character.parents).tolist())


@lru_cache(maxsize=64)
def _key_joints_of(names: tuple, parents: tuple, roles: tuple, sides: tuple) -> np.ndarray:
    lm = body_landmarks(names, parents)
    full = [lm.get(k) for k in _KEY_LANDMARKS]
    if all(j is not None for j in full):
        out = np.asarray(full, dtype=np.int64)
        out.flags.writeable = False
        return out
    found = []
    for role, side in _KEY_ROLES:
        for j, (r, s) in enumerate(zip(roles, sides)):
            if r == role and s == side:
                found.append(j)
                break
    if len(found) < 4:
        par = np.asarray(parents)
        leaves = np.setdiff1d(np.arange(par.size), par[par >= 0])
        found = sorted({int(np.flatnonzero(par < 0)[0]), *leaves.tolist()})
    out = np.asarray(found, dtype=np.int64)
    out.flags.writeable = False
    return out


def _chain_length(parents, lengths, top: int, bottom: int) -> float:
    """Sum of the bone lengths from joint ``top`` down to its descendant ``bottom``."""
    total, j = 0.0, int(bottom)
    while j >= 0 and j != top:
        total += float(lengths[j])
        j = int(parents[j])
    return total if j == top else float("nan")


def neutral_stance(character, *, ground: float) -> np.ndarray | None:
    """The character standing at rest, arms down: its key joints, shape (6, 3), metres.

    Built from the skeleton's own proportions, not from any frame's pose (a clip may
    start mid-action): the order of :func:`key_joints` (head, pelvis, left and right
    wrist, left and right ankle), in a frame with +Y up and the left side at +X,
    heights above ``ground``.

    - Legs straight down: the ankles ``a`` above the ground, below the hips; the pelvis
      at ``a + thigh + shin + drop``, ``drop`` the height of the pelvis joint above the
      hip joints.
    - Spine straight up: the head at the pelvis plus the bone lengths from the pelvis
      to the head.
    - Arms hanging: each wrist below its shoulder joint by the upper arm plus forearm,
      4 % of the stature further out (beside the thigh);
      the shoulders at the height of the joint the two arms branch from (the chest,
      spine straight) plus the height of the shoulder joints above that joint.

    Lengths are the skeleton's bone lengths (its offsets). Widths (hip to hip,
    shoulder to shoulder), ``drop``, the shoulders' height above the chest and the
    standing ankle height are body measurements read from the clip, as medians of
    nearly rigid distances over the frames (about 256 evenly spaced ones; not from any
    one frame's pose): the
    distances between the two hip and the two shoulder joints, the vertical offsets,
    and the 5th percentile of the ankles' height above the ground (a planted foot),
    kept within 2-10 % of the stature.

    Returns
    -------
    ndarray of shape (6, 3), or None
        None when the skeleton does not name a head, a pelvis and both arms and legs
        (:func:`snapcore.motion.anatomy.body_landmarks`).
    """
    geometry = _stance_geometry(
        *_skeleton_key(character), np.asarray(character.skeleton.offsets, dtype=float).tobytes()
    )
    if geometry is None:
        return None
    idx, leg, spine, to_branch, arm = geometry
    stature = stature_of(character)
    # one gather of the 8 joints used: hips, shoulders, ankles (L, R), pelvis, branch, on
    # at most ~256 evenly spaced frames (medians of body measurements need no more):
    # (F', 8, 3)
    step = max(1, character.n_frames // _MEASURE_FRAMES)
    x = character.positions[::step, idx]  # (np.take would copy the strided frames first)
    y = x[..., 1]
    ankle_h = _percentile(y[:, 4:6] - ground, 5)
    ankle_h = min(max(ankle_h, 0.02 * stature), 0.10 * stature)  # np.clip's (NaN stays)
    # four nearly rigid body measurements, their medians in one call (one call each
    # took 0.1 of this function's 0.16 ms; the same values): hip to hip and shoulder to
    # shoulder, the pelvis joint above the hip joints (below on some rigs; its vertical
    # part barely changes with the pelvis's tilt), the shoulder joints above the joint
    # both arms hang from (the chest)
    rigid = np.empty((4, x.shape[0]))
    # norms as ``np.linalg.norm(d, axis=1)`` computes them (square, sum the row, root)
    d = x[:, 0:4:2] - x[:, 1:4:2]  # (F', 2, 3): hip to hip, shoulder to shoulder
    d *= d
    np.sqrt(d.sum(axis=2).T, out=rigid[:2])
    rigid[2] = y[:, 6] - 0.5 * (y[:, 0] + y[:, 1])
    rigid[3] = 0.5 * (y[:, 2] + y[:, 3]) - y[:, 7]
    hip_d, sh_d, drop, rise = _row_medians(rigid)
    hip_w, sh_w = hip_d / 2, sh_d / 2
    pelvis_h = ankle_h + leg + drop
    head_h = pelvis_h + spine
    shoulder_h = pelvis_h + to_branch + rise
    wrist_h = shoulder_h - arm
    # hands hang beside the thighs, outside the shoulder joints by about a thigh's
    # half-thickness (measured at rest on the shared rigs: 0.03-0.05 statures)
    wrist_x = sh_w + _HAND_OUTSET * stature
    out = np.array(
        [
            [0.0, head_h, 0.0],
            [0.0, pelvis_h, 0.0],
            [wrist_x, wrist_h, 0.0],
            [-wrist_x, wrist_h, 0.0],
            [hip_w, ankle_h, 0.0],
            [-hip_w, ankle_h, 0.0],
        ]
    )
    return out if np.isfinite(out).all() else None


def _percentile(values: np.ndarray, q: float) -> float:
    """``float(np.percentile(values, q))`` (the default, linear method), the same double.

    NumPy's own arithmetic written out for one quantile of a small array (its
    ``percentile`` spent ~40 us in argument handling around a partition of 500 values):
    the virtual index ``(n - 1) q / 100``, a partition at its two neighbours, and
    ``_lerp``'s two-sided interpolation. NaN anywhere: NumPy's answer.
    """
    v = np.ravel(values)
    n = v.size
    if n == 0 or np.isnan(v).any():
        return float(np.percentile(values, q))
    vi = (n - 1) * (q / 100)
    lo = math.floor(vi)
    hi = min(lo + 1, n - 1)
    part = np.partition(v, (lo, hi) if hi > lo else lo)
    a, b = float(part[lo]), float(part[hi])
    g = vi - lo
    diff = b - a
    return b - diff * (1 - g) if g >= 0.5 else a + diff * g


def _row_medians(values: np.ndarray) -> list[float]:
    """``np.median(values, axis=1).tolist()`` for a small (R, N) array, the same doubles:
    a partition at the middle (two middles for even N, their mean ``(a + b) / 2``) per
    row, without ``median``'s argument handling. NaN anywhere: NumPy's answer."""
    n = values.shape[1]
    if n == 0 or np.isnan(values).any():
        return np.median(values, axis=1).tolist()
    h = n // 2
    if n % 2:
        return np.partition(values, h, axis=1)[:, h].tolist()
    part = np.partition(values, (h - 1, h), axis=1)
    mid = part[:, h - 1] + part[:, h]
    mid /= 2
    return mid.tolist()


@lru_cache(maxsize=64)
def _stance_geometry(names: tuple, parents: tuple, offsets: bytes):
    """The skeleton's part of :func:`neutral_stance` (cached per skeleton), or None.

    Returns the joints to gather (hips L/R, shoulders L/R, ankles L/R, pelvis, the
    shoulders' common ancestor) and the lengths (m): hip to ankle, pelvis to head,
    pelvis to that ancestor, shoulder to wrist (means of the two sides).
    """
    lm = body_landmarks(names, parents)
    need = (
        "pelvis",
        "head",
        "shoulder_L",
        "shoulder_R",
        "wrist_L",
        "wrist_R",
        "hip_L",
        "hip_R",
        "ankle_L",
        "ankle_R",
    )
    if any(lm.get(k) is None for k in need):
        return None
    par = np.asarray(parents)
    lengths = np.linalg.norm(np.frombuffer(offsets).reshape(-1, 3), axis=1)
    pelvis = lm["pelvis"]

    def chain(top, bottom):
        return _chain_length(par, lengths, top, bottom)

    def mean2(f):
        v = np.array([f(s) for s in "LR"])
        return float(np.nanmean(v)) if np.isfinite(v).any() else float("nan")

    branch = _common_ancestor(par, lm["shoulder_L"], lm["shoulder_R"])
    if branch is None or not np.isfinite(chain(pelvis, branch)):
        branch = pelvis
    idx = np.array(
        [
            lm["hip_L"],
            lm["hip_R"],
            lm["shoulder_L"],
            lm["shoulder_R"],
            lm["ankle_L"],
            lm["ankle_R"],
            pelvis,
            branch,
        ],
        dtype=np.int64,
    )
    sizes = (
        mean2(lambda s: chain(lm[f"hip_{s}"], lm[f"ankle_{s}"])),
        chain(pelvis, lm["head"]),
        chain(pelvis, branch),
        mean2(lambda s: chain(lm[f"shoulder_{s}"], lm[f"wrist_{s}"])),
    )
    if not np.isfinite(sizes).all():
        return None
    return (idx, *sizes)


def _common_ancestor(parents, a: int, b: int) -> int | None:
    up = []
    j = int(a)
    while j >= 0:
        up.append(j)
        j = int(parents[j])
    j = int(parents[b])
    while j >= 0:
        if j in up:
            return j
        j = int(parents[j])
    return None


def descriptor_of(
    points: np.ndarray, *, ground: float, stature: float, horizontal: bool = True
) -> np.ndarray:
    """:func:`pose_descriptor` of key-joint positions, shape (F, K + K (K - 1)).

    Parameters
    ----------
    points : ndarray of shape (F, K, 3)
        Metres, Y up.
    ground : float
    stature : float
        Metres.
    horizontal : bool
        Include the pairwise horizontal distances (False: shape (F, K + K (K - 1) / 2),
        for ablation).
    """
    x = np.asarray(points, dtype=float)
    # (3, K, F): a contiguous row of frames per axis and joint, so that the pairs are
    # gathered as whole rows (gathering them across the last axis of (3, F, K) took
    # three times as long); the values are the same, element by element
    out = descriptor_rows(
        np.ascontiguousarray(x.transpose(2, 1, 0)),
        ground=ground,
        stature=stature,
        horizontal=horizontal,
    )
    return np.ascontiguousarray(out.T)


def descriptor_rows(
    rows: np.ndarray, *, ground: float, stature: float, horizontal: bool = True
) -> np.ndarray:
    """:func:`descriptor_of` of key-joint rows, feature-major: shape (D, F).

    Parameters
    ----------
    rows : ndarray of shape (3, K, F)
        Key-joint positions (m, Y up) component-major, each (component, joint) a
        contiguous row of frames (:class:`snapcore.select.tracks.JointTracks` rows).
    ground, stature, horizontal
        As for :func:`descriptor_of`.

    Returns
    -------
    ndarray of shape (D, F)
        ``descriptor_of(points).T`` (the same values), a contiguous row per feature:
        the story's novelty and stance terms work on these rows directly.
    """
    xt = np.asarray(rows, dtype=float)
    k, n_f = xt.shape[1:]
    n_p = k * (k - 1) // 2
    # the pairs (a, b > a) in np.triu_indices order, joint a's to every later joint in
    # one subtraction (two gathers of (3, P, F) copies took longer); b - a instead of
    # a - b, squared next: the same doubles
    d = np.empty((3, n_p, n_f))
    i = 0
    for a in range(k - 1):
        np.subtract(xt[:, a + 1 :], xt[:, a : a + 1], out=d[:, i : i + k - 1 - a])
        i += k - 1 - a
    d *= d
    flat = d[0] + d[2]  # squared horizontal distance
    out = np.empty((k + (2 if horizontal else 1) * n_p, n_f))
    np.subtract(xt[1], ground, out=out[:k])
    flat_3d = d[1]
    flat_3d += flat
    np.sqrt(flat_3d, out=out[k : k + n_p])
    if horizontal:
        np.sqrt(flat, out=out[k + n_p :])
    out /= stature
    return out


def pose_descriptor(
    character, *, ground: float, fps: float, smooth_s: float = 0.05, horizontal: bool = True
) -> np.ndarray:
    """Pose of every frame as quantities invariant to yaw, translation and unit.

    Parameters
    ----------
    character : Character
    ground : float
        Ground height (m).
    fps : float
    smooth_s : float
        Savitzky-Golay window (s) of the trajectories.
    horizontal : bool
        Include the horizontal distances (see :func:`descriptor_of`).

    Returns
    -------
    ndarray of shape (F, K + K (K - 1))
        Heights of the K :func:`key_joints` above the ground, their pairwise distances,
        then their pairwise *horizontal* distances, all divided by the character's
        stature (dimensionless). The horizontal distances see what the 3-D ones barely
        do: a trunk leaning in a bow moves the head forward of the pelvis and feet (the
        head-to-pelvis distance is rigid; at 30 degrees the head drops 4 % of the
        stature but moves 16 % forward), a guiding hand reaching out.
    """
    x = key_positions(character, fps=fps, smooth_s=smooth_s)
    return descriptor_of(x, ground=ground, stature=stature_of(character), horizontal=horizontal)


def key_positions(character, *, fps: float, smooth_s: float = 0.05) -> np.ndarray:
    """Smoothed positions (m) of the :func:`key_joints`, shape (F, K, 3)."""
    return joint_trajectories(character, key_joints(character), fps=fps, smooth_s=smooth_s)


def joint_trajectories(character, joints, *, fps: float, smooth_s: float) -> np.ndarray:
    """Savitzky-Golay smoothed positions (m) of some joints, shape (F, len(joints), 3).

    Parameters
    ----------
    character : Character
    joints : array_like of int, shape (N,)
    fps : float
    smooth_s : float
        Window (s) of :func:`snapcore.select.signals.smooth_positions`.

    Returns
    -------
    ndarray of shape (F, N, 3)
        A new array.

    Notes
    -----
    The story selector's trajectories (its key joints and contact joints). Two shortcuts
    that change no value beyond rounding:

    - ``np.take`` along the joint axis copies each frame's (N, 3) block in one go; fancy
      indexing ``positions[:, joints]`` copies 3 values at a time and took 3 times as
      long (0.38 against 0.13 ms for 16 of 57 joints over 2,000 frames, cold cache),
      in increasing joint order (unsorted, 2.5 times as long).
    - A window of ``polyorder + 1`` frames (3 frames: the default 0.05 s at 60 or 30
      fps) is the identity: the polynomial goes through every sample of the window, so
      the filter returns its input (up to rounding of about 1e-16 in the filter matrix),
      and is skipped.
    """
    j = np.asarray(joints, dtype=np.int64)
    order = np.argsort(j, kind="stable")
    if (order == np.arange(j.size)).all():
        x = np.take(character.positions, j, axis=1)
    else:
        # gather in increasing joint order, then reorder the small copy: jumping back
        # and forth within each frame took 2.5 times as long from a cold cache
        x = np.take(character.positions, j[order], axis=1)
        x = np.take(x, np.argsort(order), axis=1)
    w = window_frames(smooth_s, fps, x.shape[0], SAVGOL_POLYORDER) if smooth_s > 0 else 0
    if w <= SAVGOL_POLYORDER + 1:
        return x
    return smooth_positions(x, fps=fps, smooth_s=smooth_s)


def stance_departure(features: np.ndarray, neutral: np.ndarray, *, spread: float) -> np.ndarray:
    """Self-information (bits) of each pose for a person standing at rest, shape (F,).

    Parameters
    ----------
    features : ndarray of shape (F, D)
        Pose descriptors (:func:`pose_descriptor`).
    neutral : ndarray of shape (D,)
        The descriptor of the character's :func:`neutral_stance`.
    spread : float
        Standard deviation (stature units) of the isotropic Gaussian around the neutral
        stance: how far a person "at rest" strays (sway, arms not quite straight).

    Returns
    -------
    ndarray of shape (F,)
        ``1/2 |x_i - n|^2 / spread^2 / ln 2``: ``-log2`` of the Gaussian's density up
        to a constant, 0 at the neutral stance.
    """
    z = np.asarray(features, dtype=float) - np.asarray(neutral, dtype=float)
    # row sums of squares in one pass (einsum; square-then-sum over short rows took
    # twice as long): the same terms, added in another order
    d2 = np.einsum("ij,ij->i", z, z)
    d2 *= 0.5 / (spread**2 * math.log(2.0))
    return d2


def stance_departure_rows(rows: np.ndarray, neutral: np.ndarray, *, spread: float) -> np.ndarray:
    """:func:`stance_departure` of feature-major descriptors (D, F)
    (:func:`descriptor_rows`), shape (F,).

    The same terms, added feature by feature (one pass per row of frames, instead of a
    short sum per frame): equal to :func:`stance_departure` up to the order of the
    additions (a few units in the last place).
    """
    z = np.asarray(rows, dtype=float) - np.asarray(neutral, dtype=float)[:, None]
    z *= z
    d2 = np.add.reduce(z, axis=0)
    d2 *= 0.5 / (spread**2 * math.log(2.0))
    return d2


def trunk_departure(
    points: np.ndarray, neutral: np.ndarray, *, stature: float, spread: float
) -> np.ndarray:
    """Self-information (bits) of the trunk's flexion for a person at rest, shape (F,).

    Parameters
    ----------
    points : ndarray of shape (F, 6, 3)
        Key-joint positions (:func:`key_positions`, m) in the order of
        :func:`neutral_stance`: head, pelvis, wrists, ankles.
    neutral : ndarray of shape (6, 3)
        The :func:`neutral_stance` (m): where the head stands above the pelvis.
    stature : float
        Metres.
    spread : float
        Standard deviation (statures) of the head around its place above the pelvis
        for a person at rest.

    Returns
    -------
    ndarray of shape (F,)
        ``1/2 d_i^2 / (spread^2 + l_i^2) / ln 2`` with ``d_i`` the distance
        (statures) of the head from where it stands over the pelvis in the neutral
        stance, ``|head - pelvis - (neutral head - neutral pelvis)|``: 0 upright; a
        bow's drop and forward lean (a 30 degree flexion moves the head by about 15 %
        of the stature), a lean back. ``l_i^2`` is the legs' departure: the mean over
        the two legs of the squared change (statures^2) of the ankle's place below the
        pelvis, vertical and horizontal distance, from the neutral stance.
        Yaw-invariant (lengths).

    Notes
    -----
    The trunk gets its own spread because a person at rest holds it far more tightly
    than the arms and legs: the head sways a few centimetres over the pelvis, the hands
    tens of centimetres. Under :func:`stance_departure`'s one spread (set for the
    limbs) a bow of 5-12 cm head drop carries a bit or two, less than the arms of a
    style that holds its hands at the chest throughout.

    The spread widens with the legs' departure because a trunk that leans while the
    knees bend (the crouch before a jump, a landing, a lunge) or a leg rises (a kick)
    is carried by the legs' motion -- it leans to keep the weight over the feet --
    and is not a gesture of its own; the stance term already counts that pose. Only
    the legs weigh: a bow is made with the arms anywhere (hanging, along the thighs,
    clasped in front).
    """
    x = np.asarray(points, dtype=float)
    # components first, a contiguous row of frames per joint: the arithmetic is on rows
    rows = np.ascontiguousarray(x.transpose(2, 1, 0))
    return trunk_departure_rows(rows, neutral, stature=stature, spread=spread)


def trunk_departure_rows(
    rows: np.ndarray, neutral: np.ndarray, *, stature: float, spread: float
) -> np.ndarray:
    """:func:`trunk_departure` of key-joint rows (3, K, F) (see
    :func:`descriptor_rows`), shape (F,): the same values, element by element."""
    x = np.asarray(rows, dtype=float)
    n = np.asarray(neutral, dtype=float)
    # the head's place over the pelvis, the three components at once: (3, F)
    d = x[:, 0] - x[:, 1]
    d -= (n[0] - n[1])[:, None]
    d *= d
    head = d[0] + d[1]
    head += d[2]
    # the legs: both ankles' vertical and horizontal distance from the pelvis, (2, F)
    a = x[:, 4:6] - x[:, 1:2]  # (3, 2, F)
    nv = n[4:6] - n[1]  # (2, 3)
    dv = a[1] - nv[:, 1:2]
    dh = np.hypot(a[0], a[2])
    dh -= np.array([[math.hypot(v[0], v[2])] for v in nv.tolist()])  # math's, as before
    dv *= dv
    dh *= dh
    dv += dh
    dv *= 0.5
    legs = dv[0] + dv[1]
    legs += spread**2 * stature**2
    head *= 0.5
    head /= legs
    head /= math.log(2.0)
    return head
