"""Vote statistics (Table 2): every p-value against an independent SciPy call, the Holm
adjustment by hand, intervals against SciPy, Fleiss' kappa against a published example,
and the Luce model against its analytic answer and simulated known strengths."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import lazy_module

from snapcore.select.view_methods import VIEW_METHODS
from study_app.design.scenes import StudyScene

# the modules under test, imported when a test first uses them (fast collection)
pd = lazy_module("pandas")
stats = lazy_module("scipy.stats")
sim = lazy_module("analysis.simulate")
vt = lazy_module("analysis.votes")

# The paper's Table 2 as printed (../shared/METHOD.md §5 and the paper's text), typed here
# independently of analysis/data/paper_table2.csv: ours, viewpoint entropy, motion area.
PAPER = {
    "dancing": (52, 8, 40),
    "running": (35, 33, 32),
    "soccer_kicking": (64, 27, 9),
    "basketball_shooting": (47, 0, 53),
    "two_person_arguing": (54, 39, 7),
    "two_person_boxing": (55, 23, 22),
}


def test_paper_counts_are_the_published_table():
    """The packaged Table 2 equals the table as printed in the paper."""
    c = vt.paper_counts()
    assert list(c.index) == list(PAPER)
    assert list(c.columns) == ["ours", "viewpoint_entropy", "motion_area"]
    for scene, row in PAPER.items():
        assert tuple(c.loc[scene]) == row
    assert (c.sum(axis=1) == 100).all()  # 100 participants per animation
    t = vt.paper_table2()
    assert t["source"].str.contains("Table 2").all()


def test_chisquare_matches_scipy_on_paper_counts():
    """Each scene's chi-square p equals scipy.stats.chisquare(observed).pvalue."""
    chi = vt.chisquare_no_preference(vt.paper_counts()).set_index("scene")
    # scipy.stats.chisquare([52, 8, 40]), chisquare([35, 33, 32]), chisquare([64, 27, 9]),
    # chisquare([47, 0, 53]), chisquare([54, 39, 7]), chisquare([55, 23, 22])
    for scene, obs in PAPER.items():
        ref = stats.chisquare(list(obs))
        assert chi.loc[scene, "chi2"] == pytest.approx(ref.statistic, rel=1e-12)
        assert chi.loc[scene, "p_value"] == pytest.approx(ref.pvalue, rel=1e-9, abs=1e-300)
        assert chi.loc[scene, "dof"] == 2
    # Dancing by hand: E = 100/3; chi2 = ((52-E)^2 + (8-E)^2 + (40-E)^2) / E = 31.04.
    assert chi.loc["dancing", "chi2"] == pytest.approx(31.04, abs=1e-9)
    assert not chi.loc["running", "significant"]  # 35/33/32 is no preference at all
    assert chi.drop(index="running")["significant"].all()


def _holm_by_hand(p):
    """Holm step-down written out: sort, multiply by m, m-1, ..., running max, cap at 1."""
    order = sorted(range(len(p)), key=lambda i: p[i])
    adj = [0.0] * len(p)
    running = 0.0
    for rank, i in enumerate(order):
        running = max(running, min(1.0, (len(p) - rank) * p[i]))
        adj[i] = running
    return adj


