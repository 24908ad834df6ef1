"""The study app driven by Streamlit's AppTest: every page, and the rows it stores.

The browser widgets (frame picker, view chooser) are components v2; AppTest cannot click
inside them, so :func:`send_trigger` sends exactly what their JavaScript sends — a trigger
value on the component's event widget — through AppTest's own run path. The real
JavaScript is exercised by the browser test (tests/test_e2e.py).
"""

from __future__ import annotations

import json
import shutil

import pytest
from app_helpers import (
    FIXTURE_ALGORITHM_FRAME,
    FIXTURE_MOTION_FPS,
    FIXTURE_MOTION_FRAMES,
    fixture_study_doc,
    write_fixture_stimuli,
)

from study_app.data.store import Store
from study_app.design.protocol import trial_plan
from study_app.web.picker import ANSWER_BUTTON, FRAME_PICKER, VIEW_CHOOSER
from study_app.web.screens import keys

pytest.importorskip("streamlit.testing.v1")
from streamlit.proto.WidgetStates_pb2 import WidgetState  # noqa: E402
from streamlit.testing.v1 import AppTest  # noqa: E402

APP = "../study_app/web/app.py"
TIMEOUT = 30
BACKGROUND = {"age_band": "25–34", "gender": "Woman", "experience": "No experience"}


@pytest.fixture(scope="module")
def stimuli_dir(tmp_path_factory):
    d = tmp_path_factory.mktemp("stimuli") / "fixture"
    # AppTest answers within milliseconds and plays no video: no minimum answer time
    # and no watching requirement here (the browser tests check both).
    write_fixture_stimuli(
        d,
        fixture_study_doc(
            redirect_url="https://app.prolific.com/submissions/complete?cc={code}",
            completion_code="C0DE42",
            min_answer_s=0,
            require_watch=False,
        ),
    )
    return d


@pytest.fixture
def store(stimuli_dir, tmp_path, monkeypatch):
    url = f"sqlite:///{tmp_path / 'study.db'}"
    monkeypatch.setenv(keys.ENV_STIMULI, str(stimuli_dir))
    monkeypatch.setenv(keys.ENV_DB, url)
    monkeypatch.delenv(keys.ENV_ADMIN_TOKEN, raising=False)
    s = Store(url)
    yield s
    s.close()


def new_app(**query) -> AppTest:
    at = AppTest.from_file(APP, default_timeout=TIMEOUT)
    for k, v in query.items():
        at.query_params[k] = v
    return at.run()


def component(at: AppTest, name: str):
    found = [e for e in at.get("bidi_component") if e.proto.component_name == name]
    assert len(found) == 1, f"expected one {name} on the page, found {len(found)}"
    return found[0]


def players(at: AppTest) -> list:
    """The frame pickers on the page (the personal link's copy button is a component too)."""
    return [e for e in at.get("bidi_component") if e.proto.component_name == FRAME_PICKER]


def send_trigger(at: AppTest, name: str, event: str, value) -> AppTest:
    """Do what the component's ``setTriggerValue(event, value)`` does in a browser."""
    from streamlit.components.v2.bidi_component.main import _make_trigger_id

    el = component(at, name)
    states = at._tree.get_widget_states()
    states.widgets.append(
        WidgetState(
            id=_make_trigger_id(el.proto.id, "events"),
            json_trigger_value=json.dumps([{"event": event, "value": value}]),
        )
    )
    return at._run(states)


#: What answer_button.js reports with a press (client.js clientInfo): a desktop browser.
CLIENT = {"viewport": [1280, 720], "dpr": 1, "input": "mouse", "active_s": 3.0, "tab": "k3x9q2m7za"}


def press_answer(at: AppTest) -> AppTest:
    """Press the page's answer button (Continue, Confirm on the slider) as a browser does."""
    return send_trigger(at, ANSWER_BUTTON, "press", {"client": dict(CLIENT)})


def texts(at: AppTest) -> str:
    parts = [e.value for e in at.markdown] + [e.value for e in at.header]
    parts += [e.value for e in at.error] + [e.value for e in at.warning]
    parts += [e.value for e in at.success]
    return "\n".join(str(p) for p in parts)


def consent_and_background(at: AppTest) -> str:
    at.checkbox(key=keys.KEY_CONSENT_AGREE).check().run()
    at.button(key=keys.KEY_CONSENT_START).click().run()
    pid = at.query_params[keys.QUERY_PID]
    pid = pid[0] if isinstance(pid, list) else pid
    at.selectbox(key=keys.KEY_BG_AGE).select(BACKGROUND["age_band"])
    at.radio(key=keys.KEY_BG_GENDER).set_value(BACKGROUND["gender"])
    at.radio(key=keys.KEY_BG_EXPERIENCE).set_value(BACKGROUND["experience"])
    at.button(key=keys.KEY_BG_SUBMIT).click().run()
    return pid


