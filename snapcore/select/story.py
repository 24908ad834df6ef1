"""Story information: the default pose selector, a repair of pose entropy (paper §3.1).

The paper's pose entropy (:mod:`snapcore.select.pose`, method ``paper``) often lands on a
footfall beside the action: contact events flicker (dozens of onsets and releases per
clip, every ankle, toe and toe-end joint its own event), each event frame gets the
normalised global term ~1, and ``-p log2 p`` of a contact *state* rewards contacts that
hold ~37 % of the time (feet) instead of rare ones. This module keeps the paper's
structure -- the information of a frame is a local (pose) term plus a global (event)
term, each min-max normalised and summed with weights (eq. 8-9), the pose is the argmax
-- and measures both terms as *surprisal* (self-information, eq. 1: ``I = -log2 P``):

1. **Pose information** (the local term; "extreme poses" of §3.1.1): the surprisal of
   the frame's pose under a Gaussian model of all the clip's poses,
   ``I_pose(i) = 1/2 (x_i - mu)^T S^-1 (x_i - mu) / ln 2`` bits (the log-normaliser is
   the same for every frame and dropped). ``x_i`` describes the pose by quantities that
   do not change under yaw, translation or a change of unit: the heights above the
   ground of six key joints (head, pelvis, hands, feet) and their pairwise distances,
   divided by the character's stature. ``S`` is the sample covariance shrunk towards
   a multiple of the identity and widened by the capture noise (well posed for short
   clips).
2. **Event information** (the global term, §3.1.2): contacts with the ground are
   *debounced* per limb -- one leg (foot and toes, a kneeling knee), one arm or the
   trunk is one contact, whatever of its joints touch -- with hysteresis on height and
   speed and minimum durations for a contact and for a gap. Each onset and each
   release is an event; an event of a kind (limb, onset or release) that happens
   ``n`` times in ``F`` frames carries ``-log2(n / F)`` bits (rare events, a two-foot
   take-off, carry most). Its information is given *temporal support* on the side where
   the limb is free: a release credits the frames after it (the swing, the flight it
   opens), an onset the frames before it (the approach it closes), with a half-Gaussian
   of width ``event_support_s``.
3. **Combination**: both terms min-max normalised (eq. 9), weighted, summed, then
   averaged over a Gaussian window of ``support_s`` with nothing outside the clip (a
   frame whose surroundings the clip does not show has less support). The pose is the
   argmax; the top-k are distinct peaks (:func:`snapcore.select.pose.top_peaks`).

Every ingredient can be switched off or replaced for ablation through
:class:`StoryParameters`. Everything is vectorised over frames and joints; the Python
loops run over characters and limbs (at most five per character).

References: Assa, Caspi & Cohen-Or 2005 (*Action Synopsis*: poses that stand out of
the motion); Roberts, Mantiuk et al. 2019 (*Salient Poses*); Shannon's self-information.
"""

from __future__ import annotations

import math
import time
import warnings
from dataclasses import dataclass, field, fields, replace
from functools import lru_cache

import numpy as np

from snapcore.motion.anatomy import (
    REFERENCE_STATURE_M,
    body_landmarks,
    joint_roles,
    joint_sides,
)
from snapcore.select.pose import minmax, smooth_positions

__all__ = [
    "StoryParameters",
    "DEFAULT_STORY",
    "StoryInformation",
    "LimbContacts",
    "limb_groups",
    "hysteresis",
    "enforce_min_durations",
    "debounced_contacts",
    "key_joints",
    "pose_descriptor",
    "pose_surprisal",
    "event_surprisal",
    "contact_state_entropy",
    "temporal_support",
    "story_information",
]

#: Roles (from :func:`snapcore.motion.anatomy.joint_roles`) that make up a leg and an arm.
_LEG_ROLES = frozenset({"thigh", "shin", "foot", "toe"})
_ARM_ROLES = frozenset({"upperarm", "forearm", "hand", "finger"})
#: Roles whose joints can bear weight: the distal parts of the limbs and the trunk. A
#: thigh or upper arm is never a limb's lowest point while its knee or elbow is not,
#: and finger joints lie within a few cm of the hand joint (leaving them out makes the
#: contacts several times cheaper on skeletons with 30 finger joints).
_CONTACT_ROLES = frozenset({"shin", "foot", "toe", "forearm", "hand", "pelvis", "spine",
                            "chest", "head"})
