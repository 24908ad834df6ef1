"""The vectorised Luce bootstrap (analysis.luce) against choix's own fit, one resample at a
time, and the bootstraps' independence of row order and participant labels."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from analysis import luce
from analysis.frames import cluster_bootstrap_ci
from analysis.votes import LUCE_ALPHA, luce_strengths
from snapcore.select.view_methods import VIEW_METHODS

METHODS = list(VIEW_METHODS)


def mixed_choices(n: int, seed: int) -> pd.DataFrame:
    """Choices among all three methods and among two-method subsets (known strengths)."""
    rng = np.random.default_rng(seed)
    true = np.array([0.5, 0.2, 0.3])
    rows = []
    for i in range(n):
        k = 3 if rng.random() < 0.6 else 2
        shown = rng.choice(3, size=k, replace=False)
        p = true[shown] / true[shown].sum()
        rows.append(
            {
                "participant_id": f"p{i // 4}",
                "scene": f"s{i % 4}",
                "chosen_method": METHODS[shown[rng.choice(k, p=p)]],
                "shown_order": tuple(METHODS[j] for j in shown),
            }
        )
    return pd.DataFrame(rows)


def test_fit_counts_equals_choix_on_the_same_resamples():
    """Each resample fitted by fit_counts (all at once) == choix.ilsr_top1 on that
    resample's rows (the old loop), to 1e-6 in log-strength."""
    import choix

    df = mixed_choices(80, seed=1)
    winners = np.array([METHODS.index(m) for m in df["chosen_method"]])
    shown = np.array([[m in s for m in METHODS] for s in df["shown_order"]])
    tw, ts, of = luce.choice_types(winners, shown)
    rng = np.random.default_rng(7)
    picks = rng.integers(0, len(df), size=(25, len(df)))  # the old loop's row resamples
    counts = np.stack([np.bincount(of[p], minlength=len(tw)) for p in picks])
    got = luce.fit_counts(counts, tw, ts, alpha=LUCE_ALPHA)
    for b, p in enumerate(picks):
        data = [
            (int(winners[i]), tuple(int(j) for j in np.flatnonzero(shown[i]) if j != winners[i]))
            for i in p
        ]
        ref = choix.ilsr_top1(3, data, alpha=LUCE_ALPHA, max_iter=1000)
        np.testing.assert_allclose(got[b], ref - ref.mean(), atol=1e-6)


def test_choice_types_are_canonical():
    """The types and their counts do not depend on the order of the choices."""
    df = mixed_choices(60, seed=2)
    winners = np.array([METHODS.index(m) for m in df["chosen_method"]])
    shown = np.array([[m in s for m in METHODS] for s in df["shown_order"]])
    tw, ts, of = luce.choice_types(winners, shown)
    perm = np.random.default_rng(0).permutation(len(df))
    tw2, ts2, of2 = luce.choice_types(winners[perm], shown[perm])
    assert (tw == tw2).all() and (ts == ts2).all()
    assert (np.bincount(of) == np.bincount(of2)).all()
    assert all(ts[t, tw[t]] for t in range(len(tw)))  # the winner is among the shown


def old_loop_interval(df: pd.DataFrame, n_boot: int, seed: int) -> np.ndarray:
    """The bootstrap as it was: rows resampled one resample at a time, each fitted by choix."""
    import choix

    rng = np.random.default_rng(seed)
    data = [
        (METHODS.index(c), tuple(METHODS.index(m) for m in s if m != c))
        for c, s in zip(df["chosen_method"], df["shown_order"], strict=True)
    ]
    boots = []
    for _ in range(n_boot):
        pick = rng.integers(0, len(data), len(data))
        theta = choix.ilsr_top1(3, [data[i] for i in pick], alpha=LUCE_ALPHA, max_iter=1000)
        boots.append(np.exp(theta) / np.exp(theta).sum())
    return np.quantile(np.array(boots), [0.025, 0.975], axis=0)


@pytest.mark.slow
def test_intervals_statistically_equivalent_to_the_old_loop():
    """On one scene of 120 choices, the vectorised bootstrap's 95% interval ends agree with
    the old per-resample loop's within Monte-Carlo error (1000 resamples each: an end's
    Monte-Carlo standard error is about 0.004, so 0.02 is about 4 standard errors of the
    difference of two runs)."""
    df = mixed_choices(120, seed=3).assign(scene="s")
    new = luce_strengths(df, n_boot=1000, seed=11, pooled=False).set_index("method")
    old = old_loop_interval(df, 1000, seed=12)
    for j, m in enumerate(METHODS):
        assert abs(new.loc[m, "ci_low"] - old[0, j]) < 0.02, m
        assert abs(new.loc[m, "ci_high"] - old[1, j]) < 0.02, m


def test_strength_intervals_ignore_row_order_and_labels():
    """Shuffled rows and renamed participants: the same strengths and intervals, per scene
    and pooled (the pooled bootstrap draws participants)."""
    df = mixed_choices(200, seed=4)
    a = luce_strengths(df, n_boot=200, seed=5)
    ids = sorted(df["participant_id"].unique())
    rename = dict(zip(ids, np.random.default_rng(1).permutation(ids), strict=True))
    shuffled = df.assign(participant_id=df["participant_id"].map(rename)).sample(
        frac=1, random_state=2
    )
    b = luce_strengths(shuffled, n_boot=200, seed=5)
    pd.testing.assert_frame_equal(a, b, check_exact=False, rtol=1e-9)
    assert not a.equals(luce_strengths(df, n_boot=200, seed=6))  # the seed matters


def test_cluster_bootstrap_ignores_labels_and_matches_the_pooled_mean():
    """cluster_bootstrap_ci: the same interval whatever the clusters are called and in
    whatever order the values come; for the mean it equals the per-resample pooled mean
    over the same draws (computed the slow way)."""
    rng = np.random.default_rng(3)
    who = rng.integers(0, 30, 200)
    values = rng.normal(size=200) + who * 0.05
    lo, hi = cluster_bootstrap_ci(values, who, n_boot=300, seed=2)
    perm = rng.permutation(200)
    relabel = rng.permutation(30)
    assert cluster_bootstrap_ci(values[perm], relabel[who][perm], n_boot=300, seed=2) == (
        pytest.approx(lo, rel=1e-12),
        pytest.approx(hi, rel=1e-12),
    )
    slow = cluster_bootstrap_ci(values, who, n_boot=300, seed=2, stat=lambda v: np.mean(v))
    assert slow == (pytest.approx(lo, rel=1e-12), pytest.approx(hi, rel=1e-12))
    assert lo < values.mean() < hi
