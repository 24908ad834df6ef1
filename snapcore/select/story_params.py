"""The story selector's parameters: every choice of :mod:`snapcore.select.story`, with
the switches used for ablation (:class:`StoryParams`), and its defaults
(:data:`DEFAULT_STORY`, those of ``snapshot select``).
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace

import numpy as np

from snapcore.errors import SelectionError

__all__ = ["COMBINE_MODES", "EVENT_MODELS", "ZERO_BITS", "StoryParams", "DEFAULT_STORY"]

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

    Lengths are metres for a person of
    :data:`~snapcore.motion.anatomy.REFERENCE_STATURE_M` and scale with the
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