#: Key joints of the pose descriptor: (role, side), the first joint of each found.
_KEY_ROLES = (("head", ""), ("pelvis", ""), ("hand", "L"), ("hand", "R"), ("foot", "L"),
              ("foot", "R"))
#: The same joints as landmarks (:func:`snapcore.motion.anatomy.body_landmarks`).
_KEY_LANDMARKS = ("head", "pelvis", "wrist_L", "wrist_R", "ankle_L", "ankle_R")
#: How far (statures) a hanging hand lies outside its shoulder joint (:func:`neutral_stance`).
_HAND_OUTSET = 0.04
#: Event-information models.
EVENT_MODELS = ("surprisal", "entropy")
#: A term whose range over the clip is below this many bits is constant: rounding in
#: the smoothing of a still clip leaves ~1e-28 bits, which min-max would blow up.
ZERO_BITS = 1e-9


@dataclass(frozen=True)
class StoryParameters:
    """Every choice of the story selector, with the switches used for ablation.

    Lengths are metres for a person of :data:`REFERENCE_STATURE_M` and scale with the
    character's stature; durations are seconds and do not depend on the frame rate.

    Attributes
    ----------
    w_pose, w_event : float
        Weights of the normalised pose and event terms (eq. 9); 0 switches a term off.
    smooth_s : float
        Savitzky-Golay window (s) for the joint trajectories (capture jitter).
    support_height, release_height : float
        Hysteresis on height above the ground (m): a limb comes into contact when one
        of its joints is at most ``support_height`` up *and* slower than
        ``support_speed``; it leaves when every joint is above ``release_height`` or
        faster than ``release_speed``. Joints are bone centres: a standing ankle is
        7-12 cm up, a toe end 0-5 cm.
    support_speed, release_speed : float
        The same on joint speed (m/s): a planted foot moves < 0.5 m/s, a swinging one
        2-5 m/s.
    min_contact_s, min_gap_s : float
        Minimum durations (s): gaps shorter than ``min_gap_s`` inside a contact are
        closed first (a heel lifting while the toes stay down), then contacts shorter
        than ``min_contact_s`` are dropped (a swing foot brushing the floor).
    debounce : bool
        False: no hysteresis (release thresholds equal the support ones) and no
        minimum durations -- the flickering contacts of the failure analysis.
    per_limb : bool
        False: every joint is its own contactor (the paper's per-joint events).
    event_model : {"surprisal", "entropy"}
        ``"surprisal"``: an event of a kind seen ``n`` times carries ``-log2(n/F)``
        bits. ``"entropy"``: the paper's ``-p log2 p`` of the contactor's contact
        probability (eq. 6-7), for comparison.
    event_support_s : float
        Width (s) of the half-Gaussian that spreads an event's information over the
        frames where the limb is free; 0: the event frame only.
    sided_support : bool
        False: spread symmetrically around the event.
    shrinkage : float
        Weight in [0, 1] of ``tr(S)/d * I`` in the pose covariance (0: sample
        covariance; 1: isotropic).
    noise : float
        Capture noise (m), added as ``noise^2 I`` (in stature units) to the covariance.
    support_s : float
        Width (s) of the Gaussian that averages the total over time; 0: none.
    """

    w_pose: float = 1.0
    w_event: float = 1.0
    smooth_s: float = 0.05
    support_height: float = 0.10
    release_height: float = 0.15
    support_speed: float = 0.8
    release_speed: float = 1.5
    min_contact_s: float = 0.1
    min_gap_s: float = 0.1
    debounce: bool = True
    per_limb: bool = True
    event_model: str = "surprisal"
    event_support_s: float = 0.2
    sided_support: bool = True
    shrinkage: float = 0.5
    noise: float = 0.02
    support_s: float = 0.1
    stance: bool = True
    stance_spread: float = 0.1
    novelty: bool = True
    combine: str = "bits"

    def __post_init__(self):
        for f in fields(self):
            v = getattr(self, f.name)
            if isinstance(v, bool) or isinstance(v, str):
                continue
            if not (np.isfinite(v) and v >= 0):
                raise ValueError(f"StoryParameters.{f.name} must be a non-negative number, "
                                 f"got {v}")
        if self.event_model not in EVENT_MODELS:
            raise ValueError(f"StoryParameters.event_model must be one of "
                             f"{', '.join(EVENT_MODELS)}, got {self.event_model!r}")
        if not self.shrinkage <= 1:
            raise ValueError(f"StoryParameters.shrinkage must be in [0, 1], got {self.shrinkage}")
        if self.release_height < self.support_height or self.release_speed < self.support_speed:
            raise ValueError("StoryParameters: release thresholds must not be below the "
                             "support thresholds (hysteresis)")
        if self.w_pose + self.w_event <= 0:
            raise ValueError("StoryParameters: at least one of w_pose, w_event must be > 0")

    def with_(self, **changes) -> StoryParameters:
        """A copy with ``changes`` (for ablation)."""
        return replace(self, **changes)


