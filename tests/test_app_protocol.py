"""Study protocol and participant session logic, without Streamlit (real SQLite store)."""

from __future__ import annotations

import itertools

import pytest
from app_helpers import fixture_study_doc, write_fixture_stimuli

from snapcore.errors import SchemaError
from snapcore.select.methods import VIEW_METHODS
from study_app.protocol import (
    AnswerError,
    StudyError,
    Trial,
    check_attention_answer,
    check_video_frame,
    check_view_choice,
    load_study,
    redirect_url,
    study_from_dict,
    trial_plan,
)
from study_app.session import (
    InvalidAnswer,
    ParticipantSession,
    Stage,
    UnknownParticipant,
    prolific_params,
)
from study_app.stimuli import load_stimuli
from study_app.store import Store

BACKGROUND = {"age_band": "18–24", "gender": "Man", "experience": "No experience"}


# ----------------------------------------------------------------------------- protocol


def test_trial_plan_is_a_seeded_permutation():
    """Same seed → same plan; each scene once per task; every view shows all methods once."""
    scenes = ["a", "b", "c", "d"]
    plan = trial_plan(scenes, 123)
    assert plan == trial_plan(scenes, 123)
    assert [t.index for t in plan] == list(range(9))
    assert [t.task for t in plan] == ["pose"] * 4 + ["view"] * 4 + ["attention"]
    assert sorted(t.scene for t in plan if t.task == "pose") == scenes
    assert sorted(t.scene for t in plan if t.task == "view") == scenes
    for t in plan[4:8]:
        assert sorted(t.shown_order) == sorted(VIEW_METHODS)
        assert t.stimulus_id == f"{t.scene}/view"


def test_trial_orders_vary_between_participants():
    """Over many seeds every pose order and every screen position of each method occurs."""
    scenes = ["a", "b", "c"]
    plans = [trial_plan(scenes, seed) for seed in range(300)]
    pose_orders = {tuple(t.scene for t in p[:3]) for p in plans}
    assert pose_orders == set(itertools.permutations(scenes))  # all 3! = 6 orders
    positions = {(m, t.shown_order.index(m)) for p in plans for t in p[3:6] for m in VIEW_METHODS}
    assert positions == {(m, k) for m in VIEW_METHODS for k in range(3)}


def test_check_video_frame_converts_and_refuses():
    """Video frame v maps through the manifest; out of range or non-integers are refused."""
    vmap = [10, 12, 15, 17]
    assert check_video_frame(2, vmap) == (2, 15)
    assert check_video_frame(3.0, vmap) == (3, 17)
    for bad in (4, -1, 1.5, "2", True, None, float("nan")):
        with pytest.raises(AnswerError):
            check_video_frame(bad, vmap)


def test_check_view_choice_refuses_forged_labels():
    """The label must be the method the seeded order put at the clicked position."""
    t = Trial(3, "view", "a", "a/view", ("motion_area", "ours", "viewpoint_entropy"))
    assert check_view_choice(t, 1, "ours") == (1, "ours")
    with pytest.raises(AnswerError, match="does not match"):
        check_view_choice(t, 0, "ours")
    with pytest.raises(AnswerError, match="unknown method"):
        check_view_choice(t, 0, "best")
    with pytest.raises(AnswerError, match="does not exist"):
        check_view_choice(t, 3, "ours")
    with pytest.raises(AnswerError, match="not a view task"):
        check_view_choice(Trial(0, "pose", "a", "a/pose"), 0, "ours")


