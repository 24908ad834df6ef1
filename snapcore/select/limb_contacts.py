"""Ground contacts of the story selector: one per limb, debounced.

Each leg (shin, foot and toes), each arm (forearm and hand) and the trunk is one
*contactor*, whatever of its joints touch (:func:`limb_groups`). A contactor is in
contact while one of its joints is low and slow, with hysteresis on both and minimum
durations for a contact and for a gap (:func:`debounced_contacts`): the flickering
per-joint contacts of the paper's pose entropy become a handful of onsets and releases,
the events of :mod:`snapcore.select.contact_events`.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from snapcore.motion.anatomy import REFERENCE_STATURE_M, stature_of
from snapcore.select.signals import enforce_min_durations, hysteresis_rows, true_runs
from snapcore.select.story_params import DEFAULT_STORY, StoryParams
from snapcore.select.tracks import JointTracks

__all__ = [
    "LimbContacts",
    "limb_groups",
    "contactor_joints",
    "debounced_contacts",
    "contacts_from_tracks",
    "limb_scores",
    "debounce_scores",
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
    names, joints, _ = _contactors_of(sk.roles, sk.sides)
    return list(names), [j.copy() for j in joints]


@lru_cache(maxsize=64)
def _contactors_of(roles: tuple, sides: tuple) -> tuple[tuple, tuple, np.ndarray]:
    """:func:`limb_groups` of a skeleton's roles and sides and their joints sorted, once
    per skeleton (a loop over its joints; the arrays are read-only)."""
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
    used = np.unique(np.concatenate(joints)) if joints else np.zeros(0, dtype=np.int64)
    for js in (*joints, used):
        js.flags.writeable = False
    return names, joints, used


def debounced_contacts(
    character, *, ground: float, fps: float, params: StoryParams = DEFAULT_STORY
) -> LimbContacts:
    """Ground contacts of one character, one per limb, debounced.

    Parameters
    ----------
    character : Character
    ground : float
        Height of the ground plane (m, world Y).
    fps : float
    params : StoryParams

    Returns
    -------
    LimbContacts

    Notes
    -----
    For joint j: ``s_j = max(h_j / h_on, v_j / v_on)`` with ``h_j`` its height above the
    ground and ``v_j`` its speed (smoothed trajectories), both in units of the
    character's stature over :data:`~snapcore.motion.anatomy.REFERENCE_STATURE_M`;
    ``s_j <= 1`` means the joint can bear weight. A limb's score is the minimum over its
    joints (any joint of the foot will do), and :func:`~snapcore.select.signals.hysteresis`
    switches it on at 1 and off above ``min(h_off / h_on, v_off / v_on)``. Then
    :func:`~snapcore.select.signals.enforce_min_durations`.
    """
    names, joints, used = contactor_joints(character, params)
    if used.size == 0 or character.n_frames < 2:
        return _contacts(names, joints, np.zeros((len(names), character.n_frames), dtype=bool))
    tracks = JointTracks.of(character, used, fps=fps, smooth_s=params.smooth_s)
    return contacts_from_tracks(tracks, character, ground=ground, fps=fps, params=params)


def contacts_from_tracks(
    tracks: JointTracks, character, *, ground: float, fps: float, params: StoryParams
) -> LimbContacts:
    """:func:`debounced_contacts` from the character's :class:`JointTracks`.

    :func:`debounce_scores` of :func:`limb_scores`. For a caller that has the tracks
    already: the story (:func:`snapcore.select.story.story_information`) gathers the
    key joints' and the contactors' tracks once for all its terms (and debounces its
    characters' scores in one call).

    Parameters
    ----------
    tracks : JointTracks
        Of ``character``, holding every joint of :func:`contactor_joints` (and maybe
        others), smoothed with ``params.smooth_s``.
    character : Character
    ground : float
    fps : float
    params : StoryParams
    """
    names, joints, _ = contactor_joints(character, params)
    if not joints or character.n_frames < 2:
        return _contacts(names, joints, np.zeros((len(names), character.n_frames), dtype=bool))
    scores = limb_scores(tracks, character, ground=ground, fps=fps, params=params)
    return _contacts(names, joints, debounce_scores(scores, fps=fps, params=params))


def _contacts(names: list, joints: list, state: np.ndarray) -> LimbContacts:
    """``LimbContacts`` with the caller's own (writeable) copies of the cached joints."""
    return LimbContacts(names, [j.copy() for j in joints], state)


def limb_scores(
    tracks: JointTracks, character, *, ground: float, fps: float, params: StoryParams
) -> np.ndarray:
    """Each contactor's weight-bearing score per frame, shape (L, F).

    ``min_j max(h_j / h_on, v_j / v_on)`` over the contactor's joints (see
    :func:`debounced_contacts`): at most 1 where it can bear weight. ``tracks`` as for
    :func:`contacts_from_tracks`; at least one contactor.
    """
    p = params
    scale = stature_of(character) / REFERENCE_STATURE_M
    _, joints, _ = contactor_joints(character, p)
    v = tracks.speed * (fps / (scale * p.support_speed))
    h = tracks.height - ground
    h /= scale * p.support_height
    score = np.maximum(h, v, out=h)  # (A, F)
    # the limbs' rows, limb after limb, then each limb's minimum over its block of rows
    # (``np.minimum.reduceat(rows, starts, axis=0)`` took 13 times as long)
    rows = score.take(tracks.columns(np.concatenate(joints)), axis=0)
    out = np.empty((len(joints), score.shape[1]))
    start = 0
    for i, j in enumerate(joints):
        np.minimum.reduce(rows[start : start + j.size], axis=0, out=out[i])
        start += j.size
    return out


def debounce_scores(scores: np.ndarray, *, fps: float, params: StoryParams) -> np.ndarray:
    """Contact states from :func:`limb_scores`, shape (L, F) of bool, each row on its own.

    :func:`~snapcore.select.signals.hysteresis_rows` along the frames (on at 1, off above
    ``min(h_off / h_on, v_off / v_on)``), then
    :func:`~snapcore.select.signals.enforce_min_durations` (with ``params.debounce``).
    Rows are independent: several characters' scores stacked give their states stacked.
    """
    p = params
    off = min(p.release_height / p.support_height, p.release_speed / p.support_speed)
    if not p.debounce:
        off = 1.0
    on = hysteresis_rows(scores, 1.0, off)
    if p.debounce:
        m_on = max(1, int(round(p.min_contact_s * fps)))
        m_off = max(1, int(round(p.min_gap_s * fps)))
        on = enforce_min_durations(on, m_on, m_off)
    return np.ascontiguousarray(on)


def contactor_joints(character, params: StoryParams) -> tuple[list, list, np.ndarray]:
    """The contactors' names and joints (:func:`limb_groups`, or every joint on its own
    when ``params.per_limb`` is off), and all their joints sorted, shape (U,).

    The arrays are read-only (computed once per skeleton).
    """
    if params.per_limb:
        sk = character.skeleton
        limbs, groups, used = _contactors_of(sk.roles, sk.sides)
        return list(limbs), list(groups), used
    names = list(character.joint_names)
    joints = [np.array([j]) for j in range(character.n_joints)]
    used = np.unique(np.concatenate(joints)) if joints else np.zeros(0, dtype=np.int64)
    return names, joints, used