#: The defaults of ``snapshot select``.
DEFAULT_STORY = StoryParameters()


@dataclass
class LimbContacts:
    """Debounced ground contacts of one character.

    Attributes
    ----------
    names : list of str
        Contactor names (``"legL"``, ``"armR"``, ``"trunk"``, or joint names when
        ``per_limb`` is off).
    joints : list of ndarray of int
        The joints of each contactor.
    state : ndarray of bool, shape (L, F)
        In contact with the ground.
    """

    names: list[str]
    joints: list[np.ndarray]
    state: np.ndarray

    def intervals(self, limb: int) -> list[tuple[int, int]]:
        """Contacts of contactor ``limb`` as ``(start, end)`` frames, ``end`` inclusive."""
        s, e = _runs(self.state[limb])
        return list(zip(s.tolist(), (e - 1).tolist()))


@dataclass
class StoryInformation:
    """Per-frame story information of a scene.

    Attributes
    ----------
    pose_bits, event_bits : ndarray of shape (F,)
        The two terms before normalisation (bits), summed over characters.
    pose, event : ndarray of shape (F,)
        The terms min-max normalised to [0, 1].
    total : ndarray of shape (F,)
        ``w_pose * pose + w_event * event``, after temporal support.
    contacts : list of LimbContacts
        Per character.
    params : StoryParameters
    timings_s : dict
    """

    pose_bits: np.ndarray
    event_bits: np.ndarray
    pose: np.ndarray
    event: np.ndarray
    total: np.ndarray
    contacts: list[LimbContacts]
    params: StoryParameters
    timings_s: dict = field(default_factory=dict)


# ----------------------------------------------------------------------- contacts


def limb_groups(character) -> tuple[list[str], list[np.ndarray]]:
    """Contactors of a character: each leg, each arm and the trunk, by joint roles.

    Returns
    -------
    names : list of str
        ``legL``, ``legR``, ``armL``, ``armR``, ``trunk`` (those present).
    joints : list of ndarray of int
        Joint indices of each: the joints that can bear weight (shin, foot and toe;
        forearm and hand; pelvis, spine, chest, head). Hidden joints (a floor-level
        ``joint_Root``, eyes), fingers, thighs and upper arms belong to none. An
        unsided joint of an arm or leg role (rare naming) goes to the trunk.
    """
    roles, sides = _roles_sides(character)
    groups: dict[str, list[int]] = {}
    for j, (role, side) in enumerate(zip(roles, sides)):
        if role not in _CONTACT_ROLES:
            continue
        if side and role in _LEG_ROLES:
            key = "leg" + side
        elif side and role in _ARM_ROLES:
            key = "arm" + side
        else:
            key = "trunk"
        groups.setdefault(key, []).append(j)
    order = ["legL", "legR", "armL", "armR", "trunk"]
    names = [n for n in order if n in groups]
    return names, [np.asarray(groups[n], dtype=np.int64) for n in names]


def hysteresis(score: np.ndarray, on: float, off: float) -> np.ndarray:
    """Two-threshold switch along the first axis.

    Parameters
    ----------
    score : ndarray of shape (F, ...)
        Low means "in contact".
    on, off : float
        The state switches on where ``score <= on`` and off where ``score > off``
        (``off >= on``); in between it keeps its previous value. It starts off.

    Returns
    -------
    ndarray of bool, the shape of ``score``

    Notes
    -----
    Vectorised: the state at frame i is the one set by the last frame ``<= i`` where
    the score was outside the band, found with a running maximum of indices.
    """
    s = np.asarray(score, dtype=float)
    n = s.shape[0]
    decided = (s <= on) | (s > off)
    idx = np.where(decided, np.arange(n).reshape((n,) + (1,) * (s.ndim - 1)), -1)
    last = np.maximum.accumulate(idx, axis=0)
    val = np.take_along_axis(s <= on, np.maximum(last, 0), axis=0)
    return val & (last >= 0)


