"""Strike events of the story selector: an end effector's speed peak, and its approach.

A strike -- a punch, a kick, a sword cut -- is a ballistic movement of a hand or a foot
that peaks in speed where it meets its target (the ball, the opponent, the cut), then
settles. Its key moment is the approach to that peak (the raise, the backswing, the
extension), not the settling: the pose held in a follow-through can depart from the
stance as much as the raise did, and the steps that bring the body after the strike
are contact events of their own, so pose and contact terms alone can put the pick
after the strike.

:func:`strike_surprisal` treats each speed peak of a wrist or an ankle above a
threshold as an event, as :func:`snapcore.select.story.event_surprisal` treats a
contact: an effector that strikes ``n`` times in ``F`` frames carries ``-log2(n / F)``
bits at each strike, credited to the frames *before* the peak (like a contact's onset:
the approach), over a half-Gaussian of ``support_s``. Gestures (a wave, a raised hand:
hands at 1-2 m/s) and steps at a walk stay below the threshold or, repeated, carry few
bits each.
"""

from __future__ import annotations

import math

import numpy as np

from snapcore.select.signals import find_peaks, half_gaussian

__all__ = [
    "strike_speeds",
    "strike_frames",
    "strike_surprisal",
    "strike_surprisal_of",
    "rows_and_speeds",
]


def strike_speeds(points: np.ndarray, *, fps: float, stature: float) -> np.ndarray:
    """Speeds of the end effectors in statures per second, shape (F, E).

    Parameters
    ----------
    points : ndarray of shape (F, K, 3)
        Key-joint positions (m, smoothed: :func:`snapcore.select.stance.key_positions`);
        with the six key joints (head, pelvis, wrists, ankles) the effectors are the
        wrists and ankles (E = 4), otherwise every key joint.
    fps : float
    stature : float
        Metres.
    """
    x = np.asarray(points, dtype=float)
    eff = x[:, 2:6] if x.shape[1] == 6 else x
    n_f = eff.shape[0]
    if n_f < 2:
        return np.zeros(eff.shape[:2])
    _, v = rows_and_speeds(eff)
    v *= fps / stature
    return v


def rows_and_speeds(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Trajectories ``x`` (F, N, 3) as contiguous (3, F, N) rows, and their speeds (F, N)
    in units per frame: ``np.gradient``'s central differences and one-sided ends, and
    the norm over the axes as two additions, written out (the same arithmetic as
    ``np.gradient`` and ``.sum(axis=2)``, at a third of the time: no checks, no short
    strided reductions). At least two frames."""
    xc = np.ascontiguousarray(np.moveaxis(x, -1, 0))
    g = np.empty_like(xc)
    np.subtract(xc[:, 2:], xc[:, :-2], out=g[:, 1:-1])
    g[:, 1:-1] *= 0.5
    np.subtract(xc[:, 1], xc[:, 0], out=g[:, 0])
    np.subtract(xc[:, -1], xc[:, -2], out=g[:, -1])
    g *= g
    v = g[0] + g[1]
    v += g[2]
    return xc, np.sqrt(v, out=v)


def strike_frames(speed: np.ndarray, *, threshold: float) -> list[np.ndarray]:
    """Frames of each effector's strikes: speed peaks of at least ``threshold``.

    Parameters
    ----------
    speed : ndarray of shape (F, E)
        Statures per second (:func:`strike_speeds`).
    threshold : float
        Statures per second; a peak must also stand out by half of it on both sides
        (its prominence), so that a fast movement that slows a little and speeds up
        again is one strike.

    Returns
    -------
    list of ndarray of int
        One array of frames per effector.
    """
    v = np.asarray(speed, dtype=float)
    # a peak is at least ``threshold`` high, so an effector that never reaches it has
    # none: one comparison for all of them instead of find_peaks' ~25 calls for each
    # (most effectors of most clips: 7 of the salsa pair's 8)
    hot: list[bool] = np.any(v >= threshold, axis=0).tolist()
    none = np.zeros(0, dtype=np.intp)
    return [
        find_peaks(v[:, e], height=threshold, prominence=0.5 * threshold) if hot[e] else none
        for e in range(v.shape[1])
    ]


def strike_surprisal(
    points: np.ndarray,
    *,
    fps: float,
    stature: float,
    threshold: float = 2.5,
    support_s: float = 0.2,
) -> np.ndarray:
    """Information (bits) of the strikes, credited to their approach, shape (F,).

    Parameters
    ----------
    points : ndarray of shape (F, K, 3)
        Key-joint positions (see :func:`strike_speeds`).
    fps : float
    stature : float
        Metres.
    threshold : float
        Least peak speed of a strike, statures per second (2.5: 4.4 m/s for a person
        of 1.75 m; punches, cuts and kicks reach 5-12 m/s, gesturing hands 1-2 m/s).
    support_s : float
        Width (s) of the half-Gaussian that credits the frames before each strike;
        0: the strike's frame only.

    Returns
    -------
    ndarray of shape (F,)
        ``sum_e sum_{t in strikes(e)} -log2(n_e / F) K(t - i)``, ``K`` a half-Gaussian
        of peak 1 over ``i <= t``.
    """
    v = strike_speeds(points, fps=fps, stature=stature)
    return strike_surprisal_of(v, fps=fps, threshold=threshold, support_s=support_s)


def strike_surprisal_of(
    speed: np.ndarray, *, fps: float, threshold: float = 2.5, support_s: float = 0.2
) -> np.ndarray:
    """:func:`strike_surprisal` from the effectors' :func:`strike_speeds` (F, E), (F,).

    For a caller that has the speeds already (the story computes every tracked
    joint's speed once, for the contacts and the strikes).
    """
    v = np.asarray(speed, dtype=float)
    n_f = v.shape[0]
    marks = np.zeros(n_f)
    if n_f < 3:
        return marks
    for frames in strike_frames(v, threshold=threshold):
        if frames.size:
            marks[frames] += -math.log2(frames.size / n_f)
    kernel, r = half_gaussian(support_s * fps, True)
    if r == 0:
        return marks
    # the mirrored kernel credits frames i <= t (see event_surprisal)
    return np.convolve(marks, kernel[::-1])[r : r + n_f]
