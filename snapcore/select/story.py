"""Story information: the default pose selector, a repair of pose entropy (paper §3.1).

The paper's pose entropy (:mod:`snapcore.select.paper`, method ``paper``) often lands on a
footfall beside the action: contact events flicker (dozens of onsets and releases per
clip, every ankle, toe and toe-end joint its own event), each event frame gets the
normalised global term ~1, and ``-p log2 p`` of a contact *state* rewards contacts that
hold ~37 % of the time (feet) instead of rare ones. A pose term that only measures
rarity *within the clip* fails the other way: where a gesture fills most of a short
clip, the performer standing at rest before and after it is the rare pose, and wins.

This module keeps the paper's structure -- the information of a frame is a pose term
plus an event term, the pose is the argmax -- and measures every ingredient as
*self-information* in bits (eq. 1: ``I = -log2 P``), so that the terms add:

1. **Departure from the neutral stance** (``stance``; "extreme poses" of §3.1.1): the
   surprisal of the frame's pose for a person standing at rest, under an isotropic
   Gaussian of spread ``stance_spread`` (statures) around the character's neutral
   stance, ``I = 1/2 |x_i - n|^2 / spread^2 / ln 2``. The neutral stance
   (:func:`neutral_stance`) is built from the skeleton's own bone lengths and rigid body
   measurements -- standing straight, arms hanging -- never from the clip's first
   frames (a clip may start mid-action). This is what finds the action whatever share
   of the clip it fills: a raised hand, a bow, a kick depart from it; the rest pose
   does not.
   **The trunk** (``trunk``) gets its own, tighter spread (:func:`trunk_departure`): a
   person at rest holds the head over the pelvis within a few centimetres
   (``trunk_spread``, 0.03 statures), the hands within tens, so a bow -- the head
   dropping 5-12 cm and leaning forward while the rest of the body barely moves --
   carries tens of bits even where the arms depart more throughout (hands clasped at
   the chest). The spread widens by the legs' own departure (bent knees, a lunge, a
   raised foot): a trunk that leans with the legs in a crouch, a landing or a kick is
   carried by them, and the stance term already counts that pose.
2. **Novelty in the clip** (``novelty``): how unusual the pose is among the clip's own
   poses -- the Mahalanobis distance under a Gaussian of all the clip's poses
   (covariance shrunk towards a multiple of the identity and widened by the capture
   noise), turned into the empirical tail surprisal ``-log2 (share of frames at least
   as far out)``, so that it is at most ``log2 F`` bits, like one event: it separates
   poses that depart equally (the punch from the held guard), and cannot outweigh a
   large departure by rarity alone.
   Its weight ``w_novelty`` (0.25) keeps rarity alone from outweighing a departure:
   where a shallow bow fills most of a clip the rest pose is the rare one.
   Both use a descriptor invariant to yaw, translation and unit (:func:`pose_descriptor`):
   the heights above the ground of six key joints (head, pelvis, wrists, ankles), their
   pairwise distances and pairwise horizontal distances (a bow's lean, a reach),
   divided by the character's stature.
3. **Event information** (``w_event``; §3.1.2): contacts with the ground are *debounced*
   per limb (``debounce``, ``per_limb``) -- one leg (foot and toes, a kneeling knee),
   one arm or the trunk is one contact, whatever of its joints touch -- with
   hysteresis on height and speed and minimum durations for a contact and for a gap.
   Each onset and each release is an event; an event of a kind (limb, onset or
   release) that happens ``n`` times in ``F`` frames carries ``-log2(n / F)`` bits
   (rare events, a two-foot take-off, carry most). Its information is given temporal
   support on the side where the limb is free (``event_support_s``,
   ``sided_support``): a release credits the frames after it (the swing, the flight),
   an onset the frames before it (the approach).
   **Strikes** (``strikes``, :mod:`snapcore.select.strikes`) are events too: a speed
   peak of a wrist or an ankle above ``strike_speed`` (a punch, a kick, a cut -- not a
   gesture) carries ``-log2(n / F)`` bits and credits the frames before it, the
   approach (raise, backswing) that the annotations call the action; the settling after
   it, however long it is held, is not credited.
4. **Combination** (``combine``): the pose bits (1 + 2: stance, trunk, novelty)
   weighted by ``w_pose`` plus the event bits (contacts, strikes) weighted by
   ``w_event``, then averaged
   over a Gaussian window of ``support_s`` with nothing outside the clip (``temporal_support``: a frame whose
   surroundings the clip does not show has less support). Averaging is linear, so the
   supported terms add up to the total exactly (:attr:`StoryInformation.terms`).
   ``combine="normalised"`` min-max normalises the pose and event terms first, as the
   paper's eq. 9 does (for ablation). The pose is the argmax; the top-k are distinct
   peaks (:func:`snapcore.select.pose_selection.top_peaks`).

Nothing depends on a frame's position in the clip (no preference for the middle), and
every ingredient can be switched off or replaced for ablation through
:class:`StoryParams` (the ablation table of docs/method.md). Everything is vectorised over
frames and joints; the Python loops run over characters and limbs.

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

from snapcore.errors import SelectionError
from snapcore.motion.anatomy import REFERENCE_STATURE_M, stature_of
from snapcore.select.signals import (
    enforce_min_durations,
    half_gaussian,
    hysteresis,
    minmax,
    true_runs,
)
from snapcore.select.stance import (
    descriptor_of,
    joint_trajectories,
    key_joints,
    key_positions,
    neutral_stance,
    pose_descriptor,
    stance_departure,
    trunk_departure,
)
from snapcore.select.strikes import rows_and_speeds, strike_surprisal, strike_surprisal_of

__all__ = [
    "StoryParams",
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
    "tail_surprisal",
    "neutral_stance",
    "descriptor_of",
    "stance_departure",
    "trunk_departure",
    "COMBINE_MODES",
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
_CONTACT_ROLES = frozenset(
    {"shin", "foot", "toe", "forearm", "hand", "pelvis", "spine", "chest", "head"}
)
#: How the pose and event terms are combined (:class:`StoryParams`).
COMBINE_MODES = ("bits", "normalised")
#: Event-information models.
EVENT_MODELS = ("surprisal", "entropy")
#: A term whose range over the clip is below this many bits is constant: rounding in
#: the smoothing of a still clip leaves ~1e-28 bits, which min-max would blow up.
ZERO_BITS = 1e-9


@dataclass(frozen=True)
class StoryParams:
    """Every choice of the story selector, with the switches used for ablation.

    Lengths are metres for a person of :data:`REFERENCE_STATURE_M` and scale with the
    character's stature; durations are seconds and do not depend on the frame rate.

    Attributes
    ----------
    w_pose, w_event : float
        Weights of the pose (stance + trunk + novelty) and event terms (eq. 9's weights, on
        bits, or on the normalised terms with ``combine="normalised"``); 0 switches a
        term off.
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
    stance : bool
        Count the departure from the neutral stance (:func:`stance_departure`).
    stance_spread : float
        Spread (statures) of a person at rest around the neutral stance; the smaller,
        the more a departure weighs against novelty and events.
    trunk : bool
        Count the trunk's flexion from upright (:func:`trunk_departure`): a bow.
    trunk_spread : float
        Spread (statures) of the head around its place above the pelvis for a person
        at rest (0.03: about 5 cm); widened by the legs' departure.
    strikes : bool
        Count the strikes (:func:`~snapcore.select.strikes.strike_surprisal`): speed
        peaks of a wrist or an ankle, credited to their approach; part of the event
        term.
    strike_speed : float
        Least peak speed of a strike, statures per second (2.5: 4.4 m/s at 1.75 m).
    novelty : bool
        Count the pose's novelty in the clip (:func:`tail_surprisal` of
        :func:`pose_surprisal`).
    w_novelty : float
        Weight of the novelty relative to the stance departure (both in bits).
    horizontal : bool
        The pose descriptor includes the key joints' horizontal distances (a lean, a
        reach); False: heights and 3-D distances only.
    combine : {"bits", "normalised"}
        Add the terms in bits, or min-max normalise each first (eq. 9).
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
    stance_spread: float = 0.15
    trunk: bool = True
    trunk_spread: float = 0.03
    strikes: bool = True
    strike_speed: float = 2.5
    novelty: bool = True
    w_novelty: float = 0.25
    horizontal: bool = True
    combine: str = "bits"

    def __post_init__(self):
        for f in fields(self):
            v = getattr(self, f.name)
            if isinstance(v, bool) or isinstance(v, str):
                continue
            if not (np.isfinite(v) and v >= 0):
                raise SelectionError(f"StoryParams.{f.name} must be a non-negative number, got {v}")
        if self.combine not in COMBINE_MODES:
            raise SelectionError(
                f"StoryParams.combine must be one of "
                f"{', '.join(COMBINE_MODES)}, got {self.combine!r}"
            )
        if not self.stance_spread > 0:
            raise SelectionError(f"StoryParams.stance_spread must be > 0, got {self.stance_spread}")
        if self.event_model not in EVENT_MODELS:
            raise SelectionError(
                f"StoryParams.event_model must be one of "
                f"{', '.join(EVENT_MODELS)}, got {self.event_model!r}"
            )
        if not self.shrinkage <= 1:
            raise SelectionError(f"StoryParams.shrinkage must be in [0, 1], got {self.shrinkage}")
        if self.release_height < self.support_height or self.release_speed < self.support_speed:
            raise SelectionError(
                "StoryParams: release thresholds must not be below the "
                "support thresholds (hysteresis)"
            )
        if self.w_pose + self.w_event <= 0:
            raise SelectionError("StoryParams: at least one of w_pose, w_event must be > 0")

    def with_(self, **changes) -> StoryParams:
        """A copy with ``changes`` (for ablation)."""
        return replace(self, **changes)


