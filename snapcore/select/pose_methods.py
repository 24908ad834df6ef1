"""Named pose selectors behind one interface (``select_pose(scene, method=...)``).

Methods, each returning the same :class:`~snapcore.select.pose_selection.PoseSelection`:

- ``story`` (the default): story information, :mod:`snapcore.select.story`;
- ``paper``: the paper's pose entropy as METHOD §1 reads it, :mod:`snapcore.select.paper`,
  unchanged (what the paper's figures and study conditions use);
- baselines from :mod:`snapcore.select.pose_baselines`: ``stretch``, ``fastest``, ``middle``,
  ``random`` (seeded), ``salient``.

Every method reports its per-frame score as a :class:`~snapcore.select.pose_selection.PoseScores`:
named terms that add up to the total, in the method's own unit (the paper's normalised
entropy ``local`` + ``global``; the story's bits ``stance`` + ``novelty`` + ``events``;
the baselines' statures, statures per second or rank). Only ``paper`` also fills
``PoseSelection.entropy``.
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, fields
from typing import TYPE_CHECKING, Any

import numpy as np

from snapcore.errors import SelectionError, SnapshotError
from snapcore.select.contacts import (
    DEFAULT_TOLERANCES,
    GROUND,
    Event,
    Interactions,
    _event,  # Event without the frozen dataclass's setattrs
)
from snapcore.select.paper import REST_SPEED, select_pose_paper
from snapcore.select.pose_baselines import (
    middle_frames,
    random_frames,
    salient_frames,
    speed_score,
    stretch_score,
)
from snapcore.select.pose_selection import MIN_SEPARATION_S, PoseScores, PoseSelection, top_peaks
from snapcore.select.signals import SMOOTH_S, nonzero_rows
from snapcore.select.story import DEFAULT_STORY, StoryInformation, StoryParams, story_information

if TYPE_CHECKING:
    from snapcore.motion.scene import Character, Scene

    #: A pose method's runner: ``(scene, *, k, min_separation_s, story, seed)``.
    Runner = Callable[..., PoseSelection]

__all__ = [
    "POSE_METHODS",
    "DEFAULT_POSE_METHOD",
    "PAPER_OPTIONS",
    "PaperOptionError",
    "PoseParams",
    "select_pose",
    "run_pose_method",
    "story_interactions",
]

#: What ``select_pose`` and ``snapshot select`` use unless told otherwise.
DEFAULT_POSE_METHOD = "story"
#: Options that only the ``paper`` method takes.
PAPER_OPTIONS = (
    "w_local",
    "w_global",
    "events",
    "smooth_s",
    "rest_speed",
    "tolerances",
    "interactions",
)
#: Every selector, the default first, with the options it takes besides ``k`` and
#: ``min_separation_s``: the one table :meth:`PoseParams.kwargs` reads (the runners
#: that take them are in ``_RUNNERS``, below them).
METHOD_OPTIONS: dict[str, tuple[str, ...]] = {
    "story": ("story",),
    "paper": PAPER_OPTIONS,
    "stretch": (),
    "fastest": (),
    "middle": (),
    "random": ("seed",),
    "salient": (),
}
#: Every selector, the default first.
POSE_METHODS = tuple(METHOD_OPTIONS)


class PaperOptionError(SnapshotError):
    """Options of the ``paper`` pose method given with another method.

    Parameters
    ----------
    names : sequence of str
        The paper-only options given (:data:`PAPER_OPTIONS`), in the order given.
    method : str
        The method that was asked for instead.
    """

    def __init__(self, names: Iterable[str], method: str) -> None:
        self.names = tuple(names)
        self.method = method
        super().__init__(
            f"option(s) {', '.join(self.names)} apply to the 'paper' pose "
            f"method only, not {method!r}"
        )


def check_paper_options(method: str, given: Iterable[str]) -> None:
    """Refuse paper-only options for another pose method (the one place this rule lives).

    Parameters
    ----------
    method : str
        The pose method that runs (the default resolved).
    given : iterable of str
        The options the caller set: for :class:`PoseParams` those changed from their
        defaults, for :func:`select_pose` the keywords passed.

    Raises
    ------
    PaperOptionError
        When ``method`` is not ``paper`` and ``given`` names a paper-only option.
    """
    names = [name for name in given if name in PAPER_OPTIONS]
    if names and method != "paper":
        raise PaperOptionError(names, method)


@dataclass(frozen=True)
class PoseParams:
    """Options of the pose stage, as one value (:func:`select_pose`'s arguments).

    Attributes
    ----------
    pose_method : str or None
        The selector, one of :data:`POSE_METHODS` (None: :data:`DEFAULT_POSE_METHOD`).
    k : int
        How many distinct peaks to return (at least 1).
    min_separation_s : float
        Minimum time (s) between two returned poses.
    w_local, w_global : float
        ``paper`` only: weights of the normalised terms (eq. 9).
    events : {"transitions", "state"}
        ``paper`` only: what counts as an event in the global term.
    smooth_s : float
        ``paper`` only: Savitzky-Golay window (s) for the trajectories; 0 for none.
    rest_speed : float
        ``paper`` only: rest threshold (m/s) for a person of the reference stature.
    tolerances : ContactParams
        ``paper`` only: for :func:`snapcore.select.contacts.detect_interactions`.
    story : StoryParams or None
        ``story`` only (None: :data:`~snapcore.select.story.DEFAULT_STORY`).
    seed : int
        ``random`` only.

    Values are checked where they are used (:func:`select_pose`); a paper-only option
    changed from its default with another method fails here, at construction, with a
    :class:`PaperOptionError` (a ``ValueError``) naming the options.

    Examples
    --------
    >>> from snapcore import PoseParams
    >>> PoseParams(pose_method="paper", w_local=0.5).kwargs()["w_local"]
    0.5
    >>> PoseParams(w_local=0.5)  # the default method is 'story'
    Traceback (most recent call last):
    ...
    snapcore.select.pose_methods.PaperOptionError: option(s) w_local apply to the 'paper' pose method only, not 'story'
    """

    pose_method: str | None = None
    k: int = 3
    min_separation_s: float = MIN_SEPARATION_S
    w_local: float = 1.0
    w_global: float = 1.0
    events: str = "transitions"
    smooth_s: float = SMOOTH_S
    rest_speed: float = REST_SPEED
    tolerances: object = DEFAULT_TOLERANCES  # a ContactParams
    story: StoryParams | None = None
    seed: int = 0

    def __post_init__(self) -> None:
        # a field left at its default was not set: only changed ones count as given
        changed = [
            name
            for name in PAPER_OPTIONS
            if name in _PARAM_DEFAULTS and getattr(self, name) != _PARAM_DEFAULTS[name]
        ]
        check_paper_options(self.method, changed)

    @property
    def method(self) -> str:
        """The selector that runs (the default resolved)."""
        return DEFAULT_POSE_METHOD if self.pose_method is None else self.pose_method

    def kwargs(self) -> dict:
        """Keyword arguments of :func:`select_pose`: the method, ``k``,
        ``min_separation_s`` and the options of that method only."""
        out = {"method": self.method, "k": self.k, "min_separation_s": self.min_separation_s}
        for name in METHOD_OPTIONS.get(self.method, ()):  # an unknown method: select_pose says
            # ``interactions`` is computed data, no parameter; story=None is the default
            if name in _PARAM_DEFAULTS and not (name == "story" and self.story is None):
                out[name] = getattr(self, name)
        return out


#: Field defaults of PoseParams (what "changed" is measured against).
_PARAM_DEFAULTS = {f.name: f.default for f in fields(PoseParams)}


def story_interactions(scene: Scene, info: StoryInformation) -> Interactions:
    """The story selector's debounced limb contacts as an ``Interactions`` record.

    One :class:`~snapcore.select.contacts.Event` per contact of a contactor with the ground;
    its joint is the contactor's lowest-numbered joint of the foot or hand when there is
    one (named in the JSON), else its first joint.
    """
    events: list[Event] = []
    active = []
    for ci, (c, lc) in enumerate(zip(scene.characters, info.contacts)):
        # (F, J), as Interactions holds it: the contactor's joints are active where it is
        # in contact, all the contactors' columns in one assignment (one assignment per
        # interval took half of this function's time; a joint-major array and its
        # transposed copy, a third longer)
        act = np.zeros((scene.n_frames, c.n_joints), dtype=bool)
        state = np.asarray(lc.state, dtype=bool)
        if state.shape[0]:
            # every contactor's contacts at once, in contactor then frame order:
            # +1 where a contact starts, -1 on the frame after it ends
            edge = np.zeros((state.shape[0], state.shape[1] + 2), dtype=np.int8)
            edge[:, 1:-1] = state
            edge = np.diff(edge, axis=1)
            limb, start = nonzero_rows(edge == 1)
            end = nonzero_rows(edge == -1)[1] - 1
            rep = [int(_representative(c, js)) for js in lc.joints]
            for li, s, e in zip(limb.tolist(), start.tolist(), end.tolist()):
                events.append(_event(ci, rep[li], GROUND, s, e, None))
            joints = np.concatenate(lc.joints)
            if np.unique(joints).size == joints.size:  # disjoint contactors (limbs, joints)
                act[:, joints] = np.repeat(state, [js.size for js in lc.joints], axis=0).T
            else:
                for li, js in enumerate(lc.joints):
                    act[:, js] |= state[li][:, None]
        active.append(act)
    return Interactions(
        events, active, [GROUND], scene.n_frames, float(scene.fps), DEFAULT_TOLERANCES
    )


def _representative(character: Character, joints: Sequence[int] | np.ndarray) -> int:
    roles = character.skeleton.roles
    for want in ("foot", "hand", "head", "pelvis"):
        for j in joints:
            if roles[int(j)] == want:
                return int(j)
    return int(joints[0])


def _empty_interactions(scene: Scene) -> Interactions:
    return Interactions(
        [],
        [np.zeros((scene.n_frames, c.n_joints), dtype=bool) for c in scene.characters],
        [],
        scene.n_frames,
        float(scene.fps),
        DEFAULT_TOLERANCES,
    )


def _selection(
    scene: Scene,
    method: str,
    frames: Sequence[int] | np.ndarray,
    *,
    terms: dict[str, np.ndarray],
    unit: str,
    interactions: Interactions,
    k: int,
    sep_s: float,
    timings: dict[str, float],
) -> PoseSelection:
    total = np.sum(list(terms.values()), axis=0)
    scores = PoseScores(
        method=method,
        total=total,
        terms=terms,
        unit=unit,
        interactions=interactions,
        fps=float(scene.fps),
    )
    return PoseSelection(
        index=int(frames[0]),
        indices=[int(f) for f in frames[:k]],
        scores=scores,
        min_separation_s=float(sep_s),
        timings_s=timings,
        method=method,
    )


def select_pose(
    scene: Scene,
    *,
    method: str | None = None,
    k: int = 3,
    min_separation_s: float = MIN_SEPARATION_S,
    **options: Any,
) -> PoseSelection:
    """The most informative pose of ``scene`` by a named selector, and the top-k runners-up.

    Parameters
    ----------
    scene : Scene
    method : str, optional
        One of :data:`POSE_METHODS`; default :data:`DEFAULT_POSE_METHOD` (``"story"``,
        story information). ``"paper"`` is the paper's pose entropy
        (:func:`snapcore.select.paper.select_pose_paper`), unchanged.
    k : int
        How many distinct peaks to return (at least 1).
    min_separation_s : float
        Minimum time (s) between two returned poses.
    **options
        ``paper``: passed to :func:`~snapcore.select.paper.pose_entropy` (``w_local``,
        ``w_global``, ``events``, ``smooth_s``, ``rest_speed``, ``tolerances``,
        ``interactions``); ``story``: ``story`` (a
        :class:`~snapcore.select.story.StoryParams`); ``random``: ``seed``.

    Returns
    -------
    PoseSelection
        Frames are internal indices; report ``scene.source_frame(frame)``.

    Raises
    ------
    PaperOptionError
        A paper-only option (:data:`PAPER_OPTIONS`) passed with another method.
    SelectionError
        ``k`` or ``min_separation_s`` out of range, an unknown ``method``.

    Warns
    -----
    UserWarning
        When the method's score is constant (e.g. a static clip): the first frame is
        returned, a defined but arbitrary choice.

    Examples
    --------
    >>> from snapcore import select_pose
    >>> from snapcore.motion.synth import synth_scene
    >>> scene = synth_scene("kick")
    >>> sel = select_pose(scene, k=2, min_separation_s=0.3)
    >>> sel.method, len(sel.indices), sel.indices[0] == sel.index
    ('story', 2, True)
    >>> abs(sel.indices[1] - sel.indices[0]) >= 0.3 * scene.fps  # the runner-up is another moment
    True
    """
    if int(k) != k or k < 1:
        raise SelectionError(f"k must be a positive integer, got {k}")
    if not (np.isfinite(min_separation_s) and min_separation_s >= 0):
        raise SelectionError(
            f"min_separation_s must be a non-negative number, got {min_separation_s}"
        )
    method = DEFAULT_POSE_METHOD if method is None else method
    check_paper_options(method, options)
    return _runner(method, POSE_METHODS)(
        scene, k=int(k), min_separation_s=min_separation_s, **options
    )


def _runner(method: str, allowed: Sequence[str]) -> Runner:
    """The function that runs ``method`` (``_RUNNERS``), checked against ``allowed``."""
    if method not in allowed:
        raise SelectionError(f"method must be one of {', '.join(allowed)}, got {method!r}")
    return _RUNNERS[method]


def run_pose_method(
    scene: Scene,
    method: str,
    *,
    k: int = 3,
    min_separation_s: float = MIN_SEPARATION_S,
    story: StoryParams | None = None,
    seed: int = 0,
) -> PoseSelection:
    """Run the named selector (see the module docstring).

    Parameters
    ----------
    scene : Scene
    method : str
        One of :data:`POSE_METHODS` other than ``paper`` (which
        :func:`select_pose` runs through :func:`~snapcore.select.paper.select_pose_paper`).
    k : int
    min_separation_s : float
    story : StoryParams, optional
        For ``story``.
    seed : int
        For ``random``.

    Returns
    -------
    PoseSelection
    """
    others = tuple(m for m in POSE_METHODS if m != "paper")
    return _runner(method, others)(
        scene, k=int(k), min_separation_s=min_separation_s, story=story, seed=seed
    )


def _story(
    scene: Scene,
    *,
    k: int,
    min_separation_s: float,
    story: StoryParams | None = None,
    seed: int = 0,
) -> PoseSelection:
    t0 = time.perf_counter()
    params = DEFAULT_STORY if story is None else story
    info = story_information(scene, params)
    total = info.total
    frames = top_peaks(total, int(k), min_separation=_separation(scene, min_separation_s))
    if not float(total.max()) > float(total.min()):
        warnings.warn(
            "story information is the same at every frame (static clip?); choosing the first frame",
            stacklevel=3,
        )
    t1 = time.perf_counter()
    timings = {
        "story": info.timings_s["story"],
        "select": t1 - t0 - info.timings_s["story"],
        "total": t1 - t0,
    }
    return _selection(
        scene,
        "story",
        frames,
        terms=info.terms,
        unit="bits" if params.combine == "bits" else "normalised",
        interactions=story_interactions(scene, info),
        k=k,
        sep_s=min_separation_s,
        timings=timings,
    )


def _scored(method: str, score: Callable[[Scene], np.ndarray], term: str, unit: str) -> Runner:
    """A runner that takes the top peaks of a per-frame score (``stretch``, ``fastest``)."""

    def run(
        scene: Scene,
        *,
        k: int,
        min_separation_s: float,
        story: StoryParams | None = None,
        seed: int = 0,
    ) -> PoseSelection:
        t0 = time.perf_counter()
        raw = score(scene)
        if not float(raw.max()) > float(raw.min()):
            warnings.warn(
                f"the {method} score is the same at every frame (static clip?); "
                "choosing the first frame",
                stacklevel=3,
            )
        frames = top_peaks(raw, int(k), min_separation=_separation(scene, min_separation_s))
        return _ranked(scene, method, frames, {term: raw}, unit, k, min_separation_s, t0)

    return run


def _picked(method: str, pick: Callable[[Scene, int, int, int], Sequence[int]]) -> Runner:
    """A runner whose frames are picked, not scored (``middle``, ``random``, ``salient``):
    its score is the rank, 1 for the first pick down to 0.5 for the last."""

    def run(
        scene: Scene,
        *,
        k: int,
        min_separation_s: float,
        story: StoryParams | None = None,
        seed: int = 0,
    ) -> PoseSelection:
        t0 = time.perf_counter()
        frames = pick(scene, int(k), seed, _separation(scene, min_separation_s))
        score = np.zeros(scene.n_frames)
        score[frames] = np.linspace(1.0, 0.5, len(frames)) if len(frames) > 1 else 1.0
        return _ranked(scene, method, frames, {"rank": score}, "rank", k, min_separation_s, t0)

    return run


def _separation(scene: Scene, min_separation_s: float) -> int:
    """The minimum separation in frames."""
    return int(round(min_separation_s * float(scene.fps)))


def _ranked(
    scene: Scene,
    method: str,
    frames: Sequence[int] | np.ndarray,
    terms: dict[str, np.ndarray],
    unit: str,
    k: int,
    sep_s: float,
    t0: float,
) -> PoseSelection:
    t1 = time.perf_counter()
    return _selection(
        scene,
        method,
        frames,
        terms=terms,
        unit=unit,
        interactions=_empty_interactions(scene),
        k=k,
        sep_s=sep_s,
        timings={"select": t1 - t0, "total": t1 - t0},
    )


#: Method → the function that runs it (keywords: ``k``, ``min_separation_s`` and the
#: method's :data:`METHOD_OPTIONS`): the one dispatch.
_RUNNERS = {
    "story": _story,
    "paper": select_pose_paper,
    "stretch": _scored("stretch", stretch_score, "stretch", "statures"),
    "fastest": _scored("fastest", speed_score, "speed", "statures/s"),
    "middle": _picked("middle", lambda scene, k, seed, sep: middle_frames(scene.n_frames, k)),
    "random": _picked(
        "random",
        lambda scene, k, seed, sep: random_frames(scene.n_frames, k, seed=seed, min_separation=sep),
    ),
    "salient": _picked("salient", lambda scene, k, seed, sep: salient_frames(scene, k)),
}
