"""The Luce choice model fitted to many data sets at once: the bootstrap of the strengths.

A view trial shows a set of methods and the participant picks one: a *top-1 choice*.
Under Luce's choice axiom ``P(m | shown S) = s_m / Σ_{j∈S} s_j``. Two choices with the
same winner and the same shown set are interchangeable in the likelihood, so a data set
is just a count per *choice type* (winner, shown set); a bootstrap resample is a new
vector of counts. :func:`fit_counts` runs iterative Luce spectral ranking (I-LSR,
Maystre & Grossglauser 2015, the algorithm of ``choix.ilsr_top1``, with the same ridge
``alpha`` and stopping rule) on a whole matrix of count vectors at once, so a thousand
resamples cost a few array operations per iteration instead of a thousand Python fits.

Because a data set is reduced to counts per type in a canonical (sorted) order, the
resamples and so the intervals do not depend on the order of the rows or on how
participants are labelled: a store and its shuffled, pseudonymised export give the same
numbers (:func:`choice_types`, :func:`cluster_counts`).
"""

from __future__ import annotations

import numpy as np

__all__ = ["choice_types", "cluster_counts", "fit_counts", "shares"]


def choice_types(winners, shown) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Choices → their distinct types, in canonical order, and each choice's type.

    Parameters
    ----------
    winners : array-like of int, shape (n,)
        The chosen method's index.
    shown : array-like of bool, shape (n, M)
        The methods on screen for each choice (the winner among them).

    Returns
    -------
    type_winner : ndarray of int, shape (T,)
    type_shown : ndarray of bool, shape (T, M)
    of_choice : ndarray of int, shape (n,)
        The type of each choice (index into the first two).
    """
    winners = np.asarray(winners, dtype=int)
    shown = np.asarray(shown, dtype=bool)
    m = shown.shape[1]
    # one integer per type: the shown set as bits, then the winner
    code = (shown.astype(np.int64) << np.arange(m)).sum(axis=1) * m + winners
    uniq, of_choice = np.unique(code, return_inverse=True)
    masks, type_winner = np.divmod(uniq, m)
    type_shown = ((masks[:, None] >> np.arange(m)) & 1).astype(bool)
    return type_winner, type_shown, of_choice.reshape(-1)


def cluster_counts(of_choice, cluster, n_types: int) -> tuple[np.ndarray, np.ndarray]:
    """Clusters (participants) → their distinct count vectors over choice types.

    Two participants with the same choices are interchangeable; listing the distinct
    count vectors in sorted order (with how many participants have each) makes a
    bootstrap over participants independent of their labels and row order.

    Returns
    -------
    vectors : ndarray of int, shape (U, T)
        Distinct per-participant counts, lexicographically sorted.
    multiplicity : ndarray of int, shape (U,)
        Participants with each vector.
    """
    _, who = np.unique(np.asarray(cluster), return_inverse=True)
    per = np.zeros((who.max() + 1, n_types), dtype=np.int64)
    np.add.at(per, (who.reshape(-1), np.asarray(of_choice)), 1)
    vectors, multiplicity = np.unique(per, axis=0, return_counts=True)
    return vectors, multiplicity


def _stationary(generator: np.ndarray) -> np.ndarray:
    """Stationary distributions of continuous-time chains, shape (B, M, M) → (B, M),
    each scaled to sum to M (as ``choix.utils.statdist``)."""
    m = generator.shape[-1]
    a = np.swapaxes(generator, -1, -2).copy()
    a[:, -1, :] = 1.0  # replace one balance equation by the normalisation
    rhs = np.zeros((generator.shape[0], m, 1))
    rhs[:, -1, 0] = m
    return np.linalg.solve(a, rhs)[..., 0]


def fit_counts(
    counts,
    type_winner,
    type_shown,
    *,
    alpha: float,
    initial=None,
    max_iter: int = 1000,
    tol: float = 1e-8,
) -> np.ndarray:
    """Maximum-likelihood (ridge ``alpha``) Luce log-strengths of many data sets at once.

    Parameters
    ----------
    counts : array-like, shape (B, T)
        Choices of each type (:func:`choice_types`) in each of B data sets.
    type_winner : array-like of int, shape (T,)
    type_shown : array-like of bool, shape (T, M)
    alpha : float
        The ridge of ``choix.ilsr_top1`` (every transition rate starts at ``alpha``).
    initial : array-like, shape (M,) or (B, M), optional
        Starting log-strengths (e.g. the full data's estimate: fewer iterations, same
        optimum).
    max_iter, tol
        As ``choix.ilsr_top1``: stop when every data set's iterate moved by at most
        ``tol * M`` in L1 norm.

    Returns
    -------
    ndarray, shape (B, M)
        Centred log-strengths (mean 0), as ``choix.ilsr_top1`` returns per data set.

    Raises
    ------
    RuntimeError
        No convergence within ``max_iter`` iterations.
    """
    counts = np.asarray(counts, dtype=float)
    shown = np.asarray(type_shown, dtype=float)
    n_sets, m = counts.shape[0], shown.shape[1]
    win = np.eye(m)[np.asarray(type_winner, dtype=int)]  # (T, M)
    losers = shown * (1.0 - win)
    theta = np.zeros((n_sets, m)) if initial is None else np.broadcast_to(initial, (n_sets, m))
    previous = None
    for _ in range(max_iter):
        w = np.exp(theta - theta.mean(axis=1, keepdims=True))
        w *= m / w.sum(axis=1, keepdims=True)
        rate = counts / (w @ shown.T)  # (B, T): each choice's 1 / Σ_shown w
        # chain[b, loser, winner] += rate of every choice that loser lost to winner
        chain = alpha + np.einsum("bt,tl,tw->blw", rate, losers, win)
        idx = np.arange(m)
        chain[:, idx, idx] = 0.0
        chain[:, idx, idx] = -chain.sum(axis=2)
        log_pi = np.log(_stationary(chain))
        theta = log_pi - log_pi.mean(axis=1, keepdims=True)
        if previous is not None and np.all(np.abs(theta - previous).sum(axis=1) <= tol * m):
            return theta
        previous = theta
    raise RuntimeError(f"the Luce fit did not converge after {max_iter} iterations")


def shares(theta: np.ndarray) -> np.ndarray:
    """Log-strengths (..., M) → probabilities of being chosen when all are shown."""
    w = np.exp(theta - theta.max(axis=-1, keepdims=True))
    return w / w.sum(axis=-1, keepdims=True)
