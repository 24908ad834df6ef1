"""Study protocol and participant session logic, without Streamlit (real SQLite store)."""

from __future__ import annotations

import itertools

import pytest
from app_helpers import fixture_study_doc, write_fixture_stimuli

from snapcore.errors import SchemaError
from snapcore.select.view_methods import VIEW_METHODS
from study_app.data.store import Store
from study_app.design.protocol import (
    AnswerError,
    StudyError,
    Trial,
    check_attention_answer,
    check_video_frame,
    check_view_choice,
    consent_text,
    estimated_minutes,
    load_study,
    redirect_url,
    study_from_dict,
    trial_plan,
)
from study_app.design.stimuli import load_stimuli
from study_app.session import (
    InvalidAnswer,
    ParticipantSession,
    Stage,
    TooEarly,
    UnknownParticipant,
    describe_value,
    prolific_params,
    prolific_problems,
    resume_url,
)

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


def test_screen_positions_are_uniform_and_drawn_per_trial():
    """Over 3000 participants each method sits at each screen position a third of the
    time (chi-square), and a participant's screen orders in two view trials are
    independent (a fixed order per participant would make a position habit a method
    preference)."""
    from scipy import stats

    scenes = ["a", "b", "c", "d", "e"]
    plans = [trial_plan(scenes, seed) for seed in range(3000)]
    views = [[t for t in p if t.task == "view"] for p in plans]
    for m in VIEW_METHODS:
        at = [v.shown_order.index(m) for vs in views for v in vs]
        counts = [at.count(k) for k in range(len(VIEW_METHODS))]
        assert stats.chisquare(counts).pvalue > 0.001, (m, counts)
    first = [vs[0].shown_order for vs in views]
    second = [vs[1].shown_order for vs in views]
    table = __import__("pandas").crosstab([str(o) for o in first], [str(o) for o in second])
    assert table.shape == (6, 6)
    assert stats.chi2_contingency(table).pvalue > 0.001


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
    p.write_text(
        '[study]\nid = "x"\ntitle = "t"\nvideo_fps = -3\n[[scenes]]\nid = "a"\ndemo = "walk"\n'
    )
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
    from study_app.design.protocol import DEMO_CONFIG, PAPER_CONFIG

    demo = load_study(DEMO_CONFIG)
    assert demo.id == "demo" and all("demo" in s for s in demo.scenes)
    paper = load_study(PAPER_CONFIG)
    assert len(paper.scenes) == 6
    assert [s["fps"] for s in paper.scenes if "salsa" in s["id"]] == [60, 60]


def test_attention_and_redirect():
    study = study_from_dict(
        fixture_study_doc(redirect_url="https://app.prolific.com/submissions/complete?cc={code}")
    )
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
    s.submit_pose(0, 5, response_time_s=1, events=[{"kind": "shown", "t": 0}])
    kinds = [(e["kind"], e["trial_index"]) for e in store.events(s.participant_id)]
    assert kinds == [("shown", 0), ("shown", 1)]


def test_the_next_trial_is_shown_when_an_answer_is_stored(store, stimuli):
    """An answer stores the next trial's shown event in its own transaction, at the
    answer's time: the run that shows the next trial reads no clock and writes none,
    a reload gets the same moment, and the last trial has no next one."""
    s = ParticipantSession.start(store, stimuli)
    s.submit_background(BACKGROUND)
    s.trial_shown_at(0)
    s.submit_pose(0, 5, response_time_s=1)
    (answer,) = store.responses(s.participant_id)
    shown = [e for e in store.events(s.participant_id) if e["kind"] == "shown"]
    assert [e["trial_index"] for e in shown] == [0, 1]
    assert shown[1]["created_at"] == answer["created_at"]
    assert shown[1]["payload"] == {
        "min_answer_s": stimuli.study.min_answer_s,
        "require_watch": stimuli.study.require_watch,
    }
    # The same moment for this session (no query), for a reload, and no second event.
    t1 = s.trial_shown_at(1)
    assert ParticipantSession.resume(store, stimuli, s.participant_id).trial_shown_at(1) == t1
    assert len([e for e in store.events(s.participant_id) if e["kind"] == "shown"]) == 2
    # A second answer to the same trial (another tab) stores no shown event either.
    assert not s.submit_pose(0, 6, response_time_s=1)
    assert len([e for e in store.events(s.participant_id) if e["kind"] == "shown"]) == 2
    # Through to the end: every trial but the first was shown by the answer before it.
    for t in s.plan[1:]:
        if t.task == "pose":
            s.submit_pose(t.index, 1, response_time_s=1)
        elif t.task == "view":
            s.submit_view(t.index, 0, t.shown_order[0], response_time_s=1)
        else:
            s.submit_attention(t.index, "A red square", response_time_s=1)
    assert s.stage is Stage.DONE
    shown = [e["trial_index"] for e in store.events(s.participant_id) if e["kind"] == "shown"]
    assert shown == list(range(len(s.plan)))