def test_pairwise_matches_scipy_binomtest_and_holm_by_hand():
    """Ours vs each baseline: p = scipy.stats.binomtest(k, k + j, 0.5).pvalue; Holm over 12."""
    pair = vt.ours_vs_baselines(vt.paper_counts())
    raw = []
    for o, ve, ma in PAPER.values():
        # e.g. scipy.stats.binomtest(52, 52 + 8, 0.5) and binomtest(52, 52 + 40, 0.5)
        raw.append(stats.binomtest(o, o + ve, 0.5).pvalue)
        raw.append(stats.binomtest(o, o + ma, 0.5).pvalue)
    assert list(pair["scene"]) == [s for s in PAPER for _ in (0, 1)]
    assert list(pair["baseline"]) == ["viewpoint_entropy", "motion_area"] * 6
    np.testing.assert_allclose(pair["p_value"], raw, rtol=1e-9, atol=1e-300)
    np.testing.assert_allclose(pair["p_holm"], _holm_by_hand(raw), rtol=1e-9, atol=1e-300)
    # Clopper-Pearson interval of ours' share: binomtest(k, n).proportion_ci(method="exact")
    ci = stats.binomtest(52, 92, 0.5).proportion_ci(0.95, method="exact")
    row = pair[(pair["scene"] == "dancing") & (pair["baseline"] == "motion_area")].iloc[0]
    assert (row["ci_low"], row["ci_high"]) == pytest.approx((ci.low, ci.high))


def test_paper_claim_verdicts_are_stated_plainly():
    """Where 'ours is preferred' holds on the paper's counts, derived from SciPy p-values."""
    pair = vt.ours_vs_baselines(vt.paper_counts())
    raw = [stats.binomtest(o, o + b, 0.5).pvalue for o, ve, ma in PAPER.values() for b in (ve, ma)]
    adj = _holm_by_hand(raw)
    expected = {}
    for i, (scene, (o, ve, ma)) in enumerate(PAPER.items()):
        for j, (name, b) in enumerate((("viewpoint_entropy", ve), ("motion_area", ma))):
            expected[scene, name] = adj[2 * i + j] < 0.05 and o > b
    got = {(r.scene, r.baseline): r.verdict == "ours preferred" for r in pair.itertuples()}
    assert got == expected
    # Spelled out: ours beats viewpoint entropy in (a), (c), (d), (f); motion area in (c), (e), (f).
    assert {s for (s, b), v in got.items() if v and b == "viewpoint_entropy"} == {
        "dancing",
        "soccer_kicking",
        "basketball_shooting",
        "two_person_boxing",
    }
    assert {s for (s, b), v in got.items() if v and b == "motion_area"} == {
        "soccer_kicking",
        "two_person_arguing",
        "two_person_boxing",
    }
    assert not (
        pair["verdict"].str.contains("viewpoint_entropy preferred|motion_area preferred")
    ).any()
    lines = vt.claim_summary(pair)
    assert lines[0].startswith("ours vs viewpoint_entropy")
    assert (
        "significantly preferred in 4 of 6 scenes (dancing, soccer_kicking, "
        "basketball_shooting, two_person_boxing)" in lines[0]
    )
    assert "not significant in running, two_person_arguing" in lines[0]
    assert "3 of 6 scenes (soccer_kicking, two_person_arguing, two_person_boxing)" in lines[1]


def test_holm_adjust_known_values():
    """Holm on (0.01, 0.04, 0.03): sorted 0.01*3, 0.03*2, max(0.06, 0.04*1) = (0.03, 0.06, 0.06)."""
    np.testing.assert_allclose(vt.holm_adjust([0.01, 0.04, 0.03]), [0.03, 0.06, 0.06])
    np.testing.assert_allclose(vt.holm_adjust([0.5, 0.9]), [1.0, 1.0])


def test_wilson_matches_scipy():
    """Wilson intervals equal scipy's binomtest(k, n).proportion_ci(method='wilson')."""
    for k, n in [(0, 100), (8, 100), (52, 100), (100, 100), (3, 7)]:
        ci = stats.binomtest(k, n).proportion_ci(0.95, method="wilson")
        lo, hi = vt.wilson_interval(k, n)
        assert (float(lo), float(hi)) == pytest.approx((ci.low, ci.high), abs=1e-12)
    table = vt.vote_table(vt.paper_counts())
    assert table["share"].sum() == pytest.approx(6.0)
    assert ((table["ci_low"] <= table["share"]) & (table["share"] <= table["ci_high"])).all()


