"""Chosen frames against the algorithm (Fig. 13): distances, hit rates, baselines and the
paired tests over participants, on hand-made choices with known answers."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from conftest import lazy_module

from study_app.design.scenes import StudyScene

# the modules under test, imported when a test first uses them (fast collection)
pd = lazy_module("pandas")
fr = lazy_module("analysis.frames")


def _pose(scene, chosen, *, algorithm, fps, n_frames):
    return pd.DataFrame(
        {
            "scene": scene,
            "participant_id": [f"p{i}" for i in range(len(chosen))],
            "chosen_frame": chosen,
            "algorithm_frame": algorithm,
            "fps": fps,
            "n_frames": n_frames,
        }
    )


def test_hit_rates_known_answer():
    """fps 10, pick 50, choices 50/52/54/60/70 → |d| = 0, .2, .4, 1, 2 s."""
    pose = _pose("a", [50, 52, 54, 60, 70], algorithm=50, fps=10.0, n_frames=200)
    scenes = fr.scene_frames_from_rows(pose)
    hits = fr.hit_rates(pose, scenes).set_index("predictor")
    alg = hits.loc["algorithm"]
    assert alg["hit_0.25s"] == pytest.approx(2 / 5)
    assert alg["hit_0.5s"] == pytest.approx(3 / 5)
    assert alg["hit_1s"] == pytest.approx(4 / 5)
    assert alg["mean_abs_error_s"] == pytest.approx((0 + 0.2 + 0.4 + 1 + 2) / 5)
    assert alg["median_abs_error_s"] == pytest.approx(0.4)
    mid = hits.loc["middle"]  # frame 99: distances 4.9 .. 2.9 s, no hits
    assert mid["predicted_frame"] == 99
    assert mid["hit_1s"] == 0
    # Uniform frame: for a choice at 100 of 0..199, P(|f - 100| <= 5 frames) = 11/200 exactly.
    one = _pose("b", [100], algorithm=100, fps=10.0, n_frames=200)
    u = (
        fr.hit_rates(one, fr.scene_frames_from_rows(one))
        .set_index("predictor")
        .loc["uniform_random"]
    )
    assert u["hit_0.5s"] == pytest.approx(11 / 200)
    assert u["mean_abs_error_s"] == pytest.approx(np.abs(np.arange(200) - 100).mean() / 10)


def test_signed_errors_in_seconds():
    """error_s = (chosen − predicted) / fps, negative when people choose earlier."""
    pose = _pose("a", [40, 70], algorithm=50, fps=20.0, n_frames=100)
    d = fr.frame_distances(pose, fr.scene_frames_from_rows(pose))
    alg = d[d["predictor"] == "algorithm"]
    np.testing.assert_allclose(alg["error_s"], [-0.5, 1.0])
    np.testing.assert_allclose(alg["abs_error_s"], [0.5, 1.0])


def test_paired_test_exact_p():
    """Five people all at the algorithm's frame, baseline far: every paired difference is
    positive, the one most extreme of the 2^5 equally likely sign patterns under H0 →
    exact one-sided signed-rank p = 1/32, for the middle frame and for a uniform frame."""
    pose = _pose("a", [80] * 5, algorithm=80, fps=10.0, n_frames=100)
    tests = fr.closeness_tests(pose, fr.scene_frames_from_rows(pose)).set_index("baseline")
    mid = tests.loc["middle"]  # middle = 49, all d_i = 3.1 s > 0
    assert mid["method"].startswith("Wilcoxon signed-rank")
    assert mid["p_value"] == pytest.approx(1 / 32)
    assert mid["difference_s"] == pytest.approx(3.1)
    assert mid["rank_biserial"] == pytest.approx(1.0)
    # Uniform baseline: d_i = mean_f |80 - f| / 10 > 0 for all five → also 1/32 (the
    # old randomisation test could not go below 1/n_frames whatever the n).
    assert tests.loc["uniform_random", "p_value"] == pytest.approx(1 / 32)
    assert tests.loc["uniform_random", "difference_s"] == pytest.approx(
        np.abs(np.arange(100) - 80).mean() / 10
    )


def test_paired_test_direction_and_null():
    """People at the baseline's frame → the algorithm is not closer (p near 1); a
    baseline on the algorithm's frame is reported but not tested, and left out of Holm."""
    rng = np.random.default_rng(0)
    chosen = np.clip(np.rint(rng.normal(50, 3, size=60)), 0, 99).astype(int)
    pose = _pose("a", chosen, algorithm=85, fps=10.0, n_frames=100)  # people near middle (49)
    t = fr.closeness_tests(pose, fr.scene_frames_from_rows(pose), seed=1).set_index("baseline")
    assert t.loc["middle", "p_value"] > 0.99
    assert t.loc["middle", "difference_s"] < 0
    assert t.loc["middle", "difference_high"] < 0  # the whole interval says "farther"
    same = _pose("a", chosen, algorithm=49, fps=10.0, n_frames=100)
    t2 = fr.closeness_tests(same, fr.scene_frames_from_rows(same)).set_index("baseline")
    assert np.isnan(t2.loc["middle", "p_value"]) and np.isnan(t2.loc["middle", "p_holm"])
    assert not t2.loc["middle", "significant"]
    assert "not tested" in t2.loc["middle", "note"]
    # Holm ran over the one test left: its adjusted p is its own p.
    assert t2.loc["uniform_random", "p_holm"] == pytest.approx(t2.loc["uniform_random", "p_value"])


