"""The frame tests' within-participant permutation over scenes against brute force:
every permutation of a tiny study enumerated, statistics recomputed by plain loops."""

from __future__ import annotations

import functools
import itertools

import numpy as np
import pytest
from conftest import lazy_module

from study_app.design.scenes import StudyScene

pd = lazy_module("pandas")
sp = lazy_module("analysis.scene_permutation")
fr = lazy_module("analysis.frames")

# Three scenes of different lengths and offsets; the algorithm's frames sit at clip
# positions 0.1, 0.5 and 0.9 (the test needs the picks at different positions).
SCENES = {
    "a": StudyScene(scene="a", fps=10.0, n_frames=11, algorithm_frame=1, frame_offset=0),
    "b": StudyScene(scene="b", fps=20.0, n_frames=21, algorithm_frame=15, frame_offset=5),
    "c": StudyScene(
        scene="c",
        fps=10.0,
        n_frames=6,
        algorithm_frame=104,
        frame_offset=100,
        baseline_frames={"fastest": 101},
    ),
}
# participant → [(scene, chosen frame)]: p2 saw two scenes, p3 chose in "a" twice.
CHOICES = {
    "p0": [("a", 1), ("b", 15), ("c", 104)],
    "p1": [("a", 3), ("b", 9), ("c", 105)],
    "p2": [("a", 6), ("c", 100)],
    "p3": [("a", 2), ("a", 0), ("b", 23), ("c", 103)],
}
# The same without p3's second choice in "a": one choice per participant and scene,
# the case the app produces (tested by independent draws instead of a sort).
STUDIES = {
    "repeats": CHOICES,
    "once": {**CHOICES, "p3": [("a", 2), ("b", 23), ("c", 103)]},
}


def _pose(choices=CHOICES):
    rows = [
        {"participant_id": p, "scene": s, "chosen_frame": f}
        for p, cs in choices.items()
        for s, f in cs
    ]
    return pd.DataFrame(rows)


def _reference_statistic(choices, scene, baseline):
    """Plain-loop statistic: mean over the scene's participants of their mean
    (|c − baseline| − |c − algorithm|) / fps (agreement: −|c − algorithm| / fps)."""
    info = SCENES[scene]
    per_person = []
    for cs in choices.values():
        mine = [f for s, f in cs if s == scene]
        if not mine:
            continue
        vals = []
        for f in mine:
            v = -abs(f - info.algorithm_frame)
            if baseline is not None:
                v += abs(f - baseline)
            vals.append(v / info.fps)
        per_person.append(sum(vals) / len(vals))
    return sum(per_person) / len(per_person)


def _to_scene(frame, src, dst):
    """A frame of scene ``src`` at the same clip position in scene ``dst``."""
    s, d = SCENES[src], SCENES[dst]
    u = (frame - s.frame_offset) / (s.n_frames - 1)
    return d.frame_offset + u * (d.n_frames - 1)


def _all_arrangements(choices):
    """Every within-participant permutation of the chosen positions over the slots."""
    people = list(choices)
    options = [list(itertools.permutations(range(len(choices[p])))) for p in people]
    for combo in itertools.product(*options):
        out = {}
        for p, perm in zip(people, combo, strict=True):
            cs = choices[p]
            out[p] = [
                (cs[j][0], _to_scene(cs[perm[j]][1], cs[perm[j]][0], cs[j][0]))
                for j in range(len(cs))
            ]
        yield out


def _tests():
    return [("a", None), ("b", None), ("c", None), ("c", 101.0), ("a", 5.0)]


def _comparisons(info):
    out = [("agreement", None)]
    if info.scene == "c":
        out.append(("fastest", 101))
    if info.scene == "a":
        out.append(("middle", 5))
    return out


@functools.cache
def _exact(study="repeats"):
    """Observed statistics and every permuted one, enumerating all 3!·3!·2!·4! = 1728
    within-participant permutations (432 for the study without repeats)."""
    choices = STUDIES[study]
    obs = np.array([_reference_statistic(choices, s, b) for s, b in _tests()])
    null = np.array(
        [
            [_reference_statistic(arr, s, b) for s, b in _tests()]
            for arr in _all_arrangements(choices)
        ]
    )
    return obs, null


