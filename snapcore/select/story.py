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

The ingredients live in their own modules, all re-exported here: the parameters in
:mod:`~snapcore.select.story_params`, the neutral stance and the descriptor in
:mod:`~snapcore.select.stance`, the novelty in :mod:`~snapcore.select.novelty`, the
contacts in :mod:`~snapcore.select.limb_contacts` (from a character's
:class:`~snapcore.select.tracks.JointTracks`, gathered once for every term), their
events in :mod:`~snapcore.select.contact_events`, the strikes in
:mod:`~snapcore.select.strikes`; this module combines them.

References: Assa, Caspi & Cohen-Or 2005 (*Action Synopsis*: poses that stand out of
the motion); Roberts, Mantiuk et al. 2019 (*Salient Poses*); Shannon's self-information.
"""

from __future__ import annotations

import math
import time
import warnings
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

from snapcore.motion.anatomy import stature_of
from snapcore.select.contact_events import (
    contact_state_entropy,
    event_marks,
    event_surprisal,
    spread_events,
)
from snapcore.select.limb_contacts import (
    LimbContacts,
    contactor_joints,
    debounce_scores,
    debounced_contacts,
    limb_groups,
    limb_scores,
)
from snapcore.select.novelty import pose_surprisal, tail_surprisal
from snapcore.select.signals import enforce_min_durations, half_gaussian, hysteresis, minmax
from snapcore.select.stance import (
    descriptor_of,
    descriptor_rows,
    key_joints,
    key_positions,
    neutral_stance,
    pose_descriptor,
    stance_departure,
    stance_departure_rows,
    trunk_departure,
    trunk_departure_rows,
)
from snapcore.select.story_params import (
    COMBINE_MODES,
    DEFAULT_STORY,
    EVENT_MODELS,
    ZERO_BITS,
    StoryParams,
)
from snapcore.select.strikes import strike_surprisal_of
from snapcore.select.tracks import JointTracks

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
    "EVENT_MODELS",
    "ZERO_BITS",
    "event_surprisal",
    "contact_state_entropy",
    "temporal_support",
    "story_information",
]


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


def temporal_support(values: np.ndarray, *, fps: float, support_s: float) -> np.ndarray:
    """Gaussian-weighted average over ``support_s`` seconds, zero beyond the clip, (F,).

    Near a clip edge part of the window lies outside the clip, where there is no
    information: a pose the clip shows only one side of gets less support.
    """
    v = np.asarray(values, dtype=float)
    sigma = support_s * fps
    if sigma <= 0 or v.size == 0:
        return v.copy()
    k = _support_kernel(sigma)
    r = k.size // 2
    return np.convolve(v, k)[r : r + v.size]


@lru_cache(maxsize=16)
def _support_kernel(sigma: float) -> np.ndarray:
    """:func:`temporal_support`'s normalised Gaussian of ``sigma`` frames over ``-r..r``,
    ``r = ceil(3 sigma)``: once per width (the story supports five terms with one),
    read-only."""
    r = int(math.ceil(3 * sigma))
    k = np.exp(-0.5 * (np.arange(-r, r + 1) / sigma) ** 2)
    k /= k.sum()
    k.flags.writeable = False
    return k


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
    pose_on = p.w_pose > 0 and (p.novelty or p.stance or p.trunk)
    strikes_on = p.w_event > 0 and p.strikes and p.event_model == "surprisal"
    # per character: contactors (names, joints) and weight-bearing scores (L, F) or None
    contactors, scores = [], []
    t_pose = t_event = 0.0
    for c in scene.characters:
        ta = time.perf_counter()
        names, joints, used = contactor_joints(c, p)
        stature = stature_of(c)
        tracks = rows = kj = None
        if c.n_frames >= 2 and (pose_on or strikes_on or used.size):
            # one gather of the key joints and the contacts' joints, component-major,
            # their speeds once, for every term: each step gathering its own joints
            # read the (F, J, 3) positions again
            kj = key_joints(c) if pose_on or strikes_on else np.zeros(0, dtype=np.int64)
            tracks = JointTracks.of(c, np.union1d(kj, used), fps=fps, smooth_s=p.smooth_s)
            rows = tracks.rows.take(tracks.columns(kj), axis=1)  # (3, K, F)
        elif pose_on:
            x = key_positions(c, fps=fps, smooth_s=p.smooth_s)
            rows = np.ascontiguousarray(x.transpose(2, 1, 0))
        if pose_on and rows is not None:
            # one row per frame, C order, as descriptor_of returns it: the novelty's
            # tail surprisal ranks frames, and frames whose surprisal ties up to
            # rounding would trade places if its sums ran in another order
            feats_rows = descriptor_rows(
                rows, ground=scene.ground, stature=stature, horizontal=p.horizontal
            )  # (D, F)
            feats = np.ascontiguousarray(feats_rows.T)
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
                        neutral[None], ground=0.0, stature=stature, horizontal=p.horizontal
                    )[0]
                    stance_bits += stance_departure_rows(feats_rows, nd, spread=p.stance_spread)
                if p.trunk:
                    trunk_bits += trunk_departure_rows(
                        rows, neutral, stature=stature, spread=p.trunk_spread
                    )
        tb = time.perf_counter()
        contactors.append((names, joints))
        scores.append(
            limb_scores(tracks, c, ground=scene.ground, fps=fps, params=p)
            if tracks is not None and joints
            else None
        )
        if strikes_on and tracks is not None and kj is not None:
            # strike_speeds' effectors (wrists and ankles of the six key joints), a row each
            eff = kj[2:6] if kj.size == 6 else kj
            speed = tracks.speed.take(tracks.columns(eff), axis=0)
            speed *= fps / stature
            # the marks (support 0), spread after the loop
            strike_bits += strike_surprisal_of(
                speed.T, fps=fps, threshold=p.strike_speed, support_s=0
            )
        t_pose += tb - ta
        t_event += time.perf_counter() - tb
    tb = time.perf_counter()
    contacts, state = _debounced(contactors, scores, n_f=n_f, fps=fps, params=p)
    if p.w_event > 0 and p.event_model == "surprisal":
        # all characters' contactors at once: the marks add over them (linear)
        onset_marks, release_marks = event_marks(state)
        sup = {"fps": fps, "support_s": p.event_support_s}
        event_bits = spread_events(onset_marks, release_marks, sided=p.sided_support, **sup)
        kernel, r = half_gaussian(p.event_support_s * fps, True)  # strikes: before them
        strike_bits = np.convolve(strike_bits, kernel[::-1])[r : r + n_f] if r else strike_bits
    elif p.w_event > 0:
        for lc in contacts:
            event_bits += contact_state_entropy(lc.state)
    t_event += time.perf_counter() - tb
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


def _debounced(
    contactors: list, scores: list, *, n_f: int, fps: float, params: StoryParams
) -> tuple[list[LimbContacts], np.ndarray]:
    """Every character's :class:`LimbContacts` from its contactors and
    :func:`~snapcore.select.limb_contacts.limb_scores` (None: never in contact), the
    scores debounced in one call (rows are independent); and all their states stacked,
    (sum L, F), of which the characters' states are views."""
    n_rows = [
        len(names) if sc is None else sc.shape[0] for (names, _), sc in zip(contactors, scores)
    ]
    have = [sc for sc in scores if sc is not None]
    if len(have) == len(scores) and have:
        state = debounce_scores(np.concatenate(have), fps=fps, params=params)
    else:
        state = np.zeros((sum(n_rows), n_f), dtype=bool)
        row = 0
        for rows, sc in zip(n_rows, scores):
            if sc is not None:
                state[row : row + rows] = debounce_scores(sc, fps=fps, params=params)
            row += rows
    out, row = [], 0
    for (names, joints), rows in zip(contactors, n_rows):
        out.append(LimbContacts(names, [j.copy() for j in joints], state[row : row + rows]))
        row += rows
    return out, state