#: The defaults of ``snapshot select``.
DEFAULT_STORY = StoryParams()


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
        s, e = true_runs(self.state[limb])
        return list(zip(s.tolist(), (e - 1).tolist()))


@dataclass
class StoryInformation:
    """Per-frame story information of a scene.

    Attributes
    ----------
    stance_bits, trunk_bits, novelty_bits, event_bits, strike_bits : ndarray of shape (F,)
        The ingredients (bits, summed over characters), before weights and support.
    terms : dict of str to ndarray of shape (F,)
        The weighted, supported terms, which add up to ``total`` exactly:
        ``stance``, ``trunk``, ``novelty``, ``events``, ``strikes`` (bits) with
        ``combine="bits"``;
        ``pose`` and ``events`` (normalised) with ``combine="normalised"``.
    total : ndarray of shape (F,)
        The score whose argmax is the pose.
    contacts : list of LimbContacts
        Per character.
    params : StoryParams
    timings_s : dict
    """

    stance_bits: np.ndarray
    trunk_bits: np.ndarray
    novelty_bits: np.ndarray
    event_bits: np.ndarray
    strike_bits: np.ndarray
    terms: dict
    total: np.ndarray
    contacts: list[LimbContacts]
    params: StoryParams
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
    sk = character.skeleton
    names, joints = _limb_groups_of(sk.roles, sk.sides)
    return list(names), [j.copy() for j in joints]