def test_picker_events_are_sanitised(store, stimuli):
    """Known event kinds are kept with numeric fields only; junk entries are dropped."""
    s = ParticipantSession.start(store, stimuli)
    s.submit_background(BACKGROUND)
    events = [
        {"kind": "play", "t": 0.25, "frame": 0},
        {"kind": "hack", "t": 1},
        "nonsense",
        {"kind": "step", "by": 1, "frame": 5, "extra": "x" * 1000},
        {"kind": "seek", "frame": 999, "from": 3, "t": float("inf")},
    ]
    s.submit_pose(0, 5, response_time_s=2, events=events)
    got = [
        (e["kind"], e["payload"]) for e in store.events(s.participant_id) if e["trial_index"] == 0
    ]  # (trial 1's "shown" event came with the answer)
    assert got == [
        ("play", {"t": 0.25, "frame": 0}),
        ("step", {"frame": 5, "by": 1}),
        ("seek", {"from": 3}),
    ]


# ----------------------------------------------------------------------------- the field study (issue 14)


def test_one_prolific_id_is_one_participant(store, stimuli):
    """The same PROLIFIC_PID consenting twice (two browsers) resumes the first record."""
    q = {"PROLIFIC_PID": "60a1b2c3d4e5f60718293a4b", "STUDY_ID": "st", "SESSION_ID": "s1"}
    a = ParticipantSession.start(store, stimuli, prolific=q)
    b = ParticipantSession.start(store, stimuli, prolific={**q, "SESSION_ID": "s2"})
    assert a.participant_id == b.participant_id and a.seed == b.seed
    assert ParticipantSession.for_prolific(store, stimuli, q).participant_id == a.participant_id
    assert ParticipantSession.for_prolific(store, stimuli, {"PROLIFIC_PID": "abc123"}) is None
    assert [p["prolific_pid"] for p in store.participants()] == [q["PROLIFIC_PID"]]
    # without a Prolific id every consent is a new participant
    assert ParticipantSession.start(store, stimuli).participant_id != a.participant_id


def test_malformed_prolific_parameters_are_named():
    """Odd PROLIFIC_PID / STUDY_ID / SESSION_ID values are problems, not silently dropped."""
    ok = {"PROLIFIC_PID": "60a1b2c3d4e5f60718293a4b", "STUDY_ID": "x", "SESSION_ID": "y"}
    assert prolific_problems(ok) == [] and prolific_problems({}) == []
    for bad in ("a" * 65, "Ünïcødé", "<script>alert(1)</script>", "1' OR '1'='1", "", ["a", "b"]):
        (msg,) = prolific_problems({**ok, "PROLIFIC_PID": bad})
        assert "PROLIFIC_PID" in msg and "not a valid Prolific value" in msg
    assert len(prolific_problems({"STUDY_ID": "a b", "SESSION_ID": "é"})) == 2
    assert describe_value("<script>") == "'<script>'"
    assert describe_value("é" * 100).endswith("(402 characters)")  # ascii-escaped


def test_answers_too_soon_are_refused(store, stimuli):
    """An answer sooner than min_answer_s after its trial appeared writes nothing."""
    s = ParticipantSession.start(store, stimuli, seed=3)
    s.submit_background(BACKGROUND)
    assert stimuli.study.min_answer_s == 1.0  # the default
    with pytest.raises(TooEarly, match="on screen long enough"):
        s.submit_pose(0, 2, response_time_s=0.455)
    assert store.answered_trials(s.participant_id) == set()
    assert s.submit_pose(0, 2, response_time_s=1.2)


def test_watching_is_required_and_stored(store, stimuli):
    """require_watch (default on): a confirm before the animation was watched is refused;
    the share watched is stored with the choice; a stored log counts after a reload."""
    s = ParticipantSession.start(store, stimuli, seed=4)
    s.submit_background(BACKGROUND)
    with pytest.raises(InvalidAnswer, match="watch the whole animation"):
        s.submit_pose(
            0,
            3,
            response_time_s=5,
            watched=0.5,
            events=[{"kind": "select", "frame": 3, "watched": 0.5}],
        )
    assert store.answered_trials(s.participant_id) == set()
    # the player's log arrives in batches while the trial is open ...
    assert (
        s.record_picker_events(
            0,
            [
                {"kind": "play", "t": 0.1, "frame": 0, "watched": 0},
                {"kind": "ended", "t": 1.1, "frame": 23, "watched": 1},
                {"kind": "step", "t": 2, "frame": 7, "by": -1},
            ],
        )
        == 3
    )
    assert s.picker_state(0) == (7, 1.0)  # where to restore the player after a reload
    assert s.record_picker_events(1, [{"kind": "play"}]) == 0  # not the open trial
    # ... and a reloaded player that reports less still counts what was watched before
    assert s.submit_pose(
        0,
        7,
        response_time_s=5,
        watched=0.2,
        events=[{"kind": "select", "frame": 7, "watched": 0.2}],
    )
    kinds = [e["kind"] for e in store.events(s.participant_id) if e["trial_index"] == 0]
    assert kinds == ["play", "ended", "step", "select"]
    assert s.record_picker_events(0, [{"kind": "play"}]) == 0  # answered: ignored