def test_paired_test_against_scipy_with_ties_and_zeros():
    """Known answer: the p-value is scipy's signed-rank test on the non-zero
    per-participant differences, and r the matched-pairs rank-biserial correlation."""
    from scipy import stats

    rng = np.random.default_rng(3)
    chosen = rng.integers(30, 70, size=45)
    pose = _pose("a", chosen, algorithm=45, fps=10.0, n_frames=100)
    t = fr.closeness_tests(pose, fr.scene_frames_from_rows(pose)).set_index("baseline")
    d = (np.abs(chosen - 49) - np.abs(chosen - 45)) / 10.0
    nz = d[d != 0]
    # scipy.stats.wilcoxon(nz, alternative="greater", zero_method="wilcox")
    expected = stats.wilcoxon(nz, alternative="greater", zero_method="wilcox").pvalue
    assert t.loc["middle", "p_value"] == pytest.approx(expected, rel=1e-12)
    ranks = stats.rankdata(np.abs(nz))
    r = (ranks[nz > 0].sum() - ranks[nz < 0].sum()) / ranks.sum()
    assert t.loc["middle", "rank_biserial"] == pytest.approx(r)
    # One participant per row: the bootstrap over participants is the ordinary one;
    # scipy.stats.bootstrap((d,), np.mean, method="percentile") agrees within MC error.
    ci = stats.bootstrap(
        (d,), np.mean, method="percentile", n_resamples=4000, random_state=np.random.default_rng(0)
    ).confidence_interval
    assert t.loc["middle", "difference_low"] == pytest.approx(ci.low, abs=0.02)
    assert t.loc["middle", "difference_high"] == pytest.approx(ci.high, abs=0.02)


def test_paired_test_small_samples_with_ties_equal_scipy():
    """Known answer for the small-sample branch: with ties and at most 13 non-zero
    differences scipy's signed-rank test enumerates all 2^n sign patterns; the p-value is
    that same exact one (sizes around the switch at 13, and a sample without ties)."""
    from scipy import stats

    rng = np.random.default_rng(11)
    samples = [rng.integers(-3, 6, size=n) / 10.0 for n in (1, 4, 8, 12, 15, 16)]
    samples.append(np.array([0.3, -0.1, 0.5, 0.2, 0.9, -0.4, 0.7]))  # no ties: exact
    for d in samples:  # ties and zeros, mostly positive
        nz = d[d != 0]
        want = stats.wilcoxon(nz, alternative="greater", zero_method="wilcox").pvalue
        assert fr.paired_closeness(d)["p_value"] == pytest.approx(want, rel=1e-12), d


