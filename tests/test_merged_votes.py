"""Merged candidates: alike pictures shown once, a choice of one counts for each method it
stands for, and a test between two methods leaves out the trials where they shared one."""

from __future__ import annotations

import pandas as pd
import pytest
from app_helpers import fixture_study_doc, write_fixture_stimuli

from analysis.load import tidy_responses, view_choices
from analysis.votes import (
    chisquare_no_preference,
    ours_vs_baselines,
    pair_votes,
    vote_counts,
    vote_table,
)
from study_app.data.store import Store
from study_app.design.protocol import trial_plan
from study_app.design.stimuli import load_stimuli
from study_app.session import ParticipantSession

BACKGROUND = {"age_band": "18–24", "gender": "Man", "experience": "No experience"}
#: walk: ours and motion area alike (one picture); jump: three pictures; kick: all alike.
SHOWN = {
    "walk": [["ours", "motion_area"], ["viewpoint_entropy"]],
    "kick": [["ours", "viewpoint_entropy", "motion_area"]],
}
#: What each of six participants chooses per scene: the picture standing for this method.
PLAN = {
    "walk": ["ours", "ours", "motion_area", "ours", "viewpoint_entropy", "viewpoint_entropy"],
    "jump": ["ours", "ours", "ours", "viewpoint_entropy", "motion_area", "motion_area"],
}


@pytest.fixture(scope="module")
def stimuli(tmp_path_factory):
    d = tmp_path_factory.mktemp("merged") / "stimuli"
    write_fixture_stimuli(d, fixture_study_doc(("walk", "jump", "kick")), shown=SHOWN)
    return load_stimuli(d)


def _run_study(store, stimuli) -> list[dict]:
    """Six participants through the whole study, choosing as PLAN says."""
    for i in range(6):
        s = ParticipantSession.start(store, stimuli, seed=100 + i)
        s.submit_background(BACKGROUND)
        for t in s.plan:
            if t.task == "pose":
                s.submit_pose(t.index, 3, response_time_s=2.0)
            elif t.task == "view":
                want = PLAN[t.scene][i]
                pos = next(p for p, g in enumerate(t.shown_groups) if want in g)
                s.submit_view(t.index, pos, response_time_s=2.0)
            else:
                s.submit_attention(
                    t.index, s.stimuli.study.attention["answer"], response_time_s=2.0
                )
        s.finish()
    return store.export_rows()


def test_plan_shows_each_merged_picture_once_and_skips_an_all_alike_scene(stimuli):
    """Walk shows two pictures (ours standing for motion area too), kick none."""
    plan = trial_plan(stimuli.scene_ids, 5, shown=dict(stimuli.view_groups))
    views = {t.scene: t for t in plan if t.task == "view"}
    assert set(views) == {"walk", "jump"}
    assert sorted(views["walk"].shown_groups) == [("ours", "motion_area"), ("viewpoint_entropy",)]
    assert [g[0] for g in views["walk"].shown_groups] == list(views["walk"].shown_order)
    assert sorted(views["jump"].shown_order) == sorted(["ours", "viewpoint_entropy", "motion_area"])
    # Without merged pictures the plan is the one earlier versions made.
    assert trial_plan(["walk", "jump"], 5, shown={}) == trial_plan(["walk", "jump"], 5)


def test_merged_picture_is_placed_uniformly():
    """The merged picture lands at each of the two positions about equally often."""
    shown = {"walk": [["ours", "motion_area"], ["viewpoint_entropy"]]}
    first = [
        trial_plan(["walk"], seed, shown=shown)[1].shown_order[0] == "ours" for seed in range(2000)
    ]
    assert 0.46 < sum(first) / len(first) < 0.54


