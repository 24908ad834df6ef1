"""How many participants does the view task need? (``snapshot power``)

Each participant casts one vote per scene among three methods. The claim "ours is
preferred to baseline B" is tested as in :func:`analysis.votes.ours_vs_baselines`: an
exact two-sided binomial test of ours' share among the votes for ours and B, and the
claim holds when the test rejects *and* ours got more votes. Its power is computed
exactly (no simulation), for true vote shares ``p_ours`` and ``p_baseline`` (the third
method gets the rest):

    power(N) = Σ_m Bin(m; N, p_o + p_b) · Σ_k Bin(k; m, p_o / (p_o + p_b)) · 1[reject(k, m), k > m/2]

where ``reject(k, m)`` is ``binomtest(k, m, 0.5).pvalue <= α / comparisons``. With
``comparisons`` tests Holm-adjusted together (6 scenes × 2 baselines = 12 in the
paper's design), Holm's first step is the Bonferroni level α/m: using it gives the power
of the *least lucky* ordering, a lower bound for Holm (set ``comparisons=1`` for a
single planned test).

The "no preference" chi-square test's power uses the noncentral chi-square
distribution, ``λ = N Σ_j (p_j − 1/k)² / (1/k)`` (Cohen 1988, §7), an approximation
that is good once every expected count is ≥ 5.

Exact binomial power is not monotone in N (a saw-tooth from the discrete rejection
region): :func:`sample_size` reports both the first N reaching the target and the N
from which every larger N (up to ``n_max``) reaches it.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike
from scipy import stats

from .votes import ALPHA

__all__ = [
    "TARGET_POWER",
    "N_MAX",
    "power_pairwise",
    "power_chisquare",
    "power_curve",
    "sample_size",
    "power_table",
    "shares_for_difference",
]

#: Conventional target power (Cohen 1988).
TARGET_POWER = 0.8
#: Largest number of participants searched.
N_MAX = 3000


def _check_shares(p_ours: float, p_baseline: float) -> None:
    if not (0 <= p_ours <= 1 and 0 <= p_baseline <= 1 and p_ours + p_baseline <= 1 + 1e-12):
        raise ValueError(
            f"shares: need 0 <= p_ours, p_baseline and p_ours + p_baseline <= 1, "
            f"got {p_ours}, {p_baseline}"
        )
    if p_ours + p_baseline == 0:
        raise ValueError("shares: p_ours + p_baseline must be > 0")


def _two_sided_p_half(k: np.ndarray, m: np.ndarray) -> np.ndarray:
    """``scipy.stats.binomtest(k, m, 0.5).pvalue`` for arrays of ``k`` and ``m``.

    The power search evaluates it for every pair size up to ``n_max`` (thousands of
    calls); :func:`scipy.stats.binomtest` is scalar (~5 ms a call), so the same value is
    computed in closed form: for the symmetric null, scipy's "minimum likelihood"
    two-sided p is twice the smaller tail, capped at 1,
    ``min(1, 2 min(P[X <= k], P[X >= k]))`` with ``X ~ Binomial(m, 1/2)``; ``m = 0``
    gives 1. The tests check it against binomtest for every ``k <= m <= 40``.
    """
    k = np.asarray(k, dtype=float)
    m = np.asarray(m, dtype=float)
    lower = stats.binom.cdf(k, m, 0.5)
    upper = stats.binom.sf(k - 1, m, 0.5)
    p = np.minimum(1.0, 2.0 * np.minimum(lower, upper))
    return np.where(m > 0, p, 1.0)


def _critical_k(m: np.ndarray, level: float) -> np.ndarray:
    """Smallest k > m/2 whose exact two-sided p (null 1/2) is <= level; m + 1 if none.

    For k > m/2 the p-value ``2 P[X >= k]`` falls as k grows, so the rejection region on
    ours' side is ``k >= c(m)``. ``binom.isf`` gives the candidate; the neighbours are
    checked with the exact p-value to guard against rounding.
    """
    m = np.asarray(m, dtype=int)
    c = np.floor(np.nan_to_num(stats.binom.isf(level / 2, m, 0.5), nan=0)).astype(int) + 1
    c = np.clip(c, m // 2 + 1, m + 1)
    for _ in range(3):  # settle rounding: step down while k-1 still rejects, up while k does not
        down = (c - 1 > m / 2) & (_two_sided_p_half(c - 1, m) <= level)
        c = np.where(down, c - 1, c)
        up = (c <= m) & (_two_sided_p_half(np.minimum(c, m), m) > level)
        c = np.where(up, c + 1, c)
    return c


def _conditional_power(m_max: int, q: float, level: float) -> np.ndarray:
    """S[m] = P(reject with ours ahead | m votes for the pair) = P[K >= c(m)], K ~ Bin(m, q)."""
    m = np.arange(m_max + 1)
    c = _critical_k(m, level)
    return np.where(c <= m, stats.binom.sf(c - 1, m, q), 0.0)


def power_pairwise(
    n: ArrayLike, p_ours: float, p_baseline: float, *, alpha: float = ALPHA, comparisons: int = 1
) -> np.ndarray:
    """Exact power of "ours preferred to the baseline" with ``n`` participants.

    Parameters
    ----------
    n : int or array_like of int
        Participants (votes per scene).
    p_ours, p_baseline : float
        True vote shares of ours and of the baseline (the third method gets the rest).
    alpha : float
        Family-wise level.
    comparisons : int
        Tests corrected together (level α / comparisons; see the module docstring).

    Returns
    -------
    ndarray of float
        Power for each ``n`` (same shape).
    """
    _check_shares(p_ours, p_baseline)
    if comparisons < 1:
        raise ValueError(f"comparisons: expected >= 1, got {comparisons}")
    n_arr = np.atleast_1d(np.asarray(n, dtype=int))
    if np.any(n_arr < 0):
        raise ValueError("n: expected numbers of participants >= 0")
    pair = p_ours + p_baseline
    s = _conditional_power(int(n_arr.max()), p_ours / pair, alpha / comparisons)
    # Bin(m; N, pair) for N = 0, 1, 2, ... by the recursion
    # pmf_{N+1}(m) = (1 - pair) pmf_N(m) + pair pmf_N(m - 1): one vector step per N,
    # exact up to rounding (each step is a convex combination).
    n_top = int(n_arr.max())
    pmf = np.zeros(n_top + 1)
    pmf[0] = 1.0
    by_n = np.empty(n_top + 1)
    by_n[0] = pmf @ s
    for k in range(1, n_top + 1):
        pmf[1 : k + 1] = (1 - pair) * pmf[1 : k + 1] + pair * pmf[:k]
        pmf[0] *= 1 - pair
        by_n[k] = pmf[: k + 1] @ s[: k + 1]
    return by_n[n_arr].reshape(np.shape(n))


def power_chisquare(n: ArrayLike, shares: ArrayLike, *, alpha: float = ALPHA) -> np.ndarray:
    """Approximate power of the chi-square "no preference" test (noncentral chi-square).

    Parameters
    ----------
    n : int or array_like of int
        Participants.
    shares : sequence of float, shape (k,)
        True vote shares (normalised to sum 1).
    """
    p = np.asarray(shares, dtype=float)
    p = p / p.sum()
    k = p.size
    effect = ((p - 1 / k) ** 2 / (1 / k)).sum()  # Cohen's w²
    n = np.asarray(n, dtype=float)
    crit = stats.chi2.ppf(1 - alpha, k - 1)
    return stats.ncx2.sf(crit, k - 1, n * effect) if effect > 0 else np.full(n.shape, alpha)


def power_curve(
    p_ours: float,
    p_baseline: float,
    *,
    n_values: ArrayLike | None = None,
    alpha: float = ALPHA,
    comparisons: int = 1,
) -> pd.DataFrame:
    """Power against the number of participants.

    Returns
    -------
    DataFrame
        ``n``, ``power_pairwise`` (exact binomial, level α/comparisons),
        ``power_chisquare`` (no-preference test, shares ``(p_ours, p_baseline, rest)``).
    """
    n_values = np.arange(10, 501, 5) if n_values is None else np.asarray(n_values, dtype=int)
    rest = max(0.0, 1 - p_ours - p_baseline)
    return pd.DataFrame(
        {
            "n": n_values,
            "power_pairwise": power_pairwise(
                n_values, p_ours, p_baseline, alpha=alpha, comparisons=comparisons
            ),
            "power_chisquare": power_chisquare(n_values, [p_ours, p_baseline, rest], alpha=alpha),
        }
    )


def sample_size(
    p_ours: float,
    p_baseline: float,
    *,
    alpha: float = ALPHA,
    power: float = TARGET_POWER,
    comparisons: int = 1,
    n_max: int = N_MAX,
) -> dict:
    """Participants needed for the pairwise claim to reach ``power``.

    Returns
    -------
    dict
        ``n_first`` (first N with power >= target; None if none up to ``n_max``),
        ``n_stable`` (smallest N from which every N up to ``n_max`` reaches it),
        ``power_at_n`` (power at ``n_stable``), and the inputs.
    """
    out = {
        "p_ours": p_ours,
        "p_baseline": p_baseline,
        "alpha": alpha,
        "power": power,
        "comparisons": comparisons,
        "n_first": None,
        "n_stable": None,
        "power_at_n": np.nan,
    }
    if p_ours <= p_baseline:
        return out  # the claim is false: no N makes it likely
    n = np.arange(1, n_max + 1)
    pw = power_pairwise(n, p_ours, p_baseline, alpha=alpha, comparisons=comparisons)
    ok = pw >= power
    if not ok.any():
        return out
    out["n_first"] = int(n[np.argmax(ok)])
    bad = np.flatnonzero(~ok)
    if bad.size == 0 or bad[-1] + 1 < n.size:
        first_stable = 0 if bad.size == 0 else bad[-1] + 1
        out["n_stable"] = int(n[first_stable])
        out["power_at_n"] = float(pw[first_stable])
    return out


def shares_for_difference(difference: float, *, third: float = 1 / 3) -> tuple[float, float]:
    """Shares ``(p_ours, p_baseline)`` differing by ``difference`` with the third method at ``third``."""
    pair = 1 - third
    if not 0 <= difference <= pair:
        raise ValueError(f"difference: expected 0..{pair:g}, got {difference}")
    return (pair + difference) / 2, (pair - difference) / 2


def power_table(
    differences: Sequence[float] = (0.05, 0.10, 0.15, 0.20, 0.25, 0.30, 0.40),
    *,
    third: float = 1 / 3,
    alpha: float = ALPHA,
    power: float = TARGET_POWER,
    comparisons: Sequence[int] = (1, 12),
    n_max: int = N_MAX,
) -> pd.DataFrame:
    """Participants needed per vote-share difference (ours − baseline).

    Parameters
    ----------
    differences : sequence of float
        ``p_ours − p_baseline``; the third method's share is ``third``.
    comparisons : sequence of int
        Family sizes to tabulate (1 = one planned test; 12 = the paper's 6 scenes × 2).

    Returns
    -------
    DataFrame
        ``difference``, ``p_ours``, ``p_baseline``, ``p_third``, ``comparisons``,
        ``level`` (α / comparisons), ``n_first``, ``n_stable``, ``power_at_n``, ``note``
        (``"more than <n_max>"`` when the target is not reached).
    """
    rows = []
    for d in differences:
        po, pb = shares_for_difference(d, third=third)
        for c in comparisons:
            r = sample_size(po, pb, alpha=alpha, power=power, comparisons=c, n_max=n_max)
            rows.append(
                {
                    "difference": d,
                    "p_ours": po,
                    "p_baseline": pb,
                    "p_third": third,
                    "comparisons": c,
                    "level": alpha / c,
                    "n_first": r["n_first"],
                    "n_stable": r["n_stable"],
                    "power_at_n": r["power_at_n"],
                    "note": "" if r["n_stable"] is not None else f"more than {n_max}",
                }
            )
    out = pd.DataFrame(rows)
    for column in ("n_first", "n_stable"):
        out[column] = out[column].astype("Int64")
    return out
