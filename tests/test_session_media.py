"""A participant whose media fail (issue 36): the way on after pictures that never load
(a skipped row, never a choice), a failed position refused, a slider answer keeping
what was watched, and every answer type carrying what it was given on."""

from __future__ import annotations

import pytest
from app_helpers import write_fixture_stimuli

from study_app.data.store import Store
from study_app.design.stimuli import load_stimuli
from study_app.session import InvalidAnswer, ParticipantSession

BACKGROUND = {"age_band": "18–24", "gender": "Man", "experience": "No experience"}
CLIENT = {"viewport": [1280, 720], "dpr": 2, "input": "touch", "active_s": 1.5, "tab": "t1"}


@pytest.fixture(scope="module")
def stimuli(tmp_path_factory):
    d = tmp_path_factory.mktemp("media") / "stimuli"
    write_fixture_stimuli(d)
    return load_stimuli(d)


@pytest.fixture
def session(tmp_path, stimuli):
    with Store(f"sqlite:///{tmp_path / 'db.sqlite'}") as store:
        s = ParticipantSession.start(store, stimuli, seed=3)
        s.submit_background(BACKGROUND)
        yield s


def _to_first_view(s) -> int:
    for t in s.plan:
        if t.task == "pose":
            s.submit_pose(t.index, 0, response_time_s=2, watched=1.0)
        else:
            return t.index
    raise AssertionError("no view trial")


def test_skip_only_after_a_failure_and_stored_as_skipped(session):
    """Skipping a view trial whose pictures loaded is refused; after a failure it stores
    a row with skipped = media_failed, no method, no position, the client described."""
    s = session
    i = _to_first_view(s)
    with pytest.raises(InvalidAnswer, match="have loaded"):
        s.skip_view(i, response_time_s=3, client=CLIENT)
    assert s.record_media_failure(i, "image", [1], "t1")
    assert s.skip_view(i, response_time_s=0.2, client=CLIENT)  # no min_answer_s: nothing seen
    (row,) = [r for r in s.store.responses(s.participant_id) if r["trial_index"] == i]
    assert (row["skipped"], row["chosen_method"], row["chosen_position"]) == (
        "media_failed",
        None,
        None,
    )
    assert row["viewport_width"] == 1280 and row["input_type"] == "touch"
    assert row["shown_groups"] == [[m] for m in row["shown_order"]]
    assert not s.skip_view(i, response_time_s=3)  # a second press: harmless


def test_failed_position_refused_until_loaded_again(session):
    """A choice of a position the browser reported as failed is refused (nothing
    stored); once every picture loaded again, it is an ordinary choice."""
    s = session
    i = _to_first_view(s)
    s.record_media_failure(i, "image", [2], "t1")
    with pytest.raises(InvalidAnswer, match="did not load"):
        s.submit_view(i, 2, response_time_s=3)
    assert not [r for r in s.store.responses(s.participant_id) if r["trial_index"] == i]
    assert s.record_media_failure(i, "image", [], "t1")  # "Try again" brought it back
    assert [e["kind"] for e in s.store.events(s.participant_id)][-1] == "media_loaded"
    assert s.submit_view(i, 2, response_time_s=3, client=CLIENT)


def test_slider_answer_keeps_the_share_watched(session):
    """A slider answer after the video played part-way keeps that share on its row."""
    s = session
    s.record_picker_events(
        0, [{"kind": "play", "t": 0, "frame": 0}, {"kind": "watch", "t": 1, "ranges": [[0, 7]]}]
    )
    assert s.submit_pose(0, 3, response_time_s=2, watched=None, client=CLIENT)
    row = s.store.responses(s.participant_id)[0]
    # video frames 0-7 of the fixture's 24 played: 7/24 of the animation
    assert row["picked_with"] == "slider" and row["watched"] == pytest.approx(7 / 24, abs=0.001)
    assert row["device_pixel_ratio"] == 2 and row["tab_id"] == "t1"


def test_attention_answer_described(session):
    """The attention check's row carries what it was answered on."""
    s = session
    for t in s.plan[:-1]:
        if t.task == "pose":
            s.submit_pose(t.index, 0, response_time_s=2, watched=1.0)
        else:
            s.submit_view(t.index, 0, response_time_s=2)
    att = s.plan[-1]
    assert s.submit_attention(att.index, "A red square", response_time_s=2, client=CLIENT)
    row = s.store.responses(s.participant_id)[-1]
    assert (row["viewport_width"], row["viewport_height"], row["active_time_s"]) == (1280, 720, 1.5)