def test_simulated_300_near_the_algorithm_are_significant_after_holm():
    """The simulated case of issue 27: 300 participants whose picks cluster near the
    algorithm's (±0.3 s) in four scenes → every test that can differ is significant after
    Holm, the uniform-frame ones included (the old randomisation test stopped at
    p ≥ 1/n_frames, ≈ 0.22 after Holm over 20 tests)."""
    rng = np.random.default_rng(27)
    parts = []
    for k, (alg, n_frames) in enumerate(((30, 120), (90, 150), (60, 100), (20, 80))):
        chosen = np.clip(np.rint(alg + rng.normal(0, 0.3 * 30, size=300)), 0, n_frames - 1)
        parts.append(_pose(f"s{k}", chosen.astype(int), algorithm=alg, fps=30.0, n_frames=n_frames))
    pose = pd.concat(parts, ignore_index=True)
    t = fr.closeness_tests(pose, fr.scene_frames_from_rows(pose))
    assert len(t) == 8 and (t["n"] == 300).all()
    assert t["significant"].all(), t[["scene", "baseline", "p_value", "p_holm"]]
    uni = t[t["baseline"] == "uniform_random"]
    assert (uni["p_holm"] < 1e-20).all()
    assert (t["difference_low"] > 0).all()


def test_permutation_false_positive_rate():
    """Choices symmetric between algorithm and baseline: one-sided tests reject ~5% or less."""
    rng = np.random.default_rng(7)
    rejections = 0
    for i in range(200):
        # Algorithm at 30, middle at 49: people uniformly spread over 20..59 are about
        # equally close to both in expectation (symmetric around 39.5) → H0 holds.
        chosen = rng.integers(20, 60, size=40)
        pose = _pose("a", chosen, algorithm=30, fps=10.0, n_frames=100)
        t = fr.closeness_tests(pose, fr.scene_frames_from_rows(pose), n_boot=0, seed=i)
        rejections += int(t.set_index("baseline").loc["middle", "p_value"] < 0.05)
    assert rejections / 200 <= 0.085


def test_pooled_rows_count_people_not_choices():
    """40 people, each either within ±0.5 s of every selector pick in 5 scenes or of none:
    200 choices but 40 independent people. The pooled interval must be about as wide as
    a Wilson interval for 40 (not 200), and the pooled row names no frame."""
    from analysis.votes import wilson_interval

    rng = np.random.default_rng(5)
    good = rng.random(40) < 0.5
    parts, scenes = [], {}
    for k in range(5):
        chosen = np.where(good, 50, 90)
        parts.append(_pose(f"s{k}", chosen, algorithm=50, fps=10.0, n_frames=100))
    pose = pd.concat(parts, ignore_index=True)
    for k in range(5):
        scenes[f"s{k}"] = StudyScene(
            scene=f"s{k}",
            fps=10.0,
            n_frames=100,
            algorithm_frame=50,
            selector_frames={"ours": [50]},
        )
    agree = fr.selector_agreement(pose, scenes)
    pooled = agree[agree["scene"] == "ALL"].iloc[0]
    assert pd.isna(pooled["frame"]) and pooled["n"] == 200 and pooled["participants"] == 40
    width = pooled["hit_high"] - pooled["hit_low"]
    lo40, hi40 = wilson_interval(int(good.sum()), 40)
    lo200, hi200 = wilson_interval(int(good.sum()) * 5, 200)
    assert width > 0.8 * (hi40 - lo40) > 1.5 * (hi200 - lo200)


def _fake_scene(positions, *, fps=10.0, offset=0):
    """A duck-typed snapcore Scene with one character (positions (F, J, 3))."""
    ch = SimpleNamespace(positions=np.asarray(positions, float))
    return SimpleNamespace(
        characters=[ch],
        fps=fps,
        n_frames=len(positions),
        frame_offset=offset,
        name="fake",
        source_frame=lambda i: i + offset,
    )