def test_wilson_known_answers():
    """Wilson 95% intervals of Newcombe (1998, Stat. Med. 17:857, Table I, method 3), also
    R: prop.test(81, 263, correct = FALSE)$conf.int -> 0.2553 0.3662."""
    for (k, n), want in {
        (81, 263): (0.2553, 0.3662),
        (15, 148): (0.0624, 0.1605),
        (0, 20): (0.0, 0.1611),
        (1, 29): (0.0061, 0.1718),
    }.items():
        lo, hi = vt.wilson_interval(k, n)
        assert (float(lo), float(hi)) == pytest.approx(want, abs=5e-5), (k, n)
    lo, hi = vt.wilson_interval([0, 3], [0, 7])  # vectorised; n = 0 gives (0, 1)
    assert lo[0] == 0 and hi[0] == 1 and 0 < lo[1] < 3 / 7 < hi[1] < 1


def test_pairwise_p_known_answer():
    """7 votes to 3: p = 2 P[X >= 7], X ~ Bin(10, 1/2) = 2 (120 + 45 + 10 + 1) / 1024 = 0.34375
    (R: binom.test(7, 10)$p.value); no votes for either gives p = 1."""
    counts = pd.DataFrame({"ours": [7, 0], "motion_area": [3, 0]}, index=["a", "b"])
    pair = vt.ours_vs_baselines(counts, family="scene")
    assert pair["p_value"].tolist() == pytest.approx([0.34375, 1.0], rel=1e-12)


def test_fleiss_kappa_published_example():
    """Fleiss (1971) example as given on Wikipedia (10 subjects, 14 raters, 5 classes): kappa 0.210."""
    table = pd.DataFrame(
        [
            [0, 0, 0, 0, 14],
            [0, 2, 6, 4, 2],
            [0, 0, 3, 5, 6],
            [0, 3, 9, 2, 0],
            [2, 2, 8, 1, 1],
            [7, 7, 0, 0, 0],
            [3, 2, 6, 3, 0],
            [2, 5, 3, 2, 2],
            [6, 5, 2, 1, 0],
            [0, 2, 2, 3, 7],
        ]
    )
    k = vt.fleiss_kappa(table).iloc[0]
    assert k["kappa"] == pytest.approx(0.20993, abs=5e-5)
    assert k["p_observed"] == pytest.approx(0.37802, abs=5e-5)  # P-bar
    assert k["p_chance"] == pytest.approx(0.2128, abs=5e-4)  # P-bar_e (Wikipedia: 0.213)
    # Everyone agreeing within each item (different items, different classes): kappa = 1.
    perfect = pd.DataFrame([[10, 0, 0], [0, 10, 0], [0, 0, 10]])
    assert vt.fleiss_kappa(perfect).iloc[0]["kappa"] == pytest.approx(1.0)


def test_luce_strengths_equal_shares_when_all_shown():
    """With all three views always shown, the Luce MLE is the vote share (analytic answer)."""
    counts = vt.paper_counts()
    st = vt.luce_strengths(vt.choices_from_counts(counts), n_boot=50, seed=1)
    for scene, row in PAPER.items():
        got = st[st["scene"] == scene].set_index("method")["strength"]
        np.testing.assert_allclose(got.loc[list(VIEW_METHODS)], np.array(row) / 100, atol=2e-3)
    pooled = st[st["scene"] == "all"].set_index("method")["strength"]
    total = np.sum(list(PAPER.values()), axis=0) / 600
    np.testing.assert_allclose(pooled.loc[list(VIEW_METHODS)], total, atol=2e-3)
    assert (
        (st["ci_low"] <= st["strength"] + 1e-9) & (st["strength"] <= st["ci_high"] + 1e-9)
    ).all()