def _runs(b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Starts and stops (exclusive) of the True runs of a 1-D bool array."""
    d = np.diff(np.r_[0, np.asarray(b, dtype=np.int8), 0])
    return np.flatnonzero(d == 1), np.flatnonzero(d == -1)


def _set_runs(b: np.ndarray, starts, stops, value: bool) -> None:
    """``b[s:e] = value`` for every run, without a Python loop over the runs."""
    lengths = stops - starts
    if lengths.size == 0 or lengths.sum() == 0:
        return
    idx = np.repeat(starts - np.cumsum(np.r_[0, lengths[:-1]]), lengths) + np.arange(lengths.sum())
    b[idx] = value


def enforce_min_durations(state: np.ndarray, min_on: int, min_off: int) -> np.ndarray:
    """Close short gaps, then drop short contacts, of a 1-D contact signal.

    Parameters
    ----------
    state : ndarray of bool, shape (F,)
    min_on, min_off : int
        Minimum contact and gap lengths (frames).

    Returns
    -------
    ndarray of bool, shape (F,)
        Gaps inside the clip shorter than ``min_off`` are filled (a gap touching a clip
        edge is left: what lies beyond is unknown); then contacts shorter than
        ``min_on`` are removed. Afterwards no contact is shorter than ``min_on`` and no
        interior gap shorter than ``min_off`` unless removing a short contact opened
        it next to a clip edge.
    """
    b = np.asarray(state, dtype=bool).copy()
    n = b.size
    s, e = _runs(~b)
    short = (e - s < min_off) & (s > 0) & (e < n)
    _set_runs(b, s[short], e[short], True)
    s, e = _runs(b)
    short = e - s < min_on
    _set_runs(b, s[short], e[short], False)
    return b


def debounced_contacts(character, *, ground: float, fps: float,
                       params: StoryParameters = DEFAULT_STORY) -> LimbContacts:
    """Ground contacts of one character, one per limb, debounced.

    Parameters
    ----------
    character : Character
    ground : float
        Height of the ground plane (m, world Y).
    fps : float
    params : StoryParameters

    Returns
    -------
    LimbContacts

    Notes
    -----
    For joint j: ``s_j = max(h_j / h_on, v_j / v_on)`` with ``h_j`` its height above the
    ground and ``v_j`` its speed (smoothed trajectories), both in units of the
    character's stature over :data:`REFERENCE_STATURE_M`; ``s_j <= 1`` means the joint
    can bear weight. A limb's score is the minimum over its joints (any joint of the
    foot will do), and :func:`hysteresis` switches it on at 1 and off above
    ``min(h_off / h_on, v_off / v_on)``. Then :func:`enforce_min_durations`.
    """
    p = params
    scale = _stature(character) / REFERENCE_STATURE_M
    if p.per_limb:
        names, joints = limb_groups(character)
    else:
        names = list(character.joint_names)
        joints = [np.array([j]) for j in range(character.n_joints)]
    used = np.unique(np.concatenate(joints)) if joints else np.zeros(0, dtype=np.int64)
    n_f = character.n_frames
    state = np.zeros((len(names), n_f), dtype=bool)
    if used.size == 0 or n_f < 2:
        return LimbContacts(names, joints, state)
    x = smooth_positions(character.positions[:, used], fps=fps, smooth_s=p.smooth_s)
    xc = np.ascontiguousarray(np.moveaxis(x, -1, 0))  # (3, F, U)
    g = np.gradient(xc, axis=1)  # metres per frame
    g *= g
    v = np.sqrt(g[0] + g[1] + g[2])
    v *= fps / (scale * p.support_speed)
    h = xc[1] - ground
    h /= scale * p.support_height
    score = np.maximum(h, v)  # (F, U)
    col = {int(j): k for k, j in enumerate(used.tolist())}
    limb_score = np.stack([score[:, [col[int(j)] for j in js]].min(axis=1) for js in joints],
                          axis=1)  # (F, L)
    off = min(p.release_height / p.support_height, p.release_speed / p.support_speed)
    if not p.debounce:
        off = 1.0
    on = hysteresis(limb_score, 1.0, off).T
    if p.debounce:
        m_on = max(1, int(round(p.min_contact_s * fps)))
        m_off = max(1, int(round(p.min_gap_s * fps)))
        on = np.stack([enforce_min_durations(row, m_on, m_off) for row in on])
    return LimbContacts(names, joints, on)


# ----------------------------------------------------------------------- pose term


def key_joints(character) -> np.ndarray:
    """Head, pelvis, left/right wrist and ankle joints, shape (K,).

    The joints of :func:`snapcore.motion.anatomy.body_landmarks` (``head``, ``pelvis``,
    ``wrist_L``, ``wrist_R``, ``ankle_L``, ``ankle_R``) when the skeleton names all six;
    else the first joint of each role (those found); with fewer than four, the root and
    every end joint (a joint without children).
    """
    return _key_joints_of(*_skeleton_key(character))


def _skeleton_key(character):
    return tuple(character.joint_names), tuple(np.asarray(character.parents).tolist())


@lru_cache(maxsize=64)
def _key_joints_of(names: tuple, parents: tuple) -> np.ndarray:
    lm = body_landmarks(names, parents)
    full = [lm.get(k) for k in _KEY_LANDMARKS]
    if all(j is not None for j in full):
        out = np.asarray(full, dtype=np.int64)
        out.flags.writeable = False
        return out
    roles, sides = _roles_sides_of(names, parents)
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
    nearly rigid distances over all frames (not from any one frame's pose): the
    distances between the two hip and the two shoulder joints, the vertical offsets,
    and the 5th percentile of the ankles' height above the ground (a planted foot),
    kept within 2-10 % of the stature.

    Returns
    -------
    ndarray of shape (6, 3), or None
        None when the skeleton does not name a head, a pelvis and both arms and legs
        (:func:`snapcore.motion.anatomy.body_landmarks`).
    """
    geometry = _stance_geometry(*_skeleton_key(character),
                                np.asarray(character.skeleton.offsets, dtype=float).tobytes())
    if geometry is None:
        return None
    idx, leg, spine, to_branch, arm = geometry
    stature = _stature(character)
    # one gather of the 8 joints used: hips, shoulders, ankles (L, R), pelvis, branch: (F, 8, 3)
    x = character.positions[:, idx]
    hip_w = float(np.median(np.linalg.norm(x[:, 0] - x[:, 1], axis=1))) / 2
    sh_w = float(np.median(np.linalg.norm(x[:, 2] - x[:, 3], axis=1))) / 2
    y = x[..., 1]
    ankle_h = float(np.percentile(y[:, 4:6] - ground, 5))
    ankle_h = float(np.clip(ankle_h, 0.02 * stature, 0.10 * stature))
    # the pelvis joint above the hip joints (below on some rigs): a rigid offset, whose
    # vertical part barely changes with the pelvis's tilt
    drop = float(np.median(y[:, 6] - 0.5 * (y[:, 0] + y[:, 1])))
    pelvis_h = ankle_h + leg + drop
    head_h = pelvis_h + spine
    # the shoulder joints above the joint both arms hang from (the chest): nearly rigid
    rise = float(np.median(0.5 * (y[:, 2] + y[:, 3]) - y[:, 7]))
    shoulder_h = pelvis_h + to_branch + rise
    wrist_h = shoulder_h - arm
    # hands hang beside the thighs, outside the shoulder joints by about a thigh's
    # half-thickness (measured at rest on the shared rigs: 0.03-0.05 statures)
    wrist_x = sh_w + _HAND_OUTSET * stature
    out = np.array([[0.0, head_h, 0.0], [0.0, pelvis_h, 0.0], [wrist_x, wrist_h, 0.0],
                    [-wrist_x, wrist_h, 0.0], [hip_w, ankle_h, 0.0], [-hip_w, ankle_h, 0.0]])
    return out if np.isfinite(out).all() else None