@lru_cache(maxsize=64)
def _limb_groups_of(roles: tuple, sides: tuple) -> tuple[tuple[str, ...], tuple[np.ndarray, ...]]:
    """:func:`limb_groups` of a skeleton's roles and sides, once per skeleton (a loop
    over its joints; the result is read-only)."""
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
    names = tuple(n for n in order if n in groups)
    joints = tuple(np.asarray(groups[n], dtype=np.int64) for n in names)
    for js in joints:
        js.flags.writeable = False
    return names, joints


def debounced_contacts(
    character,
    *,
    ground: float,
    fps: float,
    params: StoryParams = DEFAULT_STORY,
    _tracks: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
) -> LimbContacts:
    """Ground contacts of one character, one per limb, debounced.

    Parameters
    ----------
    character : Character
    ground : float
        Height of the ground plane (m, world Y).
    fps : float
    params : StoryParams
    _tracks : (joints, heights, speeds) or None
        Internal (:func:`story_information`): sorted joints (A,) including every limb
        joint, with their :func:`_tracks` heights and speeds, (F, A) each, already
        computed for the story's other terms (one gather of the character's positions).

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
    scale = stature_of(character) / REFERENCE_STATURE_M
    names, joints, used = _contact_joints(character, p)
    n_f = character.n_frames
    state = np.zeros((len(names), n_f), dtype=bool)
    if used.size == 0 or n_f < 2:
        return LimbContacts(names, joints, state)
    if _tracks is None:
        # in increasing joint order: gathering unsorted joints took 2.5 times as long
        x = joint_trajectories(character, used, fps=fps, smooth_s=p.smooth_s)  # (F, U, 3)
        _tracks = (used, *_heights_speeds(x))
    have, height, speed = _tracks
    v = speed * (fps / (scale * p.support_speed))
    h = height - ground
    h /= scale * p.support_height
    score = np.maximum(h, v, out=h)  # (F, A)
    col = np.searchsorted(have, np.concatenate(joints))  # the limbs' columns, limb after limb
    ends = np.cumsum([j.size for j in joints]).tolist()
    limb_score = np.stack(
        [score[:, col[e - j.size : e]].min(axis=1) for j, e in zip(joints, ends)], axis=1
    )  # (F, L)
    off = min(p.release_height / p.support_height, p.release_speed / p.support_speed)
    if not p.debounce:
        off = 1.0
    on = hysteresis(limb_score, 1.0, off).T
    if p.debounce:
        m_on = max(1, int(round(p.min_contact_s * fps)))
        m_off = max(1, int(round(p.min_gap_s * fps)))
        on = enforce_min_durations(on, m_on, m_off)
    return LimbContacts(names, joints, np.ascontiguousarray(on))


def _contact_joints(character, p: StoryParams) -> tuple[list, list, np.ndarray]:
    """The contactors' names and joints, and all their joints sorted (U,)."""
    if p.per_limb:
        names, joints = limb_groups(character)
    else:
        names = list(character.joint_names)
        joints = [np.array([j]) for j in range(character.n_joints)]
    used = np.unique(np.concatenate(joints)) if joints else np.zeros(0, dtype=np.int64)
    return names, joints, used