def test_luce_uses_shown_subsets():
    """Choices from two-item subsets: the fit agrees with choix.opt_top1 (a different optimiser)."""
    import choix

    rng = np.random.default_rng(3)
    true = np.array([0.5, 0.2, 0.3])
    rows = []
    for _ in range(600):
        shown = tuple(rng.choice(3, size=2, replace=False))
        p = true[list(shown)] / true[list(shown)].sum()
        win = shown[rng.choice(2, p=p)]
        rows.append(
            {
                "scene": "s",
                "chosen_method": VIEW_METHODS[win],
                "shown_order": tuple(VIEW_METHODS[i] for i in shown),
            }
        )
    st = vt.luce_strengths(pd.DataFrame(rows), n_boot=0, pooled=False)
    data = [
        (
            VIEW_METHODS.index(r["chosen_method"]),
            tuple(VIEW_METHODS.index(m) for m in r["shown_order"] if m != r["chosen_method"]),
        )
        for r in rows
    ]
    theta = choix.opt_top1(3, data)
    ref = np.exp(theta) / np.exp(theta).sum()
    np.testing.assert_allclose(st["strength"].to_numpy(), ref, atol=2e-3)


def test_simulated_strengths_recovered_within_ci():
    """Simulated observers with known strengths: the fitted 95% CIs contain the truth.

    One arbitrary seed (1); any seed passes with probability ~0.9 (three 95% intervals),
    which the coverage test below checks over many seeds. (Seed 0 missed viewpoint
    entropy's 0.2 by 3e-6 once the simulation drew its screen orders from the app's
    trial plan.)
    """
    true = {"ours": 0.5, "viewpoint_entropy": 0.2, "motion_area": 0.3}
    design = [StudyScene("scene_a", 30.0, 120, 60, strengths=true)]
    people = sim.simulate_participants(design, 400, seed=1)
    rows = sim.simulated_rows(people)
    views = rows[rows["task"] == "view"]
    st = vt.luce_strengths(views, n_boot=300, seed=2, pooled=False).set_index("method")
    for m, s in true.items():
        assert st.loc[m, "ci_low"] <= s <= st.loc[m, "ci_high"], (m, st.loc[m].to_dict())
        assert abs(st.loc[m, "strength"] - s) < 0.06


@pytest.mark.slow
def test_strength_interval_coverage_over_seeds():
    """Across 30 simulated studies the 95% bootstrap intervals cover the truth >= 80% of the time."""
    true = np.array([0.45, 0.25, 0.30])
    counts = sim.simulate_vote_counts(200, true, n_sims=30, seed=5)
    covered = np.zeros(3)
    for i, c in enumerate(counts):
        df = vt.choices_from_counts(pd.DataFrame([c], columns=list(VIEW_METHODS), index=["s"]))
        st = vt.luce_strengths(df, n_boot=150, seed=i, pooled=False)
        covered += ((st["ci_low"] <= true) & (true <= st["ci_high"])).to_numpy()
    # Binomial(30, 0.95): P(X <= 23) < 0.01, so >= 24 is the honest bar.
    assert (covered >= 24).all(), covered


def test_chisquare_false_positive_rate_under_no_preference():
    """Equal strengths, 100 voters, 400 simulated studies: chi-square rejects 2.5-8% at 0.05."""
    counts = sim.simulate_vote_counts(100, [1, 1, 1], n_sims=400, seed=2024)
    table = pd.DataFrame(counts, columns=list(VIEW_METHODS), index=[f"s{i}" for i in range(400)])
    rate = vt.chisquare_no_preference(table)["significant"].mean()
    assert 0.025 <= rate <= 0.08, rate
    # The exact binomial test of ours vs one baseline is conservative: at most ~5%.
    pair = vt.ours_vs_baselines(table, baselines=["motion_area"], family="scene")
    assert pair["significant"].mean() <= 0.065