@lru_cache(maxsize=64)
def _stance_geometry(names: tuple, parents: tuple, offsets: bytes):
    """The skeleton's part of :func:`neutral_stance` (cached per skeleton), or None.

    Returns the joints to gather (hips L/R, shoulders L/R, ankles L/R, pelvis, the
    shoulders' common ancestor) and the lengths (m): hip to ankle, pelvis to head,
    pelvis to that ancestor, shoulder to wrist (means of the two sides).
    """
    lm = body_landmarks(names, parents)
    need = ("pelvis", "head", "shoulder_L", "shoulder_R", "wrist_L", "wrist_R", "hip_L",
            "hip_R", "ankle_L", "ankle_R")
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
    idx = np.array([lm["hip_L"], lm["hip_R"], lm["shoulder_L"], lm["shoulder_R"],
                    lm["ankle_L"], lm["ankle_R"], pelvis, branch], dtype=np.int64)
    sizes = (mean2(lambda s: chain(lm[f"hip_{s}"], lm[f"ankle_{s}"])),
             chain(pelvis, lm["head"]), chain(pelvis, branch),
             mean2(lambda s: chain(lm[f"shoulder_{s}"], lm[f"wrist_{s}"])))
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


def descriptor_of(points: np.ndarray, *, ground: float, stature: float) -> np.ndarray:
    """:func:`pose_descriptor` of key-joint positions, shape (F, K + K (K - 1) / 2).

    Parameters
    ----------
    points : ndarray of shape (F, K, 3)
        Metres, Y up.
    ground : float
    stature : float
        Metres.
    """
    x = np.asarray(points, dtype=float)
    k = x.shape[1]
    xc = np.ascontiguousarray(np.moveaxis(x, -1, 0))  # (3, F, K): reductions over 3 unrolled
    a, b = np.triu_indices(k, 1)
    d = xc[:, :, a] - xc[:, :, b]  # (3, F, P)
    d *= d
    dist = np.sqrt(d[0] + d[1] + d[2])
    out = np.empty((x.shape[0], k + a.size))
    out[:, :k] = xc[1] - ground
    out[:, k:] = dist
    out /= stature
    return out