def test_simulated_study_votes_match_hand_counts(tmp_path, stimuli):
    """Vote table and pairwise tests of a simulated study with merged candidates equal the
    votes counted by hand."""
    with Store(f"sqlite:///{tmp_path / 'db.sqlite'}") as store:
        rows = _run_study(store, stimuli)
    views = [r for r in rows if r["task"] == "view"]
    assert len(views) == 12  # kick: no view task
    walk = [r for r in views if r["scene"] == "walk"]
    assert all(
        sorted(map(tuple, r["shown_groups"])) == [("ours", "motion_area"), ("viewpoint_entropy",)]
        for r in walk
    )
    choices = view_choices(tidy_responses(rows))
    counts = vote_counts(choices)
    # Hand counts. walk: 4 choices of the ours/motion-area picture, 2 of viewpoint
    # entropy's. jump: ours 3, viewpoint entropy 1, motion area 2.
    assert counts.loc["walk"].to_dict() == {"ours": 4, "viewpoint_entropy": 2, "motion_area": 4}
    assert counts.loc["jump"].to_dict() == {"ours": 3, "viewpoint_entropy": 1, "motion_area": 2}
    table = vote_table(counts).set_index(["scene", "method"])
    assert table.loc[("walk", "ours"), "n"] == 6 and table.loc[("jump", "ours"), "n"] == 6
    assert table.loc[("walk", "motion_area"), "share"] == pytest.approx(4 / 6)
    assert table.loc[("walk", "viewpoint_entropy"), "share"] == pytest.approx(2 / 6)
    pair = ours_vs_baselines(counts, choices=choices).set_index(["scene", "baseline"])
    # walk: ours and motion area shared a picture in every trial: no evidence either way.
    assert pair.loc[("walk", "motion_area"), ["reference_votes", "baseline_votes"]].tolist() == [
        0,
        0,
    ]
    assert pair.loc[("walk", "motion_area"), "p_value"] == 1.0
    # walk ours vs viewpoint entropy 4:2 -> exact two-sided p = 44/64; jump 3:1 -> 10/16,
    # jump ours vs motion area 3:2 -> 1.0 (P(X<=2 or X>=3) of Bin(5, 1/2)).
    assert pair.loc[("walk", "viewpoint_entropy"), "p_value"] == pytest.approx(44 / 64)
    assert pair.loc[("jump", "viewpoint_entropy"), "p_value"] == pytest.approx(10 / 16)
    assert pair.loc[("jump", "motion_area"), ["reference_votes", "baseline_votes"]].tolist() == [
        3,
        2,
    ]
    assert pair.loc[("jump", "motion_area"), "p_value"] == pytest.approx(1.0)
    # No preference: walk's two pictures chosen 4 and 2 times -> chi2 = (1 + 1) / 3 on
    # 1 degree of freedom; jump's three 3, 1, 2 -> chi2 = (1 + 1 + 0) / 2 on 2.
    chi = chisquare_no_preference(counts, choices=choices).set_index("scene")
    assert (chi.loc["walk", "n"], chi.loc["walk", "dof"]) == (6, 1)
    assert chi.loc["walk", "chi2"] == pytest.approx(2 / 3)
    assert (chi.loc["jump", "dof"], chi.loc["jump", "chi2"]) == (2, pytest.approx(1.0))


def test_pair_votes_leave_out_shared_trials_only():
    """A trial where ours and a baseline shared a picture gives neither a vote; a choice
    of the third picture in such a trial counts for nobody in that pair."""
    choices = pd.DataFrame(
        {
            "scene": ["s"] * 4,
            "chosen_method": ["ours", "viewpoint_entropy", "ours", "motion_area"],
            "shown_order": [("ours", "viewpoint_entropy")] * 2
            + [None, ("motion_area", "ours", "viewpoint_entropy")],
            "shown_groups": [
                [["ours", "motion_area"], ["viewpoint_entropy"]],
                [["ours", "motion_area"], ["viewpoint_entropy"]],
                None,  # a row of an earlier version: each method its own picture
                [["motion_area"], ["ours"], ["viewpoint_entropy"]],
            ],
        }
    )
    got = pair_votes(choices, "ours", ["viewpoint_entropy", "motion_area"]).set_index("baseline")
    assert got.loc[
        "viewpoint_entropy", ["reference_votes", "baseline_votes", "shared"]
    ].tolist() == [2, 1, 0]
    assert got.loc["motion_area", ["reference_votes", "baseline_votes", "shared"]].tolist() == [
        1,
        1,
        2,
    ]