def test_study_config_errors_name_the_field(tmp_path):
    """Bad configs: schema errors name file and field; semantic errors are StudyErrors."""
    p = tmp_path / "s.toml"
    p.write_text('[study]\nid = "x"\ntitle = "t"\nvideo_fps = -3\n[[scenes]]\nid = "a"\ndemo = "walk"\n')
    with pytest.raises(SchemaError, match=r"s\.toml: study\.video_fps"):
        load_study(p)
    doc = fixture_study_doc(("a", "a"))
    with pytest.raises(StudyError, match="duplicate scene id"):
        study_from_dict(doc)
    doc = fixture_study_doc(("a",))
    doc["attention"] = {"question": "q", "options": ["x", "y"], "answer": "z"}
    with pytest.raises(StudyError, match="attention.answer"):
        study_from_dict(doc)
    doc = fixture_study_doc(("a",))
    doc["scenes"][0]["frames"] = [50, 10]
    with pytest.raises(StudyError, match=r"scenes\[0\]\.frames"):
        study_from_dict(doc)
    doc = fixture_study_doc(("a",))
    doc["scenes"][0]["files"] = ["x.bvh"]  # two sources for one scene
    with pytest.raises(SchemaError, match="scenes"):
        study_from_dict(doc)


def test_shipped_configs_are_valid():
    """The demo and paper configs load, with the paper's six scenes."""
    from study_app.commands.serve import DEMO_CONFIG, PAPER_CONFIG

    demo = load_study(DEMO_CONFIG)
    assert demo.id == "demo" and all("demo" in s for s in demo.scenes)
    paper = load_study(PAPER_CONFIG)
    assert len(paper.scenes) == 6
    assert [s["fps"] for s in paper.scenes if "salsa" in s["id"]] == [60, 60]


def test_attention_and_redirect():
    study = study_from_dict(fixture_study_doc(
        redirect_url="https://app.prolific.com/submissions/complete?cc={code}"))
    assert check_attention_answer(study, "A purple circle") is True
    assert check_attention_answer(study, "A red square") is False
    with pytest.raises(AnswerError):
        check_attention_answer(study, "something else")
    assert redirect_url(study, "ABC") == "https://app.prolific.com/submissions/complete?cc=ABC"
    assert redirect_url(study_from_dict(fixture_study_doc()), "ABC") is None


def test_prolific_params_keep_only_plausible_ids():
    q = {"PROLIFIC_PID": "5f1e2d3c", "STUDY_ID": "<script>", "SESSION_ID": "s" * 65, "x": "1"}
    assert prolific_params(q) == {"PROLIFIC_PID": "5f1e2d3c"}


# ----------------------------------------------------------------------------- session


@pytest.fixture(scope="module")
def stimuli(tmp_path_factory):
    d = tmp_path_factory.mktemp("proto") / "stimuli"
    write_fixture_stimuli(d)
    return load_stimuli(d)


@pytest.fixture
def store(tmp_path):
    s = Store(f"sqlite:///{tmp_path / 'db.sqlite'}")
    yield s
    s.close()


def test_session_walks_the_stages_and_resumes(store, stimuli):
    """Stages follow the store; a resumed session sees the same plan and position."""
    s = ParticipantSession.start(store, stimuli, seed=7)
    assert s.stage is Stage.BACKGROUND and s.progress() == (1, 7)
    with pytest.raises(InvalidAnswer, match="yourself first"):
        s.submit_pose(0, 1, response_time_s=1)
    with pytest.raises(InvalidAnswer, match="gender"):
        s.submit_background({**BACKGROUND, "gender": "Robot"})
    assert s.submit_background(BACKGROUND)
    assert s.stage is Stage.POSE and s.current_trial.index == 0
    assert s.submit_pose(0, 5, response_time_s=1.5)
    again = ParticipantSession.resume(store, stimuli, s.participant_id)
    assert again.plan == s.plan == trial_plan(stimuli.scene_ids, 7)
    assert again.current_trial.index == 1 and again.progress() == (3, 7)
    assert not again.submit_pose(0, 9, response_time_s=1)  # re-sent: harmless
    assert store.responses(s.participant_id)[0]["chosen_video_frame"] == 5
    with pytest.raises(InvalidAnswer, match="in order"):
        again.submit_view(2, 0, again.plan[2].shown_order[0], response_time_s=1)
    again.submit_pose(1, 0, response_time_s=1)
    for t in again.plan[2:4]:
        again.submit_view(t.index, 2, t.shown_order[2], response_time_s=1)
    with pytest.raises(InvalidAnswer, match="still questions"):
        again.finish()
    again.submit_attention(4, "A red square", response_time_s=1)
    assert again.stage is Stage.DONE
    code = again.finish()
    assert again.finish() == code and store.get_participant(s.participant_id)["completed_at"]
    assert store.responses(s.participant_id)[-1]["correct"] is False