def test_motion_baselines_are_the_selectors_picks():
    """motion_baselines uses the fastest and stretch selectors' own scores: on a whole
    clip it returns their top picks (source numbering), inside a window an argmax
    within it; a window outside the clip is an error."""
    import warnings

    from snapcore.motion import synth
    from snapcore.select.pose_methods import select_pose

    scene = synth.synth_scene("jump", fps=30)
    scene.frame_offset = 7
    b = fr.motion_baselines(scene)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for name in ("fastest", "stretch"):
            assert b[name] == select_pose(scene, method=name).index + 7, name
    w = fr.motion_baselines(scene, window=(7, 17))
    assert all(7 <= f < 17 for f in w.values())
    with pytest.raises(ValueError, match="window"):
        fr.motion_baselines(scene, window=(1000, 2000))


def test_baselines_enter_hits_and_tests():
    """Motion baselines passed as extra scene info appear as predictors."""
    pose = _pose("a", [10, 11, 12], algorithm=11, fps=10.0, n_frames=60)
    scenes = fr.scene_frames_from_rows(
        pose, extra={"a": {"baseline_frames": {"fastest": 40, "stretch": 12}}}
    )
    hits = fr.hit_rates(pose, scenes)
    assert set(hits["predictor"]) == {"algorithm", "middle", "fastest", "stretch", "uniform_random"}
    t = fr.closeness_tests(pose, scenes).set_index("baseline")
    assert t.loc["fastest", "p_value"] == pytest.approx(1 / 8)  # n = 3, all d > 0: 1/2^3
    assert t.loc["stretch", "difference_s"] == pytest.approx(
        (np.abs([-2, -1, 0]).mean() - np.abs([-1, 0, 1]).mean()) / 10
    )


def test_histogram_counts_every_choice():
    """The Fig. 13 histogram covers the clip and counts every choice once."""
    pose = _pose("a", [0, 5, 99, 50, 50], algorithm=50, fps=30.0, n_frames=100)
    info = fr.scene_frames_from_rows(pose)["a"]
    counts, edges = fr.frame_histogram(pose, info, bins=10)
    assert counts.sum() == 5
    assert edges[0] == -0.5 and edges[-1] == 99.5


def test_disagreeing_rows_warn():
    """Rows with different algorithm frames for one scene: warn and use the most common."""
    pose = _pose("a", [1, 2, 3], algorithm=10, fps=10.0, n_frames=50)
    pose.loc[0, "algorithm_frame"] = 11
    with pytest.warns(UserWarning, match="disagree on algorithm_frame"):
        s = fr.scene_frames_from_rows(pose)
    assert s["a"].algorithm_frame == 10


def test_selector_agreement_and_timeline(tmp_path):
    """Every selector's top pick against people's choices: hit rate within ±0.5 s and
    median distance per scene and over all; the report section writes the table and the
    timeline figure."""
    from analysis.sections import _selector_section

    info = StudyScene(
        scene="kick",
        fps=10.0,
        n_frames=100,
        algorithm_frame=50,
        selector_frames={"story": [50, 20], "middle": [49], "paper": [90]},
    )
    pose = pd.DataFrame(
        {"scene": "kick", "participant_id": ["a", "b", "c", "d"], "chosen_frame": [48, 52, 56, 80]}
    )
    agree = fr.selector_agreement(pose, {"kick": info})
    row = agree[(agree["scene"] == "kick") & (agree["selector"] == "story")].iloc[0]
    # |48-50|, |52-50| <= 5 frames (0.5 s); 56 and 80 are not
    assert row["hit"] == 0.5 and row["median_abs_error_s"] == pytest.approx(0.4)
    paper = agree[(agree["scene"] == "ALL") & (agree["selector"] == "paper")].iloc[0]
    assert paper["hit"] == 0 and paper["n"] == 4
    (tmp_path / "tables").mkdir()
    (tmp_path / "figures").mkdir()
    sections = _selector_section(pose, tmp_path, scenes={"kick": info})
    # ties on hit rate go to the smaller median distance: story (0.4 s) over middle (0.5 s)
    assert sections and "best is story" in sections[0][1][1]
    assert (tmp_path / "figures" / "selector_timeline.png").exists()
    assert list((tmp_path / "tables").glob("selector_agreement.*"))