def progress_value(at: AppTest) -> float:
    (bar,) = at.get("progress")
    return bar.proto.value


def test_whole_session_stores_every_answer(store):
    """Consent → background → pose → view → attention → done; the stored rows match the clicks."""
    at = new_app(PROLIFIC_PID="5f1e2d3c4b5a69788796a5b4", STUDY_ID="S1", SESSION_ID="X9")
    assert not at.exception
    assert "I have read" in at.checkbox(key=keys.KEY_CONSENT_AGREE).label
    assert progress_value(at) == 0
    assert store.progress()["participants"] == 0  # nothing stored before consent
    pid = consent_and_background(at)
    part = store.get_participant(pid)
    assert part["background"] == BACKGROUND
    assert part["prolific_pid"] == "5f1e2d3c4b5a69788796a5b4"
    assert part["prolific_study_id"] == "S1" and part["prolific_session_id"] == "X9"
    plan = trial_plan(["walk", "jump"], part["seed"])  # the order this participant sees
    picks = {}
    chosen = {}
    for trial in plan:
        assert not at.exception, at.exception
        if trial.task == "pose":
            picker = component(at, FRAME_PICKER)
            data = json.loads(picker.proto.json)[0]
            assert data["trial"] == trial.index and data["n_frames"] == 24
            assert data["fps"] == 24.0 and data["sources"][0]["src"].endswith(".mp4")
            video_frame = 3 + 5 * trial.index
            picks[trial.scene] = video_frame
            events = [
                {"kind": "play", "t": 0.5, "frame": 0},
                {"kind": "pause", "t": 1.5, "frame": 12},
                {"kind": "step", "t": 2.0, "frame": video_frame},
            ]
            at = send_trigger(
                at,
                FRAME_PICKER,
                "confirm",
                {"trial": trial.index, "frame": video_frame, "events": events},
            )
        elif trial.task == "view":
            chooser = component(at, VIEW_CHOOSER)
            data = json.loads(chooser.proto.json)[0]
            # The page gets pictures by position only: no method names.
            assert all(set(v) == {"src", "label"} for v in data["views"])
            position = trial.index % 3
            chosen[trial.scene] = (position, trial.shown_order[position])
            at = send_trigger(
                at, VIEW_CHOOSER, "choice", {"trial": trial.index, "position": position}
            )
        else:
            at.radio(key=keys.KEY_ATTENTION_CHOICE).set_value("A purple circle")
            at = press_answer(at)
    assert not at.exception
    assert "Thank you" in texts(at)
    assert progress_value(at) == 100
    assert [c.value for c in at.code] == ["C0DE42"]  # the study's fixed completion code
    (link,) = at.get("link_button")
    assert link.proto.url == "https://app.prolific.com/submissions/complete?cc=C0DE42"
    # How to withdraw after the end: whom to write to, with which id.
    assert any("withdraw" in c.value and pid in c.value for c in at.caption)

    rows = store.responses(pid)
    assert [r["trial_index"] for r in rows] == list(range(len(plan)))
    # The attention answer is described like the others: what the button reported.
    (att,) = [r for r in rows if r["task"] == "attention"]
    assert (att["viewport_width"], att["tab_id"]) == (1280, CLIENT["tab"])
    for r, trial in zip(rows, plan):
        assert (r["task"], r["scene"], r["stimulus_id"]) == (
            trial.task,
            trial.scene,
            trial.stimulus_id,
        )
        assert r["age_band"] == "25–34" and r["prolific_pid"] == "5f1e2d3c4b5a69788796a5b4"
        assert r["response_time_s"] >= 0
        if trial.task == "pose":
            v = picks[trial.scene]
            # The fixture's video shows motion frame 2v at video frame v (48 fps → 24 fps).
            assert r["chosen_video_frame"] == v and r["chosen_frame"] == 2 * v
            assert r["algorithm_frame"] == FIXTURE_ALGORITHM_FRAME
            assert r["fps"] == FIXTURE_MOTION_FPS and r["n_frames"] == FIXTURE_MOTION_FRAMES
        elif trial.task == "view":
            assert (r["chosen_position"], r["chosen_method"]) == chosen[trial.scene]
            assert r["shown_order"] == list(trial.shown_order)
        else:
            assert r["chosen_value"] == "A purple circle" and r["correct"] is True
    part = store.get_participant(pid)
    assert part["completed_at"] is not None and part["completion_code"] == "C0DE42"
    kinds = [(e["trial_index"], e["kind"]) for e in store.events(pid)]
    # each trial's "shown" when first displayed (once, though the page reruns), then
    # a pose trial's picker log when it is answered
    assert kinds == [
        (t.index, k)
        for t in plan
        for k in (("shown", "play", "pause", "step") if t.task == "pose" else ("shown",))
    ]


