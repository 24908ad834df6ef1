"""The one simulated participant (analysis.simulate.SimulatedParticipant).

``snapshot simulate`` and the load test's two drivers answer through it: its choices
follow the observer model the simulate module documents, and each user really draws
from it.
"""

from __future__ import annotations

import random

import numpy as np
import pytest

from analysis import simulate as sim
from analysis.simulate import ObserverModel, SimulatedParticipant
from study_app.ops.loadtest.participant import (
    LOADTEST_OBSERVER,
    Behaviour,
    ParticipantResult,
    _Run,
    answering_person,
)


def person(seed: int = 0, **model) -> SimulatedParticipant:
    return SimulatedParticipant(np.random.default_rng(seed), ObserverModel(**model))


def test_view_choices_follow_luce_strengths():
    """P(m) = s_m / sum of the shown strengths (Luce's choice axiom): 8:1:1 gives 0.8."""
    p = person(1)
    shown = ("motion_area", "ours", "viewpoint_entropy")
    strengths = {"ours": 8.0, "motion_area": 1.0, "viewpoint_entropy": 1.0}
    picks = [p.view_position(shown, strengths) for _ in range(4000)]
    assert abs(np.mean(np.array(picks) == 1) - 0.8) < 0.03


def test_a_fixed_screen_position_wins_and_unknown_methods_are_equal():
    assert {person(view_position=2).view_position(3) for _ in range(20)} == {2}
    counts = np.bincount([person(s).view_position(3) for s in range(600)], minlength=3)
    assert counts.min() > 150  # about 200 each


def test_pose_frames_stay_in_the_clip_and_aim_at_the_pick():
    uniform = person(2, pose_model="uniform")
    frames = [uniform.pose_frame(10, 19) for _ in range(500)]
    assert min(frames) == 10 and max(frames) == 19
    # no lapse, no spread, only the pick: always the pick
    exact = person(3, lapse=0.0, spread_s=0.0, algorithm_weight=1.0)
    assert {exact.pose_frame(0, 99, aim=42, salient=(7,)) for _ in range(50)} == {42}
    with pytest.raises(ValueError, match="aims at a frame"):
        person(4, lapse=0.0).pose_frame(0, 99)


def test_attention_answers_follow_the_pass_rate():
    options = ["a", "b", "c"]
    assert {person(5, attention_pass=1.0).attention_answer(options, "b") for _ in range(30)} == {
        "b"
    }
    never = person(6, attention_pass=0.0)
    assert "b" not in {never.attention_answer(options, "b") for _ in range(30)}
    # the answer unknown (the load test): any option
    unknown = person(7)
    assert {unknown.attention_answer(options) for _ in range(60)} == set(options)


def test_snapshot_simulate_answers_through_the_model(monkeypatch):
    """Replacing the model's view choice changes what simulate_participants stores."""
    monkeypatch.setattr(SimulatedParticipant, "view_position", lambda self, shown, s=None: 0)
    people = sim.simulate_participants(sim.paper_design(), 3, seed=0)
    views = [r for p in people for r in p["rows"] if r["task"] == "view"]
    assert views and all(r["chosen_position"] == 0 for r in views)
    assert all(r["chosen_method"] == r["shown_order"][0] for r in views)


def test_load_test_drivers_answer_through_the_model():
    """The protocol driver's participant carries the model, seeded from its own seed
    (the browser driver makes its person with the same answering_person)."""
    run = _Run(None, ParticipantResult(0, "p"), random.Random("7:0"), 1.0, Behaviour(), None)
    assert isinstance(run.person, SimulatedParticipant)
    assert run.person.model == LOADTEST_OBSERVER
    a, b = answering_person(random.Random("7:0")), answering_person(random.Random("7:0"))
    assert [a.pose_frame(0, 999) for _ in range(5)] == [b.pose_frame(0, 999) for _ in range(5)]
