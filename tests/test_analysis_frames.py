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


def _scenes_study(picks, algorithms, *, fps=10.0, n_frames=100):
    """Participant i picks ``picks[k][i]`` in scene ``s<k>`` whose algorithm frame is
    ``algorithms[k]``."""
    return pd.concat(
        [
            _pose(f"s{k}", chosen, algorithm=a, fps=fps, n_frames=n_frames)
            for k, (chosen, a) in enumerate(zip(picks, algorithms, strict=True))
        ],
        ignore_index=True,
    )


def test_one_scene_alone_is_not_tested():
    """A scene whose participants chose in no other scene leaves nothing to permute: its
    rows are reported with a note, never tested, and stay out of Holm."""
    pose = _pose("a", [80] * 5, algorithm=80, fps=10.0, n_frames=100)
    t = fr.closeness_tests(pose, fr.scene_frames_from_rows(pose)).set_index("comparison")
    assert t["p_value"].isna().all() and not t["significant"].any()
    assert "another scene" in t.loc["agreement", "note"]
    assert t.loc["middle", "difference_s"] == pytest.approx(3.1)  # |80-49| - 0, in s


def test_baseline_on_the_algorithm_frame_is_not_tested():
    """A baseline on the algorithm's frame gives d = 0 for everyone: reported with a
    note, not tested, and left out of Holm (which then runs over the other tests)."""
    rng = np.random.default_rng(0)
    picks = [rng.integers(0, 100, size=30) for _ in range(3)]
    pose = _scenes_study(picks, (49, 20, 80))  # s0: the algorithm's frame is the middle
    t = fr.closeness_tests(pose, fr.scene_frames_from_rows(pose), n_permutations=199)
    same = t[(t["scene"] == "s0") & (t["comparison"] == "middle")].iloc[0]
    assert np.isnan(same["p_value"]) and np.isnan(same["p_holm"]) and not same["significant"]
    assert "same frame" in same["note"]
    tested = t[t["p_value"].notna()]
    assert len(tested) == 5
    from analysis.votes import holm_adjust

    np.testing.assert_allclose(tested["p_holm"], holm_adjust(tested["p_value"]))


def test_closer_than_needs_people_closer_on_average():
    """A pull toward the algorithm that leaves people nearer the baseline is no "closer
    than X" claim: significant needs Holm and a positive mean difference."""
    rng = np.random.default_rng(4)
    n = 200
    # Algorithm near the start of s0 and the end of s1; people pick the middle, moved
    # 15 frames toward the algorithm: still nearer the middle (49) than the algorithm.
    picks = [
        np.clip(49 - 15 + rng.integers(-2, 3, n), 0, 99),
        np.clip(49 + 15 + rng.integers(-2, 3, n), 0, 99),
    ]
    pose = _scenes_study(picks, (5, 95))
    t = fr.closeness_tests(pose, fr.scene_frames_from_rows(pose), n_permutations=999)
    mid = t[t["comparison"] == "middle"]
    assert (mid["p_holm"] < 0.05).all() and (mid["difference_s"] < 0).all()
    assert not mid["significant"].any()
    assert mid["note"].str.contains("nearer this baseline").all()


def test_simulated_300_near_the_algorithm_are_significant_after_holm():
    """300 participants whose picks cluster near the algorithm's (±0.3 s) in four scenes
    with the algorithm at different clip positions → every agreement and closer-than-
    middle test is significant after Holm, with the effect's interval above 0."""
    rng = np.random.default_rng(27)
    parts = []
    for k, (alg, n_frames) in enumerate(((30, 120), (110, 150), (60, 100), (10, 80))):
        chosen = np.clip(np.rint(alg + rng.normal(0, 0.3 * 30, size=300)), 0, n_frames - 1)
        parts.append(_pose(f"s{k}", chosen.astype(int), algorithm=alg, fps=30.0, n_frames=n_frames))
    pose = pd.concat(parts, ignore_index=True)
    t = fr.closeness_tests(pose, fr.scene_frames_from_rows(pose), n_permutations=999)
    assert len(t) == 8 and (t["n"] == 300).all()
    assert t["significant"].all(), t[["scene", "comparison", "p_value", "p_holm"]]
    assert (t["p_value"] == 1 / 1000).all()  # no permutation reached the data
    assert (t["beyond_habit_low"] > 0).all()


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
    t = fr.closeness_tests(pose, scenes).set_index("comparison")
    assert list(t.index) == ["agreement", "middle", "fastest", "stretch"]
    assert t.loc["fastest", "difference_s"] == pytest.approx(
        (np.abs([30, 29, 28]).mean() - np.abs([-1, 0, 1]).mean()) / 10
    )
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