def test_reload_resumes_at_first_unanswered_trial(store):
    """A new browser session with the same ?pid lands on the first unanswered trial."""
    at = new_app()
    pid = consent_and_background(at)
    plan = trial_plan(["walk", "jump"], store.get_participant(pid)["seed"])
    at = send_trigger(at, FRAME_PICKER, "confirm", {"trial": 0, "frame": 4, "events": []})
    assert store.answered_trials(pid) == {0}
    again = new_app(pid=pid)  # "reload": fresh session state, same URL
    assert not again.exception
    data = json.loads(component(again, FRAME_PICKER).proto.json)[0]
    assert data["trial"] == 1 and plan[1].task == "pose"
    # consent, background and 1 of 5 trials: 3 of 7 steps; st.progress stores int(100 * 3/7)
    assert progress_value(again) == 42


def test_tampered_participant_id_is_refused_and_writes_nothing(store):
    """An unknown or malformed id in the URL gets a clear message; no participant is created."""
    for bad in ("AAAAAAAAAAAAAAAAAAAAAA", "../../etc/passwd", "x"):
        at = new_app(pid=bad)
        assert not at.exception
        assert "link" in texts(at).lower() and "not" in texts(at).lower()
        assert not at.get("bidi_component")
    assert store.progress()["participants"] == 0
    at.button(key=keys.KEY_RESTART).click().run()  # start over: back to consent
    assert keys.QUERY_PID not in at.query_params
    assert at.checkbox(key=keys.KEY_CONSENT_AGREE)


def test_out_of_range_frame_and_forged_position_write_nothing(store):
    """Bad answers from a browser are refused with a message; the trial stays open; a
    method named by the browser is never believed (the server maps the position)."""
    at = new_app()
    pid = consent_and_background(at)
    plan = trial_plan(["walk", "jump"], store.get_participant(pid)["seed"])
    for bad in (24, -1, 2.5, "7", None):
        at = send_trigger(at, FRAME_PICKER, "confirm", {"trial": 0, "frame": bad, "events": []})
        assert not at.exception
        assert at.error, f"no message for frame {bad!r}"
    at = send_trigger(at, FRAME_PICKER, "confirm", {"trial": 1, "frame": 3, "events": []})
    assert "order" in at.error[0].value  # answering a later trial first
    assert store.answered_trials(pid) == set()  # no answer, no picker log:
    assert [(e["trial_index"], e["kind"]) for e in store.events(pid)] == [(0, "shown")]
    # a fresh picker is mounted after a refusal, and a good answer still goes through
    at = send_trigger(at, FRAME_PICKER, "confirm", {"trial": 0, "frame": 23, "events": []})
    at = send_trigger(at, FRAME_PICKER, "confirm", {"trial": 1, "frame": 0, "events": []})
    assert store.answered_trials(pid) == {0, 1}
    view = plan[2]
    wrong = next(
        m for m in ("ours", "motion_area", "viewpoint_entropy") if m != view.shown_order[0]
    )
    for position in (3, -1, 1.5, "0", None, True):
        at = send_trigger(at, VIEW_CHOOSER, "choice", {"trial": 2, "position": position})
        assert at.error, f"no message for position {position!r}"
    assert store.answered_trials(pid) == {0, 1}
    # a forged method label in the payload is ignored: position 0 shows shown_order[0]
    at = send_trigger(at, VIEW_CHOOSER, "choice", {"trial": 2, "position": 0, "method": wrong})
    assert store.responses(pid)[-1]["chosen_method"] == view.shown_order[0]


def test_frames_picker_mode(store, stimuli_dir, tmp_path, monkeypatch):
    """picker = "frames": a slider over the extracted frames answers the pose task."""
    d = tmp_path / "frames-stimuli"
    write_fixture_stimuli(d, fixture_study_doc(picker="frames", min_answer_s=0))
    monkeypatch.setenv(keys.ENV_STIMULI, str(d))
    at = new_app()
    pid = consent_and_background(at)
    assert not players(at)
    slider = at.slider[0]
    assert (slider.min, slider.max) == (1, 24)
    slider.set_value(7).run()
    assert len(at.image) == 1  # the frame is shown
    at = press_answer(at)
    (row,) = store.responses(pid)
    assert row["chosen_video_frame"] == 6 and row["chosen_frame"] == 12  # 1-based slider