def _heights_speeds(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """World heights (m) and speeds (m per frame) of trajectories (F, N, 3): (F, N) each.

    The speed is the strikes' (:func:`~snapcore.select.strikes.rows_and_speeds`:
    ``np.gradient`` written out, whose checks and slicing took a third of the contacts'
    time).
    """
    xc, v = rows_and_speeds(x)
    return xc[1], v


# ----------------------------------------------------------------------- pose term


def pose_surprisal(
    features: np.ndarray, *, shrinkage: float = 0.5, noise: float = 0.02
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
    cov = (1.0 - shrinkage) * cov + (shrinkage * np.trace(cov) / max(d, 1) + noise**2) * np.eye(d)
    # Cholesky: C = L L^T, m^2 = |L^-1 z|^2; L^-1 of the small, well-conditioned (shrunk,
    # noise-widened) D x D factor once, then one matrix product over the frames (a
    # solve with F right-hand sides is 4x slower)
    w = z @ np.linalg.inv(np.linalg.cholesky(cov)).T
    # row sums of squares as one pass (``einsum``; ``(w * w).sum(axis=1)`` over rows of
    # D ~ 36 values took twice as long): the same terms, added in another order
    m2 = np.einsum("ij,ij->i", w, w)
    m2 *= 0.5 / math.log(2.0)
    return m2


def tail_surprisal(values: np.ndarray) -> np.ndarray:
    """``-log2`` of the fraction of frames whose value is at least this frame's, (F,).

    The empirical surprisal of "a pose at least this unusual" in the clip: bounded by
    ``log2 F`` (the most unusual frame), 0 for the least unusual, and the same for any
    monotone transform of ``values``. Ties share the larger fraction; values that
    span at most :data:`ZERO_BITS` are all ties (rounding noise on a static clip),
    giving 0 everywhere.
    """
    v = np.asarray(values, dtype=float)
    n = v.size
    if n == 0 or float(v.max() - v.min()) <= ZERO_BITS:
        return np.zeros(n)
    srt = np.sort(v)
    at_least = n - np.searchsorted(srt, v, side="left")  # frames with value >= v_i
    return -np.log2(at_least / n)


# ----------------------------------------------------------------------- event term


def event_surprisal(
    state: np.ndarray, *, fps: float, support_s: float = 0.2, sided: bool = True
) -> np.ndarray:
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
    onset, release = _event_marks(state)
    return _spread_events(onset, release, fps=fps, support_s=support_s, sided=sided)


def _event_marks(state: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The onsets' and releases' bits at their frames (:func:`event_surprisal`), (F,) each."""
    st = np.asarray(state, dtype=bool)
    n_l, n_f = st.shape
    onset = np.zeros(n_f)
    release = np.zeros(n_f)
    if n_f < 2 or n_l == 0:
        return onset, release
    d = np.diff(st.astype(np.int8), axis=1)  # (L, F-1): +1 onset at t+1, -1 release at t+1
    for kind, out in ((1, onset), (-1, release)):
        hit = d == kind
        n = hit.sum(axis=1)  # events per contactor
        bits = np.where(n > 0, -np.log2(np.maximum(n, 1) / n_f), 0.0)
        out[1:] += (hit * bits[:, None]).sum(axis=0)
    return onset, release


def _spread_events(onset, release, *, fps: float, support_s: float, sided: bool) -> np.ndarray:
    """Onsets credited before, releases after (:func:`event_surprisal`), (F,)."""
    n_f = onset.size
    kernel, r = half_gaussian(support_s * fps, sided)
    if r == 0:
        return onset + release
    # np.convolve(x, k)[i + r] = sum_t x[t] k[i - t + r]: kernel index r + (i - t), so the
    # "after" kernel (offsets >= 0) credits frames i >= t, its mirror frames i <= t
    after = np.convolve(release, kernel)[r : r + n_f]
    before = np.convolve(onset, kernel[::-1])[r : r + n_f]
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
    return np.convolve(v, k)[r : r + v.size]


def story_information(scene, params: StoryParams = DEFAULT_STORY) -> StoryInformation:
    """Per-frame story information of ``scene`` (see the module docstring).

    Parameters
    ----------
    scene : Scene
    params : StoryParams

    Returns
    -------
    StoryInformation

    Warns
    -----
    UserWarning
        When the pose term is constant over the clip (a static clip): the pick is then
        arbitrary (:func:`snapcore.select.pose_methods.select_pose` warns too); and when
        a character's skeleton does not name the joints of a neutral stance (its
        departure is left out).
    """
    p = params
    t0 = time.perf_counter()
    n_f, fps = scene.n_frames, float(scene.fps)
    stance_bits = np.zeros(n_f)
    trunk_bits = np.zeros(n_f)
    novelty_bits = np.zeros(n_f)
    event_bits = np.zeros(n_f)
    strike_bits = np.zeros(n_f)
    onset_marks, release_marks = np.zeros(n_f), np.zeros(n_f)
    contacts = []
    t_pose = t_event = 0.0
    for c in scene.characters:
        ta = time.perf_counter()
        pose_on = p.w_pose > 0 and (p.novelty or p.stance or p.trunk)
        strikes_on = p.w_event > 0 and p.strikes and p.event_model == "surprisal"
        tracks = None
        if (pose_on or strikes_on) and c.n_frames >= 3:
            # one gather of the key joints and the contacts' joints (sorted), their
            # heights and speeds once for the contacts and the strikes: each step
            # gathering its own joints read the (F, J, 3) positions twice per character
            kj = key_joints(c)
            have = np.union1d(kj, _contact_joints(c, p)[2])
            xa = joint_trajectories(c, have, fps=fps, smooth_s=p.smooth_s)  # (F, A, 3)
            x = np.take(xa, np.searchsorted(have, kj), axis=1)  # key_positions
            tracks = (have, *_heights_speeds(xa))
        elif pose_on or strikes_on:
            x = key_positions(c, fps=fps, smooth_s=p.smooth_s)
        if pose_on:
            feats = descriptor_of(
                x, ground=scene.ground, stature=stature_of(c), horizontal=p.horizontal
            )
            if p.novelty:
                novelty_bits += tail_surprisal(
                    pose_surprisal(feats, shrinkage=p.shrinkage, noise=p.noise)
                )
            neutral = neutral_stance(c, ground=scene.ground) if p.stance or p.trunk else None
            if neutral is None and (p.stance or p.trunk):
                warnings.warn(
                    f"{c.name}: the skeleton does not name a head, pelvis, arms "
                    "and legs; its pose term leaves out the departure from "
                    "a neutral stance",
                    stacklevel=2,
                )
            elif neutral is not None:
                if p.stance:
                    nd = descriptor_of(
                        neutral[None], ground=0.0, stature=stature_of(c), horizontal=p.horizontal
                    )[0]
                    stance_bits += stance_departure(feats, nd, spread=p.stance_spread)
                if p.trunk:
                    trunk_bits += trunk_departure(
                        x, neutral, stature=stature_of(c), spread=p.trunk_spread
                    )
        tb = time.perf_counter()
        lc = debounced_contacts(c, ground=scene.ground, fps=fps, params=p, _tracks=tracks)
        contacts.append(lc)
        if p.w_event > 0:
            if p.event_model == "surprisal":
                # the characters' marks first, spread once after the loop (linear)
                on_m, off_m = _event_marks(lc.state)
                onset_marks += on_m
                release_marks += off_m
            else:
                event_bits += contact_state_entropy(lc.state)
        if strikes_on and tracks is not None:
            # strike_speeds' effectors (wrists and ankles of the six key joints)
            eff = kj[2:6] if kj.size == 6 else kj
            speed = np.take(tracks[2], np.searchsorted(have, eff), axis=1)
            speed *= fps / stature_of(c)
            strike_bits += strike_surprisal_of(
                speed, fps=fps, threshold=p.strike_speed, support_s=0
            )
        elif strikes_on:  # the marks (support 0), spread after the loop
            strike_bits += strike_surprisal(
                x, fps=fps, stature=stature_of(c), threshold=p.strike_speed, support_s=0
            )
        t_pose += tb - ta
        t_event += time.perf_counter() - tb
    if p.w_event > 0 and p.event_model == "surprisal":
        sup = {"fps": fps, "support_s": p.event_support_s}
        event_bits = _spread_events(onset_marks, release_marks, sided=p.sided_support, **sup)
        kernel, r = half_gaussian(p.event_support_s * fps, True)  # strikes: before them
        strike_bits = np.convolve(strike_bits, kernel[::-1])[r : r + n_f] if r else strike_bits
    for bits in (stance_bits, trunk_bits, novelty_bits, event_bits, strike_bits):
        if float(bits.max() - bits.min()) <= ZERO_BITS:
            bits[:] = 0.0
    pose_bits = stance_bits + trunk_bits + novelty_bits
    if p.w_pose > 0 and not pose_bits.any():
        warnings.warn(
            "story pose information is constant over the clip (static clip?); it contributes 0",
            stacklevel=2,
        )

    def support(v):
        return temporal_support(v, fps=fps, support_s=p.support_s)

    if p.combine == "bits":
        terms = {
            "stance": support(p.w_pose * stance_bits),
            "trunk": support(p.w_pose * trunk_bits),
            "novelty": support(p.w_pose * p.w_novelty * novelty_bits),
            "events": support(p.w_event * event_bits),
            "strikes": support(p.w_event * strike_bits),
        }
    else:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # constant terms warned about above
            pose = minmax(pose_bits)
            event = minmax(event_bits + strike_bits)
        terms = {"pose": support(p.w_pose * pose), "events": support(p.w_event * event)}
    total = np.sum(list(terms.values()), axis=0)
    timings = {"pose_term": t_pose, "contacts_events": t_event, "story": time.perf_counter() - t0}
    return StoryInformation(
        stance_bits,
        trunk_bits,
        novelty_bits,
        event_bits,
        strike_bits,
        terms,
        total,
        contacts,
        p,
        timings,
    )