def _ordered(design):
    key = {(s, b): k for k, (s, b) in enumerate(_tests())}
    return [key[(t["scene"], t["baseline"])] for t in design]


def test_observed_statistics_equal_plain_loops():
    """The vectorised statistic of the data equals the plain-loop definition per test."""
    groups, u, design = sp.design_from_rows(_pose(), SCENES, _comparisons)
    got = sp.scene_statistics(u, design)
    want, _ = _exact()
    np.testing.assert_allclose(got, want[_ordered(design)], atol=1e-12)


@pytest.mark.parametrize("study", sorted(STUDIES))
def test_monte_carlo_pvalue_matches_exact_enumeration(study):
    """With B = 40 000 the Monte-Carlo p-value is the exact enumerated p-value (every
    within-participant permutation) within 4 Monte-Carlo standard errors, and the mean
    of the permuted statistics is the exact null mean; with and without a participant
    who chose twice in one scene (the sorted permutation and the independent draws)."""
    groups, u, design = sp.design_from_rows(_pose(STUDIES[study]), SCENES, _comparisons)
    assert any(t["repeated"] for t in design) == (study == "repeats")
    obs, null = _exact(study)
    idx = _ordered(design)
    exact_p = (null >= obs - 1e-9).mean(axis=0)[idx]
    b = 40_000
    _, null_mean, p = sp.permutation_pvalues(groups, u, design, n_permutations=b, seed=3)
    se = np.sqrt(exact_p * (1 - exact_p) / b) + 1 / b
    assert np.all(np.abs(p - exact_p) <= 4 * se + 1 / b), (p, exact_p)
    assert 0 < exact_p.min() < exact_p.max() < 1  # the tiny study is not degenerate
    tol = 4 * null.std(axis=0)[idx] / np.sqrt(b)
    assert np.all(np.abs(null_mean - null.mean(axis=0)[idx]) <= tol)


def test_habit_prediction_is_the_exact_null_mean():
    """The effect's 'habits predict' term is, per test, exactly the mean statistic over
    every permutation (enumerated), not an estimate."""
    groups, u, design = sp.design_from_rows(_pose(), SCENES, _comparisons)
    _, null = _exact()
    for t, k in zip(design, _ordered(design), strict=True):
        _, expected = sp.habit_effects(groups, u, t)
        # Participants' predictions averaged with the statistic's weights (one per
        # person): the mean over people of their own expected value.
        assert expected.mean() == pytest.approx(null[:, k].mean(), abs=1e-12), t["scene"]


def test_permuted_within_is_uniform_inside_groups():
    """Rows move only inside their group, each of a group's 3! orders about equally often
    (chi-square, 6000 draws), and groups are permuted independently."""
    from scipy import stats

    groups = np.array([0, 0, 0, 1, 1])
    perms = sp.permuted_within(groups, 6000, np.random.default_rng(0))
    assert set(map(tuple, np.sort(perms[:, :3], axis=1))) == {(0, 1, 2)}
    assert set(map(tuple, np.sort(perms[:, 3:], axis=1))) == {(3, 4)}
    codes = [tuple(r) for r in perms[:, :3]]
    counts = pd.Series(codes).value_counts()
    assert len(counts) == 6
    assert stats.chisquare(counts.to_numpy()).pvalue > 0.001
    joint = pd.crosstab(perms[:, 0], perms[:, 3])
    assert stats.chi2_contingency(joint).pvalue > 0.001
    with pytest.raises(ValueError, match="sorted"):
        sp.permuted_within(np.array([1, 0]), 2, np.random.default_rng(0))