def test_video_error_switches_to_frames(store):
    """When the browser reports it cannot play the video, the slider picker takes over."""
    at = new_app()
    consent_and_background(at)
    at = send_trigger(at, FRAME_PICKER, "error", {"trial": 0, "message": "no H.264"})
    assert not players(at) and at.slider


def test_altered_stimuli_refused_before_anyone_starts(store, stimuli_dir, tmp_path, monkeypatch):
    """A changed or missing stimulus file stops the app with the file named; nothing stored."""
    bad = tmp_path / "altered"
    shutil.copytree(stimuli_dir, bad)
    with open(bad / "walk" / "view_ours.png", "ab") as f:
        f.write(b"\0")
    monkeypatch.setenv(keys.ENV_STIMULI, str(bad))
    at = new_app()
    assert "walk/view_ours.png has been altered" in at.error[0].value
    assert not at.checkbox
    gone = tmp_path / "missing"
    shutil.copytree(stimuli_dir, gone)
    (gone / "jump" / "frames" / "00003.jpg").unlink()
    monkeypatch.setenv(keys.ENV_STIMULI, str(gone))
    at = new_app()
    assert "jump/frames/00003.jpg is missing" in at.error[0].value
    assert store.progress()["participants"] == 0


def test_researcher_page_needs_the_token(store, monkeypatch):
    """Without SNAPSHOT_ADMIN_TOKEN, or with a wrong token, the page shows no data."""
    at = new_app()
    consent_and_background(at)
    send_trigger(at, FRAME_PICKER, "confirm", {"trial": 0, "frame": 5, "events": []})

    def researcher():
        a = AppTest.from_file(APP, default_timeout=TIMEOUT)
        a.switch_page("screens/researcher.py")
        return a.run()

    a = researcher()
    assert "disabled" in a.info[0].value and not a.get("metric") and not a.dataframe
    monkeypatch.setenv(keys.ENV_ADMIN_TOKEN, "s3cret-token-0123456789")
    a = researcher()
    assert not a.get("metric")
    a.text_input(key=keys.KEY_ADMIN_TOKEN).input("wrong").run()
    assert "Wrong token" in a.error[0].value and not a.get("metric")
    assert not a.get("download_button")
    a.text_input(key=keys.KEY_ADMIN_TOKEN).input("s3cret-token-0123456789").run()
    assert not a.exception
    metrics = {m.label: m.value for m in a.get("metric")}
    assert metrics["Participants"] == "1" and metrics["Responses"] == "1"
    assert len(a.get("download_button")) >= 4


def test_researcher_page_withdraws_a_participant(store, monkeypatch):
    """The researcher page deletes a participant after a confirmation and records it as
    "page"; their personal link and their Prolific study link then say so, and nothing
    new is stored for them."""
    ppid = "5f1e2d3c4b5a69788796c0c0"
    at = new_app(PROLIFIC_PID=ppid)
    pid = consent_and_background(at)
    send_trigger(at, FRAME_PICKER, "confirm", {"trial": 0, "frame": 5, "events": []})
    other = consent_and_background(new_app())
    assert store.progress()["responses"] == 1
    monkeypatch.setenv(keys.ENV_ADMIN_TOKEN, "s3cret-token-0123456789")
    a = AppTest.from_file(APP, default_timeout=TIMEOUT)
    a.switch_page("screens/researcher.py")
    a.run()
    a.text_input(key=keys.KEY_ADMIN_TOKEN).input("s3cret-token-0123456789").run()
    a.text_input(key=keys.KEY_WITHDRAW_ID).input(pid).run()
    assert any(pid in w.value and "1 responses" in w.value for w in a.warning)
    assert a.button(key=keys.KEY_WITHDRAW_BUTTON).disabled  # not before the confirmation
    assert store.get_participant(pid) is not None
    a.checkbox(key=f"{keys.KEY_WITHDRAW_CONFIRM}.{pid}").check().run()
    a.button(key=keys.KEY_WITHDRAW_BUTTON).click().run()
    assert not a.exception
    assert any(f"Withdrew participant {pid}" in m.value for m in a.success)
    with store.engine.connect() as conn:
        left = {
            t: conn.exec_driver_sql(
                f"SELECT COUNT(*) FROM {t} WHERE participant_id = ?", (pid,)
            ).scalar()
            for t in ("participants", "responses", "events")
        }
        record = conn.exec_driver_sql(
            "SELECT requested_by, prolific_pid FROM withdrawals WHERE participant_id = ?", (pid,)
        ).all()
    assert left == {"participants": 0, "responses": 0, "events": 0}
    assert record == [("page", ppid)]
    assert [p["participant_id"] for p in store.participants()] == [other]
    for link in ({"pid": pid}, {"PROLIFIC_PID": ppid}):
        back = new_app(**link)
        assert back.header[0].value == "Your data were withdrawn", link
        assert "withdrawn" in back.info[0].value and not back.checkbox
    assert [p["participant_id"] for p in store.participants()] == [other]