def test_bad_input_named():
    """Unknown methods and bad options raise ValueError naming the parameter."""
    with pytest.raises(ValueError, match="chosen_method"):
        vt.vote_counts(pd.DataFrame({"scene": ["a"], "chosen_method": ["best"]}))
    with pytest.raises(ValueError, match="family"):
        vt.ours_vs_baselines(vt.paper_counts(), family="each")
    with pytest.raises(ValueError, match="reference"):
        vt.ours_vs_baselines(vt.paper_counts(), reference="mine")


def test_zero_votes_get_a_real_interval():
    """A method nobody chose gets the exact upper end 1 - 0.025^(1/n), not [0, 0]."""
    counts = pd.DataFrame(
        {"ours": [10], "viewpoint_entropy": [0], "motion_area": [5]},
        index=pd.Index(["s"], name="scene"),
    )
    st = vt.luce_strengths(vt.choices_from_counts(counts), n_boot=50, seed=1)
    zero = st[st["method"] == "viewpoint_entropy"].iloc[0]
    # scipy: Clopper-Pearson interval of 0 of 15
    exact = stats.binomtest(0, 15).proportion_ci(confidence_level=0.95, method="exact")
    assert zero["ci_low"] == 0 and zero["ci_high"] == pytest.approx(exact.high)
    assert zero["ci_high"] > 0.2
    all_votes = vt.luce_strengths(
        vt.choices_from_counts(counts.assign(viewpoint_entropy=0, motion_area=0)), n_boot=20, seed=1
    )
    ours = all_votes[all_votes["method"] == "ours"].iloc[0]
    assert ours["ci_high"] == 1 and ours["ci_low"] == pytest.approx(
        stats.binomtest(10, 10).proportion_ci(method="exact").low
    )


def test_near_duplicates_merged_into_one_option():
    """Sensitivity analysis: a near-duplicate pair's votes are one option, tested against
    equal votes per distinct picture (scipy chisquare)."""
    counts = pd.DataFrame(
        {"ours": [10, 7], "viewpoint_entropy": [5, 6], "motion_area": [9, 8]},
        index=pd.Index(["dup", "fine"], name="scene"),
    )
    m = vt.merge_near_duplicates(counts, {"dup": [("ours", "motion_area")]})
    dup = m[m["scene"] == "dup"].set_index("option")
    assert dup["votes"].to_dict() == {"ours = motion_area": 19, "viewpoint_entropy": 5}
    assert (dup["options"] == 2).all() and (dup["n"] == 24).all()
    assert dup["chisquare_p"].iloc[0] == pytest.approx(stats.chisquare([19, 5]).pvalue)
    fine = m[m["scene"] == "fine"]
    assert list(fine["option"]) == [m.value for m in VIEW_METHODS] and (fine["options"] == 3).all()
    assert fine["chisquare_p"].iloc[0] == pytest.approx(stats.chisquare([7, 6, 8]).pvalue)


def test_pooled_strengths_resample_people_not_choices():
    """30 people, each choosing the same method in all 5 scenes: the pooled ("all")
    interval comes from a bootstrap over the 30 people, so it is about sqrt(5) times as
    wide as one that treats the 150 choices as independent (issue 27)."""
    import numpy as np
    import pandas as pd

    from analysis.votes import luce_strengths

    rng = np.random.default_rng(1)
    favourite = rng.choice(["ours", "motion_area", "viewpoint_entropy"], size=30, p=[0.5, 0.3, 0.2])
    choices = pd.DataFrame(
        [
            {"scene": f"s{k}", "participant_id": f"p{i}", "chosen_method": m}
            for k in range(5)
            for i, m in enumerate(favourite)
        ]
    )
    people = luce_strengths(choices, n_boot=300, seed=0)
    loose = luce_strengths(choices.drop(columns="participant_id"), n_boot=300, seed=0)

    def width(t):
        row = t[(t["scene"] == "all") & (t["method"] == "ours")].iloc[0]
        return row["ci_high"] - row["ci_low"]

    assert width(people) > 1.7 * width(loose)
