"""Power of the view-task tests: the exact computation against brute force and simulation."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import lazy_module

# the modules under test, imported when a test first uses them (fast collection)
stats = lazy_module("scipy.stats")
pw = lazy_module("analysis.power")
sim = lazy_module("analysis.simulate")


def test_vectorised_p_equals_scipy_for_all_k():
    """The power search's vectorised p equals scipy.stats.binomtest(k, m, 0.5).pvalue for
    every k <= m <= 40 (m = 0 gives 1)."""
    for m in range(0, 41):
        for k in range(0, m + 1):
            ref = stats.binomtest(k, m, 0.5).pvalue if m else 1.0
            assert float(pw._two_sided_p_half(k, m)) == pytest.approx(ref, rel=1e-9, abs=1e-300)


def test_critical_region_matches_brute_force():
    """c(m) = smallest k > m/2 with scipy.stats.binomtest(k, m, 0.5).pvalue <= level."""
    for level in (0.05, 0.05 / 12):
        m = np.arange(0, 121)
        c = pw._critical_k(m, level)
        for mm in range(0, 121):
            ks = [
                k
                for k in range(mm + 1)
                if 2 * k > mm and stats.binomtest(k, mm, 0.5).pvalue <= level
            ]
            assert c[mm] == (ks[0] if ks else mm + 1), (level, mm)


def test_power_equals_brute_force_sum():
    """Exact power = Σ over the multinomial outcomes (ours, baseline, rest) of n = 30 voters."""
    po, pb = 0.5, 0.2
    n = 30
    total = 0.0
    for k in range(n + 1):
        for j in range(n - k + 1):
            prob = stats.multinomial.pmf([k, j, n - k - j], n, [po, pb, 1 - po - pb])
            # binomtest(k, k + j, 0.5): the paper-style test of ours vs the baseline
            if k > j and stats.binomtest(k, k + j, 0.5).pvalue <= 0.05:
                total += prob
    assert float(pw.power_pairwise(n, po, pb)) == pytest.approx(total, abs=1e-10)


def test_power_matches_simulation():
    """Exact power at n = 100 agrees with 20,000 simulated studies (numpy multinomial)."""
    c = sim.simulate_vote_counts(100, [0.45, 0.25, 0.30], n_sims=20000, seed=3)
    p = pw._two_sided_p_half(c[:, 0], c[:, 0] + c[:, 1])
    rate = np.mean((p <= 0.05) & (c[:, 0] > c[:, 1]))
    exact = float(pw.power_pairwise(100, 0.45, 0.25))
    assert rate == pytest.approx(exact, abs=4 * np.sqrt(exact * (1 - exact) / 20000))


def test_chisquare_power_approximation_close_to_simulation():
    """The noncentral chi-square power is within 0.03 of simulation at n = 150."""
    shares = [0.45, 0.25, 0.30]
    c = sim.simulate_vote_counts(150, shares, n_sims=5000, seed=4)
    e = 50.0
    chi2 = ((c - e) ** 2 / e).sum(axis=1)
    rate = np.mean(stats.chi2.sf(chi2, 2) < 0.05)
    assert float(pw.power_chisquare(150, shares)) == pytest.approx(rate, abs=0.03)


def test_sample_size_is_the_threshold():
    """n_stable reaches the target, n_stable − 1 does not; more comparisons need more people."""
    r = pw.sample_size(0.52, 0.40)
    n = r["n_stable"]
    assert pw.power_pairwise(n, 0.52, 0.40) >= 0.8 > pw.power_pairwise(n - 1, 0.52, 0.40)
    r12 = pw.sample_size(0.52, 0.40, comparisons=12)
    assert r12["n_stable"] > n
    assert pw.sample_size(0.3, 0.4)["n_stable"] is None  # the claim is false
    t = pw.power_table(differences=(0.2, 0.4))
    big = t[t["comparisons"] == 1].set_index("difference")["n_stable"]
    assert big.loc[0.4] < big.loc[0.2]  # larger differences need fewer people


def test_bad_shares_named():
    """Shares that cannot be probabilities raise ValueError naming them."""
    with pytest.raises(ValueError, match="shares"):
        pw.power_pairwise(10, 0.8, 0.5)
    with pytest.raises(ValueError, match="difference"):
        pw.shares_for_difference(0.9)