def test_same_seed_same_pvalues_whatever_the_block():
    """p-values are a function of the seed: blocks of 512 draws give the same answer as
    one call for a B that is not a multiple of the block."""
    groups, u, design = sp.design_from_rows(_pose(), SCENES, _comparisons)
    a = sp.permutation_pvalues(groups, u, design, n_permutations=1300, seed=9)[2]
    b = sp.permutation_pvalues(groups, u, design, n_permutations=1300, seed=9)[2]
    np.testing.assert_array_equal(a, b)
    assert np.all(a >= 1 / 1301)


def _study(rng, n, positions, chooser, fastest=None):
    """n participants, one pick per scene of length 91 frames at 30 fps."""
    rows, scenes = [], {}
    for k, alg_u in enumerate(positions):
        sid = f"s{k}"
        base = {} if fastest is None else {"baseline_frames": {"fastest": round(fastest[k] * 90)}}
        scenes[sid] = StudyScene(
            scene=sid, fps=30.0, n_frames=91, algorithm_frame=round(alg_u * 90), **base
        )
    for i in range(n):
        for sid, sc in scenes.items():
            rows.append(
                {
                    "participant_id": f"p{i}",
                    "scene": sid,
                    "chosen_frame": int(np.clip(chooser(rng, sc), 0, 90)),
                    "algorithm_frame": sc.algorithm_frame,
                    "fps": 30.0,
                    "n_frames": 91,
                }
            )
    return pd.DataFrame(rows), scenes


def test_followers_are_found_and_direction_matters():
    """People within ±0.2 s of the algorithm's frame, frames at different clip positions:
    every agreement test significant. People who follow another frame (the fastest pose,
    elsewhere in every clip): no agreement, and "closer than fastest" p near 1."""
    rng = np.random.default_rng(1)
    follow = lambda r, sc: sc.algorithm_frame + r.normal(0, 6)  # noqa: E731
    pose, scenes = _study(rng, 40, (0.15, 0.5, 0.85, 0.3), follow)
    t = fr.closeness_tests(pose, scenes, n_boot=0, n_permutations=999)
    agree = t[t["comparison"] == "agreement"]
    assert agree["significant"].all() and (agree["p_value"] <= 0.002).all()
    assert (agree["beyond_habit_s"] > 0).all()
    other = lambda r, sc: sc.baseline_frames["fastest"] + r.normal(0, 6)  # noqa: E731
    fastest = (0.8, 0.2, 0.4, 0.9)
    pose, scenes = _study(rng, 40, (0.15, 0.5, 0.85, 0.3), other, fastest=fastest)
    t = fr.closeness_tests(pose, scenes, n_boot=0, n_permutations=999).set_index(
        ["scene", "comparison"]
    )
    assert not t["significant"].any()
    assert (t.xs("fastest", level="comparison")["p_value"] > 0.99).all()
    assert (t.xs("agreement", level="comparison")["beyond_habit_s"] < 0).all()


def test_a_habit_is_not_agreement():
    """People at the middle frame of every clip, or at the algorithm's frame when the
    algorithm picked the same clip position in every scene, have a position habit: the
    test finds nothing beyond it (no claim after Holm, effect near 0) — the documented
    limit of its power — while the same followers are found when the picks are spread."""
    rng = np.random.default_rng(2)
    middle = lambda r, sc: 45 + r.normal(0, 3)  # noqa: E731
    follow = lambda r, sc: sc.algorithm_frame + r.normal(0, 3)  # noqa: E731
    for positions, chooser in (((0.15, 0.3, 0.85, 0.7), middle), ((0.7,) * 4, follow)):
        pose, scenes = _study(rng, 60, positions, chooser)
        t = fr.closeness_tests(pose, scenes, n_boot=0, n_permutations=999)
        assert not t["significant"].any()
        agree = t[t["comparison"] == "agreement"]
        assert agree["beyond_habit_s"].abs().max() < 0.05
    pose, scenes = _study(rng, 60, (0.7, 0.2, 0.45, 0.9), follow)
    t = fr.closeness_tests(pose, scenes, n_boot=0, n_permutations=999)
    assert t.loc[t["comparison"] == "agreement", "significant"].all()
