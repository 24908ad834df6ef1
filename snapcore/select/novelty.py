"""The pose's novelty in its clip, the story selector's second pose ingredient.

How unusual a frame's pose is among the clip's own poses: its Mahalanobis distance
under a Gaussian of all the clip's pose descriptors (:func:`pose_surprisal`; the
covariance shrunk towards a multiple of the identity and widened by the capture noise),
turned into the empirical tail surprisal ``-log2 (share of frames at least as far
out)`` (:func:`tail_surprisal`), at most ``log2 F`` bits. See
:mod:`snapcore.select.story`.
"""

from __future__ import annotations

import math

import numpy as np

from snapcore.select.story_params import ZERO_BITS

__all__ = ["pose_surprisal", "tail_surprisal"]


def pose_surprisal(
    features: np.ndarray, *, shrinkage: float = 0.5, noise: float = 0.02
) -> np.ndarray:
    """Self-information (bits) of each frame's pose under a Gaussian of the clip's poses.

    Parameters
    ----------
    features : ndarray of shape (F, D)
        Pose descriptors (:func:`snapcore.select.stance.pose_descriptor`).
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
    # the mean as ``x.mean(axis=0)`` computes it (the column sums over the count), without
    # its argument handling
    mu = np.add.reduce(x, axis=0)
    mu /= n_f
    z = x - mu
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
    if n == 0:
        return np.zeros(0)
    # a stable argsort (a merge sort of the few runs of a smooth curve) was faster than
    # ``np.sort`` and a binary search of every frame in the result
    order = np.argsort(v, kind="stable")
    srt = v[order]
    # the range from the sorted ends (NaN sorts last, so a NaN range stays NaN)
    if float(srt[-1] - srt[0]) <= ZERO_BITS:
        return np.zeros(n)
    if np.isnan(srt[-1]):
        at_least = n - np.searchsorted(srt, v, side="left")  # NaNs tie with each other
    else:
        # frames with value >= v_i: n minus the sorted place of the first of v_i's ties
        # (``np.searchsorted(srt, v, side="left")``), written back in frame order
        first = np.arange(n)
        tied = np.flatnonzero(srt[1:] == srt[:-1]) + 1
        if tied.size:
            first[tied] = 0
            first = np.maximum.accumulate(first)
        at_least = np.empty(n, dtype=np.intp)
        at_least[order] = n - first
    return -np.log2(at_least / n)