def test_view_answer_is_mapped_from_the_position(store, stimuli):
    """The page sends a position; the stored method is the one the plan put there."""
    s = ParticipantSession.start(store, stimuli, seed=5)
    s.submit_background(BACKGROUND)
    s.submit_pose(0, 1, response_time_s=2)
    s.submit_pose(1, 1, response_time_s=2)
    assert s.submit_view(2, 1, response_time_s=2)
    row = store.responses(s.participant_id)[-1]
    assert (row["chosen_position"], row["chosen_method"]) == (1, s.plan[2].shown_order[1])
    assert check_view_choice(s.plan[2], 0) == (0, s.plan[2].shown_order[0])


def test_background_names_every_missing_answer(store, stimuli):
    """All missing background answers are named at once; a self-description is kept."""
    s = ParticipantSession.start(store, stimuli, seed=6)
    with pytest.raises(InvalidAnswer, match=r"questions about your age, gender and experience\."):
        s.submit_background({})
    with pytest.raises(InvalidAnswer, match=r"question about your experience\.$"):
        s.submit_background({"age_band": "18–24", "gender": "Man"})
    s.submit_background(
        {**BACKGROUND, "gender": "Prefer to self-describe", "gender_self": "  genderfluid "}
    )
    assert store.get_participant(s.participant_id)["background"]["gender_self"] == "genderfluid"


def test_estimated_minutes_follow_the_stimuli():
    """The consent page's duration is computed from the animations' lengths."""
    assert estimated_minutes([]) == 2  # consent, background, attention check: 120 s
    # two 3 s animations: 120 + 2 * (9 + 20) + 2 * 15 = 208 s → 4 minutes (rounded up)
    assert estimated_minutes([3.0, 3.0]) == 4
    assert estimated_minutes([60.0] * 6) > estimated_minutes([3.0] * 6)
    study = study_from_dict(fixture_study_doc())
    assert "about 7 minutes" in consent_text(study, 7) and "{minutes}" not in consent_text(study, 7)


def test_new_study_options_are_validated_by_the_schema():
    """min_answer_s, require_watch, near_duplicate(_deg): defaults, and bad values refused."""
    s = study_from_dict(fixture_study_doc())
    assert (s.min_answer_s, s.require_watch, s.near_duplicate_deg, s.near_duplicate) == (
        1.0,
        True,
        15.0,
        "merge",  # issue 36: alike pictures shown once
    )
    s = study_from_dict(
        fixture_study_doc(
            min_answer_s=0.5, require_watch=False, near_duplicate_deg=20, near_duplicate="error"
        )
    )
    assert study_from_dict(s.to_dict()) == s  # the manifest keeps them
    for bad in (
        {"min_answer_s": -1},
        {"min_answer_s": "1"},
        {"require_watch": "yes"},
        {"near_duplicate": "drop"},
        {"near_duplicate_deg": 200},
    ):
        with pytest.raises(SchemaError, match=next(iter(bad))):
            study_from_dict(fixture_study_doc(**bad))


def test_bundled_configs_show_participants_no_paper_jargon():
    """Participant-facing text of the bundled studies has no section numbers or
    "demonstration of" (it was shown on the consent page)."""
    from study_app.design.protocol import DEMO_CONFIG, PAPER_CONFIG

    for path in (DEMO_CONFIG, PAPER_CONFIG):
        st = load_study(path)
        for text in (st.title, st.description, st.consent):
            assert "§" not in text and "demonstration of" not in text.lower(), (path, text)


def test_resume_url_is_the_app_address_with_the_id():
    """The personal link: the app's root with ?pid=, whatever page the URL names."""
    assert resume_url("http://h:8501/", "abc") == "http://h:8501/?pid=abc"
    assert resume_url("http://h:8501/study", "abc") == "http://h:8501/?pid=abc"
    assert resume_url("https://x.org/app/study", "abc") == "https://x.org/app/?pid=abc"
