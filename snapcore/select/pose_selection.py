"""What every pose selector returns: the selection, its per-frame score, and the peaks.

:class:`PoseSelection` (the chosen frame and the top-k runners-up) with its
:class:`PoseScores` (named terms that add up to the score) is the result of every method
of :mod:`snapcore.select.pose_methods`; :class:`PoseEntropy` is the extra record of the
paper's method (:mod:`snapcore.select.paper`). :func:`top_peaks` turns a score into the
top-k distinct frames for all of them.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from snapcore.select.contacts import Interactions

__all__ = [
    "MIN_SEPARATION_S",
    "PoseEntropy",
    "PoseScores",
    "PoseSelection",
    "score_caption",
    "top_peaks",
]

#: Default minimum separation (s) of the top-k poses.
MIN_SEPARATION_S = 0.3


def score_caption(method: str, unit: str, value: float) -> str:
    """A pose score as a short caption: ``"entropy 1.1"`` for the paper, ``"story 14.9
    bits"``, ``"stretch 0.236 statures"``... (also from a snapshot document's
    ``pose_scores``, where only the method, the unit and the numbers are left)."""
    if method == "paper":
        return f"entropy {float(value):.3g}"
    return f"{method} {float(value):.3g} {unit}"


# ----------------------------------------------------------------------- results


@dataclass
class PoseEntropy:
    """Pose entropy of every frame of a scene.

    Attributes
    ----------
    local : ndarray of shape (F,)
        Normalised local term ``H*_local`` in [0, 1].
    global_ : ndarray of shape (F,)
        Normalised global term ``H*_global`` in [0, 1] (``global`` is a keyword).
    total : ndarray of shape (F,)
        ``w_local * local + w_global * global_``.
    local_by_character, global_by_character : ndarray of shape (C, F)
        Per-character terms before summing and normalising (bits).
    information : ndarray of shape (C, F)
        Per-character ``p_i = sum_j l_j |dm_ji| kappa_ji`` before normalisation.
    interactions : Interactions
        The events behind the global term.
    weights : tuple of float
        ``(w_local, w_global)``.
    events_mode : str
    fps : float
    timings_s : dict
        Seconds spent in ``contacts``, ``local``, ``global``.
    """

    local: np.ndarray
    global_: np.ndarray
    total: np.ndarray
    local_by_character: np.ndarray
    global_by_character: np.ndarray
    information: np.ndarray
    interactions: Interactions
    weights: tuple[float, float]
    events_mode: str
    fps: float
    timings_s: dict = field(default_factory=dict)

    @property
    def n_frames(self) -> int:
        return int(self.total.shape[0])


@dataclass
class PoseScores:
    """The per-frame score of any pose selector, as named terms that add up to it.

    Attributes
    ----------
    method : str
        The selector (:data:`snapcore.select.pose_methods.POSE_METHODS`).
    total : ndarray of shape (F,)
        The score whose top peaks are the poses.
    terms : dict of str to ndarray of shape (F,)
        Named terms, weighted, with ``sum(terms.values()) == total`` (to rounding):
        ``paper``: ``local``, ``global`` (normalised entropy times its weight);
        ``story``: ``stance``, ``novelty``, ``events`` (bits); ``stretch``: ``stretch``
        (statures); ``fastest``: ``speed`` (statures per second); ``middle``,
        ``random``, ``salient``: ``rank`` (1 for the first pick down to 0.5 for the
        last, 0 elsewhere).
    unit : str
        What the numbers are: ``"normalised entropy"``, ``"bits"``, ``"statures"``,
        ``"statures/s"``, ``"rank"``.
    interactions : Interactions
        The events behind an event term (the paper's contacts, the story's debounced
        limb contacts; none for the baselines).
    fps : float
    """

    method: str
    total: np.ndarray
    terms: dict
    unit: str
    interactions: Interactions
    fps: float

    @property
    def n_frames(self) -> int:
        return int(self.total.shape[0])

    def caption(self, value: float) -> str:
        """A value of the total as a short caption (see :func:`score_caption`)."""
        return score_caption(self.method, self.unit, value)

    @property
    def label(self) -> str:
        """How plots name the total: ``"pose entropy"`` for the paper, else
        ``"<method> score (<unit>)"``."""
        return "pose entropy" if self.method == "paper" else f"{self.method} score ({self.unit})"


@dataclass
class PoseSelection:
    """The selected pose(s) of a scene.

    Frames here are *indices* into the scene's (cut) arrays; the file's own frame
    numbers are ``scene.source_frame(index)`` (``Snapshot.source_frame``).

    Attributes
    ----------
    index : int
        Index of the selected frame in the scene's arrays (the top peak of the score).
    indices : list of int
        Top-k distinct peaks, best first (``indices[0] == index``).
    scores : PoseScores
        The method's per-frame score and its terms.
    min_separation_s : float
    timings_s : dict
        Seconds: ``contacts``, ``local``, ``global``, ``select``, ``total``.
    method : str
        The selector that ran (:data:`snapcore.select.pose_methods.POSE_METHODS`).
    entropy : PoseEntropy or None
        The paper's pose entropy (``paper`` only).
    """

    index: int
    indices: list[int]
    scores: PoseScores
    min_separation_s: float
    timings_s: dict = field(default_factory=dict)
    method: str = "paper"
    entropy: PoseEntropy | None = None


def top_peaks(values: np.ndarray, k: int, *, min_separation: int) -> list[int]:
    """Indices of the ``k`` highest distinct peaks, best first.

    Candidates are local maxima (not lower than either neighbour); taken in
    decreasing value (ties: earlier first), each suppresses every candidate closer
    than ``min_separation`` frames. Fewer than ``k`` come back when the clip has
    fewer distinct peaks.
    """
    v = np.asarray(values, dtype=float)
    n = v.size
    if n == 0 or k < 1:
        return []
    left = np.r_[True, v[1:] >= v[:-1]]
    right = np.r_[v[:-1] >= v[1:], True]
    cand = np.flatnonzero(left & right)
    order = cand[np.lexsort((cand, -v[cand]))]
    chosen: list[int] = []
    sep = max(int(min_separation), 1)
    for i in order.tolist():
        if all(abs(i - c) >= sep for c in chosen):
            chosen.append(i)
            if len(chosen) == k:
                break
    return chosen