def pose_descriptor(character, *, ground: float, fps: float, smooth_s: float = 0.05
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

    Returns
    -------
    ndarray of shape (F, K + K (K - 1) / 2)
        Heights of the K :func:`key_joints` above the ground, then their pairwise
        distances, all divided by the character's stature (dimensionless).
    """
    kj = key_joints(character)
    x = smooth_positions(character.positions[:, kj], fps=fps, smooth_s=smooth_s)
    return descriptor_of(x, ground=ground, stature=_stature(character))


def stance_departure(features: np.ndarray, neutral: np.ndarray, *, spread: float
                     ) -> np.ndarray:
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
    return 0.5 * np.square(z).sum(axis=1) / (spread ** 2 * math.log(2.0))


def pose_surprisal(features: np.ndarray, *, shrinkage: float = 0.5, noise: float = 0.02
                   ) -> np.ndarray:
    """Self-information (bits) of each frame's pose under a Gaussian of the clip's poses.

    Parameters
    ----------
    features : ndarray of shape (F, D)
        Pose descriptors (:func:`pose_descriptor`).
    shrinkage : float
        In [0, 1]: covariance ``(1 - a) S + a tr(S)/D I`` (Ledoit-Wolf style
        regularisation: a short clip cannot estimate D(D+1)/2 covariances).
    noise : float
        Standard deviation of capture noise in descriptor units, added as
        ``noise^2 I``: differences below it carry no information, and a static clip
        has a defined, constant surprisal of 0.

    Returns
    -------
    ndarray of shape (F,)
        ``I(i) = 1/2 (x_i - mu)^T C^-1 (x_i - mu) / ln 2``, the Gaussian's ``-log2 p``
        up to a constant that is the same for every frame.
    """
    x = np.asarray(features, dtype=float)
    n_f, d = x.shape
    z = x - x.mean(axis=0)
    cov = (z.T @ z) / max(n_f - 1, 1)
    cov = (1.0 - shrinkage) * cov + (shrinkage * np.trace(cov) / max(d, 1) + noise ** 2) * np.eye(d)
    # Cholesky: C = L L^T, m^2 = |L^-1 z|^2 (stable, no explicit inverse)
    chol = np.linalg.cholesky(cov)
    w = np.linalg.solve(chol, z.T)
    return 0.5 * np.square(w).sum(axis=0) / math.log(2.0)


def tail_surprisal(values: np.ndarray) -> np.ndarray:
    """``-log2`` of the fraction of frames whose value is at least this frame's, (F,).

    The empirical surprisal of "a pose at least this unusual" in the clip: bounded by
    ``log2 F`` (the most unusual frame), 0 for the least unusual, and the same for any
    monotone transform of ``values``. Ties share the larger fraction (a static clip
    gives 0 everywhere).
    """
    v = np.asarray(values, dtype=float)
    n = v.size
    if n == 0:
        return v.copy()
    srt = np.sort(v)
    at_least = n - np.searchsorted(srt, v, side="left")  # frames with value >= v_i
    return -np.log2(at_least / n)


# ----------------------------------------------------------------------- event term


def _half_gaussian(sigma_frames: float, sided: bool) -> tuple[np.ndarray, int]:
    """Kernel (peak 1 at offset 0) over offsets -r..r and r; one-sided: offsets >= 0."""
    if sigma_frames <= 0:
        return np.ones(1), 0
    r = int(math.ceil(3 * sigma_frames))
    off = np.arange(-r, r + 1)
    k = np.exp(-0.5 * (off / sigma_frames) ** 2)
    if sided:
        k = np.where(off >= 0, k, 0.0)
    return k, r


def event_surprisal(state: np.ndarray, *, fps: float, support_s: float = 0.2,
                    sided: bool = True) -> np.ndarray:
    """Information (bits) of the contact events, with temporal support, shape (F,).

    Parameters
    ----------
    state : ndarray of bool, shape (L, F)
        Debounced contacts per contactor.
    fps : float
    support_s : float
        Width (s) of the spreading kernel; 0: only the event frame.
    sided : bool
        Release events credit the frames after them, onsets the frames before them
        (where the limb is free); False: both sides.

    Notes
    -----
    Onset of contactor l at frame t: ``state[l, t]`` and not ``state[l, t-1]``; release
    at t: the first free frame. A contact running at a clip edge has no onset or release
    there (the clip cut it). For each (contactor, kind) with ``n`` events in ``F``
    frames, ``P = n / F`` is the probability that a frame carries such an event and
    each one carries ``-log2 P`` bits. Events of one frame add; the spread signal is
    ``sum_e I_e K(i - t_e)`` with ``K`` a (half-)Gaussian of peak 1.
    """
    st = np.asarray(state, dtype=bool)
    n_l, n_f = st.shape
    onset = np.zeros(n_f)
    release = np.zeros(n_f)
    if n_f < 2 or n_l == 0:
        return onset
    d = np.diff(st.astype(np.int8), axis=1)  # (L, F-1): +1 onset at t+1, -1 release at t+1
    for kind, out in ((1, onset), (-1, release)):
        hit = d == kind
        n = hit.sum(axis=1)  # events per contactor
        bits = np.where(n > 0, -np.log2(np.maximum(n, 1) / n_f), 0.0)
        out[1:] += (hit * bits[:, None]).sum(axis=0)
    kernel, r = _half_gaussian(support_s * fps, sided)
    if r == 0:
        return onset + release
    # np.convolve(x, k)[i + r] = sum_t x[t] k[i - t + r]: kernel index r + (i - t), so the
    # "after" kernel (offsets >= 0) credits frames i >= t, its mirror frames i <= t
    after = np.convolve(release, kernel)[r:r + n_f]
    before = np.convolve(onset, kernel[::-1])[r:r + n_f]
    return after + before


def contact_state_entropy(state: np.ndarray) -> np.ndarray:
    """The paper's event entropy on debounced contacts, for ablation, shape (F,).

    ``-p_l log2 p_l`` (``p_l``: fraction of frames contactor l touches, eq. 6) at each
    onset and release frame of l (eq. 7, transitions mode).
    """
    st = np.asarray(state, dtype=bool)
    n_l, n_f = st.shape
    out = np.zeros(n_f)
    if n_f < 2 or n_l == 0:
        return out
    p = st.mean(axis=1)
    h = np.where(p > 0, -p * np.log2(np.where(p > 0, p, 1.0)), 0.0)
    mark = np.diff(st.astype(np.int8), axis=1) != 0
    out[1:] = (mark * h[:, None]).sum(axis=0)
    return out


# ----------------------------------------------------------------------- combination


def temporal_support(values: np.ndarray, *, fps: float, support_s: float) -> np.ndarray:
    """Gaussian-weighted average over ``support_s`` seconds, zero beyond the clip, (F,).

    Near a clip edge part of the window lies outside the clip, where there is no
    information: a pose the clip shows only one side of gets less support.
    """
    v = np.asarray(values, dtype=float)
    sigma = support_s * fps
    if sigma <= 0 or v.size == 0:
        return v.copy()
    r = int(math.ceil(3 * sigma))
    k = np.exp(-0.5 * (np.arange(-r, r + 1) / sigma) ** 2)
    k /= k.sum()
    return np.convolve(v, k)[r:r + v.size]


def _roles_sides(character) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """Body role and side of each joint, read from the names (cached per skeleton)."""
    return _roles_sides_of(tuple(character.joint_names),
                           tuple(np.asarray(character.parents).tolist()))


@lru_cache(maxsize=64)
def _roles_sides_of(names: tuple, parents: tuple):
    return tuple(joint_roles(names, parents)), tuple(joint_sides(names))


def _stature(character) -> float:
    h = float(character.height)
    return h if np.isfinite(h) and h > 0 else REFERENCE_STATURE_M


def story_information(scene, params: StoryParameters = DEFAULT_STORY) -> StoryInformation:
    """Per-frame story information of ``scene`` (see the module docstring).

    Parameters
    ----------
    scene : Scene
    params : StoryParameters

    Returns
    -------
    StoryInformation

    Warns
    -----
    UserWarning
        When a term is constant over the clip (a static clip, no contact events): it
        contributes 0 (:func:`snapcore.select.pose.minmax`).
    """
    p = params
    t0 = time.perf_counter()
    n_f, fps = scene.n_frames, float(scene.fps)
    pose_bits = np.zeros(n_f)
    event_bits = np.zeros(n_f)
    contacts = []
    t_pose = t_event = 0.0
    for c in scene.characters:
        ta = time.perf_counter()
        if p.w_pose > 0:
            feats = pose_descriptor(c, ground=scene.ground, fps=fps, smooth_s=p.smooth_s)
            if p.novelty:
                pose_bits += tail_surprisal(pose_surprisal(feats, shrinkage=p.shrinkage,
                                                           noise=p.noise))
            if p.stance:
                neutral = neutral_stance(c, ground=scene.ground)
                if neutral is not None:
                    nd = descriptor_of(neutral[None], ground=0.0, stature=_stature(c))[0]
                    pose_bits += stance_departure(feats, nd, spread=p.stance_spread)
        tb = time.perf_counter()
        lc = debounced_contacts(c, ground=scene.ground, fps=fps, params=p)
        contacts.append(lc)
        if p.w_event > 0:
            if p.event_model == "surprisal":
                event_bits += event_surprisal(lc.state, fps=fps, support_s=p.event_support_s,
                                              sided=p.sided_support)
            else:
                event_bits += contact_state_entropy(lc.state)
        t_pose += tb - ta
        t_event += time.perf_counter() - tb
    for bits in (pose_bits, event_bits):
        if float(bits.max() - bits.min()) <= ZERO_BITS:
            bits[:] = 0.0
    with warnings.catch_warnings():
        # a term that is switched off is constant by design: no warning for it
        if p.w_pose == 0 or p.w_event == 0:
            warnings.simplefilter("ignore")
        pose = minmax(pose_bits, name="story pose information") if p.w_pose > 0 else pose_bits * 0
        # No contact event at all (a punch with both feet planted) leaves the event term
        # 0 by construction: expected, not a symptom worth a warning.
        event = (minmax(event_bits, name="story event information")
                 if p.w_event > 0 and event_bits.any() else event_bits * 0)
    if p.combine == "bits":
        total = temporal_support(p.w_pose * pose_bits + p.w_event * event_bits, fps=fps,
                                 support_s=p.support_s)
    else:
        total = temporal_support(p.w_pose * pose + p.w_event * event, fps=fps,
                                 support_s=p.support_s)
    timings = {"pose_term": t_pose, "contacts_events": t_event,
               "story": time.perf_counter() - t0}
    return StoryInformation(pose_bits, event_bits, pose, event, total, contacts, p, timings)