def test_resume_refuses_unknown_and_foreign_ids(store, stimuli, tmp_path):
    for bad in (None, "", "short", "A" * 22, "x" * 100, "a/b/c/d/e/f/g/h/i"):
        with pytest.raises(UnknownParticipant):
            ParticipantSession.resume(store, stimuli, bad)
    other = store.create_participant("other-study", stimuli.sha256, app_version="1", seed=1)
    with pytest.raises(UnknownParticipant, match="another study"):
        ParticipantSession.resume(store, stimuli, other)
    stale = store.create_participant(stimuli.study.id, "0" * 64, app_version="1", seed=1)
    with pytest.raises(UnknownParticipant, match="changed"):
        ParticipantSession.resume(store, stimuli, stale)


def test_invalid_answers_write_nothing(store, stimuli):
    """Out-of-range frames, forged labels and wrong trial kinds leave the store untouched."""
    s = ParticipantSession.start(store, stimuli)
    s.submit_background(BACKGROUND)
    for frame in (24, -1, 0.5, "3", None):
        with pytest.raises(InvalidAnswer):
            s.submit_pose(0, frame, response_time_s=1, events=[{"kind": "play"}])
    for index in (-1, 99, True, "0"):
        with pytest.raises(InvalidAnswer):
            s.submit_pose(index, 1, response_time_s=1)
    with pytest.raises(InvalidAnswer, match="does not belong"):
        s.submit_view(0, 0, "ours", response_time_s=1)
    with pytest.raises(InvalidAnswer, match="response time"):
        s.submit_pose(0, 1, response_time_s=float("nan"))
    assert store.answered_trials(s.participant_id) == set()
    assert store.events(s.participant_id) == []
    s.submit_pose(0, 1, response_time_s=1)
    s.submit_pose(1, 1, response_time_s=1)
    view = s.plan[2]
    wrong = next(m for m in VIEW_METHODS if m != view.shown_order[1])
    with pytest.raises(InvalidAnswer, match="does not match"):
        s.submit_view(2, 1, wrong, response_time_s=1)
    assert store.answered_trials(s.participant_id) == {0, 1}


def test_trial_clock_survives_a_reload(store, stimuli):
    """The moment a trial was first shown is stored: a resumed session (a reload, a
    second tab) gets the same moment, so the response time does not restart; the next
    trial gets its own; the browser cannot send that event itself."""
    import time

    s = ParticipantSession.start(store, stimuli)
    s.submit_background(BACKGROUND)
    before = time.time()
    t0 = s.trial_shown_at(0)
    assert before - 1.0 <= t0 <= time.time() + 1.0
    time.sleep(0.05)
    again = ParticipantSession.resume(store, stimuli, s.participant_id)
    assert again.trial_shown_at(0) == t0
    assert again.trial_shown_at(1) >= t0 + 0.04
    s.submit_pose(0, 5, response_time_s=1, events=[{"kind": "shown", "t": 0}])
    kinds = [(e["kind"], e["trial_index"]) for e in store.events(s.participant_id)]
    assert kinds == [("shown", 0), ("shown", 1)]


def test_picker_events_are_sanitised(store, stimuli):
    """Known event kinds are kept with numeric fields only; junk entries are dropped."""
    s = ParticipantSession.start(store, stimuli)
    s.submit_background(BACKGROUND)
    events = [{"kind": "play", "t": 0.25, "frame": 0}, {"kind": "hack", "t": 1},
              "nonsense", {"kind": "step", "by": 1, "frame": 5, "extra": "x" * 1000},
              {"kind": "seek", "frame": 999, "from": 3, "t": float("inf")}]
    s.submit_pose(0, 5, response_time_s=2, events=events)
    got = [(e["kind"], e["payload"]) for e in store.events(s.participant_id)]
    assert got == [("play", {"t": 0.25, "frame": 0}), ("step", {"frame": 5, "by": 1}),
                   ("seek", {"from": 3})]