def test_background_self_describe_and_missing_answers(store):
    """ "Prefer to self-describe" opens a text box whose text is stored; every missing
    answer is named in one message at the top of the page."""
    at = new_app()
    at.checkbox(key="consent.agree").check().run()
    at.button(key="consent.start").click().run()
    pid = at.query_params["pid"]
    pid = pid[0] if isinstance(pid, list) else pid
    at.button(key=keys.KEY_BG_SUBMIT).click().run()
    (warning,) = at.warning
    assert warning.value == "Please answer the questions about your age, gender and experience."
    main = list(at.main)
    assert main.index(warning) < main.index(at.selectbox(key="background.age_band"))  # on top
    assert not at.text_input
    at.radio(key="background.gender").set_value("Prefer to self-describe").run()
    at.text_input(key="background.gender_self").input("agender").run()
    at.button(key=keys.KEY_BG_SUBMIT).click().run()
    assert at.warning[0].value == "Please answer the questions about your age and experience."
    at.selectbox(key="background.age_band").select(BACKGROUND["age_band"])
    at.radio(key="background.experience").set_value(BACKGROUND["experience"])
    at.button(key=keys.KEY_BG_SUBMIT).click().run()
    assert store.get_participant(pid)["background"] == {
        "age_band": "25–34",
        "gender": "Prefer to self-describe",
        "experience": "No experience",
        "gender_self": "agender",
    }


def test_fallback_text_matches_its_controls(store):
    """The player's instructions name Play and the arrow keys; the slider fallback's
    instructions name the slider, not controls it does not have."""
    at = new_app()
    consent_and_background(at)
    text = " ".join(m.value for m in at.markdown)
    assert "**Play**" in text and "arrow keys" in text and "slider" not in text
    at = send_trigger(at, FRAME_PICKER, "error", {"trial": 0, "message": "no H.264"})
    text = " ".join(m.value for m in at.markdown)
    assert "**Frame** slider" in text
    assert "Play" not in text and "arrow" not in text and "space bar" not in text


def test_a_withdrawn_finisher_stays_payable_and_the_page_lists_withdrawals(store, monkeypatch):
    """Someone who finished and then withdrew keeps their completion code in the page's
    completion codes (marked withdrawn, their data gone) and the page lists every
    withdrawal; the code is in no export."""
    from click.testing import CliRunner

    from snapcore.cli.main import cli
    from study_app.data.withdraw import withdraw

    ppid = "5f1e2d3c4b5a69788796d0d0"
    pid = store.create_participant(
        "fixture", "ab" * 32, app_version="0.1.0", seed=1, prolific={"PROLIFIC_PID": ppid}
    )
    code = store.complete(pid)
    started = store.create_participant("fixture", "ab" * 32, app_version="0.1.0", seed=2)
    withdraw(store, participant_id=pid)
    withdraw(store, participant_id=started)  # never finished: owed nothing
    monkeypatch.setenv(keys.ENV_ADMIN_TOKEN, "s3cret-token-0123456789")
    a = AppTest.from_file(APP, default_timeout=TIMEOUT)
    a.switch_page("screens/researcher.py")
    a.run()
    a.text_input(key=keys.KEY_ADMIN_TOKEN).input("s3cret-token-0123456789").run()
    assert not a.exception
    tables = [d.value for d in a.dataframe]
    codes = next(t for t in tables if "completion code" in t.columns)
    assert list(codes["completion code"]) == [code] and list(codes["Prolific id"]) == [ppid]
    assert codes["withdrawn (UTC)"].iloc[0] != ""
    listed = next(t for t in tables if "link id" in t.columns)
    assert set(listed["link id"]) == {pid, started}
    out = store.url.removeprefix("sqlite:///")
    result = CliRunner().invoke(
        cli,
        ["export", "--db", out, "-o", f"{out}.csv", "--participants", f"{out}.p.csv", "-q"]
        + ["--identifiers"],
    )
    assert result.exit_code == 0, result.output
    assert not [f for f in (f"{out}.csv", f"{out}.p.csv") if code in open(f).read()]
