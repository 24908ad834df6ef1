"""End to end in a real browser: `snapshot study` on a free port, headless Chromium clicks.

One participant goes through every page like a person (including the frame picker's
play/pause/step buttons), reloads in the middle and resumes; then the database is
checked row by row. Tampering (unknown id, out-of-range frame, forged view position) is
done the way a participant could — through the URL or the page's DOM — and must store
nothing. A screenshot of every page goes to ``var/test-artifacts/e2e/``.

Needs Chromium (/usr/bin/chromium) and Playwright for Python (never `playwright install`).
"""

from __future__ import annotations

import os
import re
import shutil
import socket
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import pytest
from app_helpers import tiny_demo_stimuli
from conftest import need

from study_app.data.store import Store
from study_app.design.protocol import trial_plan
from study_app.design.stimuli import load_stimuli

pytestmark = [pytest.mark.browser, pytest.mark.slow]

CHROMIUM = "/usr/bin/chromium"
CHROMIUM_ARGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
    "--disable-quic",
]
REPO = Path(__file__).resolve().parents[1]
SNAPSHOT = str(Path(sys.executable).with_name("snapshot"))
ARTIFACTS = REPO / "var" / "test-artifacts" / "e2e"
TOKEN = "e2e-researcher-token"
#: Seconds to wait for the server to answer /_stcore/health.
SERVER_START_S = 90
#: Streamlit marks the app root with the script state; "notRunning" = the page is settled.
#: (Callers first wait for something the run they wait on draws, a heading or a message,
#: so a run that has not started yet cannot pass for a finished one.)
IDLE = "[data-testid=stApp][data-test-script-state=notRunning]"
#: The same as a JavaScript condition (for the Firefox test, which has no Playwright).
SETTLED = f"() => document.querySelector('{IDLE}') !== null"


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def start_study(stimuli, db: str, log_path) -> tuple[subprocess.Popen, str]:
    """Start `snapshot study` on a free port, its output in ``log_path``; wait until it
    answers /_stcore/health. Returns (process, base url); fails the test with the log."""
    port = free_port()
    with open(log_path, "w") as log:  # the child keeps its own handle
        proc = subprocess.Popen(
            [SNAPSHOT, "study", "--stimuli", str(stimuli), "--db", db, "--port", str(port)],
            env={**os.environ, "SNAPSHOT_ADMIN_TOKEN": TOKEN},
            stdout=log,
            stderr=subprocess.STDOUT,
        )
    base = f"http://127.0.0.1:{port}"
    deadline = time.monotonic() + SERVER_START_S
    while True:
        try:
            with urllib.request.urlopen(f"{base}/_stcore/health", timeout=2) as r:
                if r.read() == b"ok":
                    return proc, base
        except OSError:
            pass
        if proc.poll() is not None or time.monotonic() > deadline:
            proc.kill()
            pytest.fail(f"server did not start:\n{Path(log_path).read_text()}")
        time.sleep(0.25)


def stop_process(proc: subprocess.Popen, timeout_s: float = 15) -> None:
    """Terminate a child process, killing it when it does not stop within ``timeout_s``."""
    proc.terminate()
    try:
        proc.wait(timeout=timeout_s)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()


@pytest.fixture(scope="module")
def playwright_api():
    sync = pytest.importorskip("playwright.sync_api")
    need(os.path.exists(CHROMIUM), f"no Chromium at {CHROMIUM}")
    return sync


@pytest.fixture(scope="module")
def artifacts():
    if ARTIFACTS.exists():
        shutil.rmtree(ARTIFACTS)
    ARTIFACTS.mkdir(parents=True)
    return ARTIFACTS


@pytest.fixture(scope="module")
def stimuli_dir(tmp_path_factory):
    """Real stimuli (the tiny two-scene study), built once per test session."""
    out, r = tiny_demo_stimuli(tmp_path_factory)
    if r is not None:
        assert r.returncode == 0, r.stderr
    return out


@pytest.fixture(scope="module")
def server(stimuli_dir, tmp_path_factory, playwright_api):
    """`snapshot study` serving the stimuli on a free port; yields (base url, store)."""
    db = f"sqlite:///{tmp_path_factory.mktemp('e2e-db') / 'study.db'}"
    log_path = tmp_path_factory.mktemp("e2e-log") / "server.log"
    proc, base = start_study(stimuli_dir, db, log_path)
    store = Store(db)
    yield base, store
    store.close()
    stop_process(proc)


@pytest.fixture(scope="module")
def browser(playwright_api):
    with playwright_api.sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        yield b
        b.close()


@pytest.fixture
def page(browser):
    context = browser.new_context(viewport={"width": 1000, "height": 900})
    pg = context.new_page()
    pg.set_default_timeout(20_000)
    yield pg
    context.close()


def settle(page) -> None:
    """Wait until Streamlit has finished the current script run (see :data:`SETTLED`)."""
    page.wait_for_selector(IDLE, timeout=30_000)


def after_resize(page) -> None:
    """Wait until the page has laid itself out again after a viewport change: two
    animation frames (resize observers run before the first paint) and a settled app."""
    page.evaluate("() => new Promise(r => requestAnimationFrame(() => requestAnimationFrame(r)))")
    settle(page)


def video_settled(page) -> None:
    """Wait until the picker's video shows the frame it was sent to (no seek pending:
    the picker chains its seeks, so ``seeking`` stays true until the last lands)."""
    video = page.locator(".snap-picker video").element_handle()
    page.wait_for_function("v => !v.seeking && v.readyState >= 2", arg=video, timeout=20_000)


def wait_until_answerable(store, pid: str, trial_index: int, min_answer_s: float) -> None:
    """Return once the trial has been on screen for the study's ``min_answer_s`` (the app
    refuses an earlier answer as the second click of a double click): the deadline is the
    stored time the trial was first shown, not a guess."""
    from datetime import datetime

    from study_app.session import SHOWN_EVENT

    deadline = time.monotonic() + 30
    while True:
        shown = [
            e["created_at"]
            for e in store.events(pid)
            if e["kind"] == SHOWN_EVENT and e["trial_index"] == trial_index
        ]
        if shown:
            break
        assert time.monotonic() < deadline, f"trial {trial_index} was never shown"
        time.sleep(0.05)  # polling the store
    left = datetime.fromisoformat(shown[0]).timestamp() + min_answer_s - time.time()
    if left > 0:
        time.sleep(left)


def shot(page, artifacts, name: str) -> None:
    settle(page)
    page.screenshot(path=str(artifacts / f"{name}.png"), full_page=True)


def heading(page, text: str):
    from playwright.sync_api import expect

    h = page.get_by_role("heading", name=text)
    expect(h).to_be_visible(timeout=30_000)
    return h


def completion_code(page) -> str:
    """The completion code on the "Thank you!" page, read once the page is the only one
    shown: Streamlit sends the new page's elements one by one and removes the previous
    page's (the attention check's resume link is a code block too) only when the run
    ends, so right after the heading two code blocks can be on screen."""
    from playwright.sync_api import expect

    settle(page)
    code = page.locator("[data-testid=stCode]")
    expect(code).to_have_count(1, timeout=30_000)
    return code.inner_text().strip()


def agree_and_start(page) -> str:
    from playwright.sync_api import expect

    page.get_by_text("I have read the information").click()
    start = page.get_by_role("button", name="Start the study")
    expect(start).to_be_enabled()
    start.click()
    heading(page, "About you")
    pid = re.search(r"[?&]pid=([A-Za-z0-9_-]+)", page.url)
    assert pid, page.url
    return pid.group(1)


def answer_background(page) -> None:
    settle(page)
    page.get_by_role("combobox", name="Your age").click()
    page.get_by_role("option", name="35–44").click()
    page.get_by_text("Prefer not to say", exact=True).first.click()
    page.get_by_text("Some (a course or a hobby)").click()


def picker_ready(page):
    page.wait_for_selector(".snap-picker[data-ready='1']", timeout=30_000)
    return page.get_by_test_id("picker-frame")


def watch_through(page, timeout_ms: int = 30_000) -> None:
    """Play the animation to its end (Confirm opens only after that) and wait for it."""
    settle(page)  # the player of this trial, not the one of the run before
    page.get_by_test_id("picker-play").click()
    page.wait_for_selector("[data-testid=picker-confirm]:enabled", timeout=timeout_ms)
    page.wait_for_selector(".snap-picker video", timeout=timeout_ms)
    video = page.locator(".snap-picker video").element_handle()
    page.wait_for_function("v => v.paused", arg=video, timeout=timeout_ms)  # at the end


def shown_frame(page) -> int:
    """The 0-based video frame the picker says is on screen ("Frame k / n" is 1-based)."""
    m = re.match(r"Frame (\d+) / (\d+)", page.get_by_test_id("picker-frame").inner_text())
    return int(m.group(1)) - 1


def frame_images(stimuli_dir, scene: str):
    """The scene's pickable frames as grey-level arrays, shape (K, H, W)."""
    import numpy as np
    from PIL import Image

    sc = load_stimuli(stimuli_dir, verify=False).scenes[scene]
    return np.stack([np.asarray(Image.open(f).convert("L"), dtype=float) for f in sc.frames])


def frame_on_screen_matches(page, stimuli_dir, scene: str, frame: int) -> None:
    """The video element shows stimulus frame ``frame``: among all the scene's frame images,
    the one that best matches the pixels on screen looks like ``frame`` (equal up to
    compression noise: consecutive frames of a still moment may be alike)."""
    import io

    import numpy as np
    from PIL import Image

    refs = frame_images(stimuli_dir, scene)
    png = page.locator(".snap-video").screenshot()
    img = Image.open(io.BytesIO(png)).convert("L").resize(refs.shape[2:0:-1])
    err = np.abs(refs - np.asarray(img, dtype=float)).mean(axis=(1, 2))
    assert err[frame] - err.min() < 1.0, (frame, int(err.argmin()), err.round(2).tolist())


def moving_frame(stimuli_dir, scene: str) -> int:
    """A frame that differs clearly from both neighbours (where an off-by-one would show)."""
    import numpy as np

    f = frame_images(stimuli_dir, scene)
    d = np.abs(np.diff(f, axis=0)).mean(axis=(1, 2))  # change between k and k+1
    both = np.minimum(d[:-1], d[1:])  # frame k+1 against k and k+2
    return int(np.argmax(both)) + 1


def test_participant_session_in_browser(server, page, artifacts, stimuli_dir):
    """A participant clicks through every page; the database holds exactly their answers."""
    base, store = server
    n_before = store.progress()["participants"]
    page.goto(f"{base}/?PROLIFIC_PID=60a1b2c3d4e5f60718293a4b&STUDY_ID=st1&SESSION_ID=se1")
    heading(page, "Tiny demo")
    shot(page, artifacts, "01-consent")
    pid = agree_and_start(page)
    answer_background(page)
    shot(page, artifacts, "02-background")
    page.get_by_role("button", name="Continue").click()
    heading(page, "Animation 1 of 2")

    part = store.get_participant(pid)
    assert part["background"] == {
        "age_band": "35–44",
        "gender": "Prefer not to say",
        "experience": "Some (a course or a hobby)",
    }
    assert part["prolific_pid"] == "60a1b2c3d4e5f60718293a4b"
    plan = trial_plan(["jump", "push"], part["seed"])
    stim = load_stimuli(stimuli_dir)
    n_first = stim.scenes[plan[0].scene].n_video_frames

    # Pose task 1: watch it through once, play, pause, step forward three frames and
    # back one, confirm.
    picker_ready(page)
    watch_through(page)
    page.get_by_test_id("picker-play").click()  # from the start again
    video = page.locator(".snap-picker video").element_handle()
    page.wait_for_function("v => !v.paused && v.currentTime > 0.3", arg=video)  # it plays
    page.get_by_test_id("picker-play").click()  # pause, some frames in
    video_settled(page)
    paused = shown_frame(page)
    for _ in range(3):
        page.get_by_test_id("picker-forward").click()
    page.get_by_test_id("picker-back").click()
    video_settled(page)
    first = shown_frame(page)
    assert first == min(paused + 3, n_first - 1) - 1
    frame_on_screen_matches(page, stimuli_dir, plan[0].scene, first)
    shot(page, artifacts, "03-pose-task")
    page.get_by_test_id("picker-confirm").click()
    heading(page, "Animation 2 of 2")
    assert store.answered_trials(pid) == {0}

    # Reload in the middle: the same participant resumes at the first unanswered trial.
    page.reload()
    heading(page, "Animation 2 of 2")
    picker_ready(page)
    shot(page, artifacts, "04-pose-task-after-reload")

    # Pose task 2: watch, scrub to a frame with the slider, confirm.
    watch_through(page)
    scrub = page.get_by_test_id("picker-scrub")
    target = moving_frame(stimuli_dir, plan[1].scene)
    scrub.fill(str(target))  # the range input's value (0-based frame)
    video_settled(page)
    second = shown_frame(page)
    assert second == target
    frame_on_screen_matches(page, stimuli_dir, plan[1].scene, second)
    with pytest.raises(AssertionError):  # the check can tell neighbours apart here
        frame_on_screen_matches(page, stimuli_dir, plan[1].scene, second + 1)
    page.get_by_test_id("picker-confirm").click()

    # View tasks: pick position 2, then position 0.
    heading(page, "Pictures 1 of 2")
    page.wait_for_selector(".snap-view img", timeout=30_000)
    shot(page, artifacts, "05-view-task")
    page.get_by_test_id("view-choose-2").click()
    heading(page, "Pictures 2 of 2")
    settle(page)  # the previous trial's chooser is gone
    page.wait_for_selector(".snap-view img", timeout=30_000)
    page.get_by_test_id("view-choose-0").click()

    heading(page, "One more question")
    wait_until_answerable(store, pid, 4, stim.study.min_answer_s)
    page.get_by_test_id("stRadioGroup").get_by_text("A purple circle").click()
    shot(page, artifacts, "06-attention")
    page.get_by_role("button", name="Continue").click()
    heading(page, "Thank you!")
    shot(page, artifacts, "07-done")
    code = completion_code(page)

    rows = store.responses(pid)
    assert [r["trial_index"] for r in rows] == [0, 1, 2, 3, 4]
    assert [(r["task"], r["scene"]) for r in rows] == [(t.task, t.scene) for t in plan]
    # stored: the video frame on screen, and the motion frame the manifest maps it to
    for row, v in ((rows[0], first), (rows[1], second)):
        sc = stim.scenes[row["scene"]]
        assert (row["chosen_video_frame"], row["chosen_frame"]) == (v, sc.video_to_motion[v])
        assert row["algorithm_frame"] == sc.algorithm_frame and row["fps"] == sc.fps
    assert (rows[2]["chosen_position"], rows[2]["chosen_method"]) == (2, plan[2].shown_order[2])
    assert (rows[3]["chosen_position"], rows[3]["chosen_method"]) == (0, plan[3].shown_order[0])
    assert rows[2]["shown_order"] == list(plan[2].shown_order)
    assert rows[4]["chosen_value"] == "A purple circle" and rows[4]["correct"] is True
    assert all(r["prolific_pid"] == "60a1b2c3d4e5f60718293a4b" for r in rows)
    assert all(r["response_time_s"] > 0 for r in rows)
    # ("watch" entries, the frames watched every 2 s of play, come and go with timing)
    kinds = [e["kind"] for e in store.events(pid) if e["trial_index"] == 0 and e["kind"] != "watch"]
    # the server's "shown" (the response time counts from it), then the picker's log:
    # the play-through, then play, pause, four steps, the choice
    assert (
        kinds[:4] == ["shown", "play", "ended", "play"]
        and "pause" in kinds
        and kinds.count("step") == 4
        and kinds[-1] == "select"
    )
    shown = [e["trial_index"] for e in store.events(pid) if e["kind"] == "shown"]
    assert shown == [t.index for t in plan]  # each trial once, though pages rerun
    part = store.get_participant(pid)
    assert part["completion_code"] == code and part["completed_at"] is not None
    assert store.progress()["participants"] == n_before + 1


def test_tampering_is_refused_and_writes_nothing(server, page, artifacts):
    """Unknown id in the URL, an out-of-range frame and a forged position: message, no rows."""
    base, store = server
    n_before = store.progress()["participants"]
    page.goto(f"{base}/?pid=AAAAAAAAAAAAAAAAAAAAAA")
    heading(page, "This link does not work")
    shot(page, artifacts, "08-unknown-participant")
    assert "not known" in page.locator("[data-testid=stAlert]").inner_text()
    assert store.progress()["participants"] == n_before

    page.goto(f"{base}/")
    pid = agree_and_start(page)
    answer_background(page)
    page.get_by_role("button", name="Continue").click()
    heading(page, "Animation 1 of 2")
    picker = page.locator(".snap-picker")
    picker_ready(page)
    watch_through(page)
    # What a participant could do in the developer tools: send a frame past the end.
    picker.evaluate("root => { root._snap.frame = 999; }")
    page.get_by_test_id("picker-confirm").click()
    alert = page.locator("[data-testid=stAlert]")
    alert.wait_for()
    assert "outside this video" in alert.inner_text()
    shot(page, artifacts, "09-out-of-range-frame")
    # no answer and no choice logged (the play-through log was sent as it happened)
    assert store.answered_trials(pid) == set()
    assert "select" not in [e["kind"] for e in store.events(pid)]

    for title in ("Animation 2 of 2", "Pictures 1 of 2"):  # honest answers
        picker_ready(page)
        watch_through(page)
        page.get_by_test_id("picker-confirm").click()
        heading(page, title)
    heading(page, "Pictures 1 of 2")
    page.wait_for_selector(".snap-view img")
    # The page knows positions only; send one that does not exist.
    page.locator(".snap-views").evaluate(
        "root => root._api.setTriggerValue('choice', {trial: 2, position: 7})"
    )
    alert = page.locator("[data-testid=stAlert]")
    alert.wait_for()
    assert "position 7 does not exist" in alert.inner_text()
    shot(page, artifacts, "10-forged-position")
    assert store.answered_trials(pid) == {0, 1}
    assert store.progress()["participants"] == n_before + 1


def test_researcher_page_needs_token(server, page, artifacts):
    """Without the right token the researcher page shows no data; with it, live counts."""
    base, store = server
    page.goto(f"{base}/researcher")
    heading(page, "Researcher")
    settle(page)
    assert page.locator("[data-testid=stMetric]").count() == 0
    field = page.get_by_label("Access token")
    field.fill("not-the-token")
    field.press("Enter")
    page.get_by_text("Wrong token.").wait_for()
    assert page.locator("[data-testid=stMetric]").count() == 0
    shot(page, artifacts, "11-researcher-locked")
    field.fill(TOKEN)
    field.press("Enter")
    page.locator("[data-testid=stMetric]").first.wait_for(timeout=60_000)
    page.get_by_text("Votes per method").wait_for(timeout=60_000)
    shot(page, artifacts, "12-researcher")
    metrics = page.locator("[data-testid=stMetric]").all_inner_texts()
    expected = store.progress()["participants"]
    assert any(t.startswith("Participants") and t.split()[-1] == str(expected) for t in metrics)


def test_altered_stimuli_refused_before_serving(stimuli_dir, tmp_path):
    """`snapshot study` on a folder with an altered or missing file exits 2 naming it."""
    bad = tmp_path / "stimuli"
    shutil.copytree(stimuli_dir, bad)
    (bad / "jump" / "video.mp4").write_bytes(b"not a video")
    r = subprocess.run(
        [SNAPSHOT, "study", "--stimuli", str(bad), "--port", str(free_port())],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert r.returncode == 2
    assert "jump/video.mp4 has been altered" in r.stderr and "Traceback" not in r.stderr
    (bad / "jump" / "video.mp4").unlink()
    r = subprocess.run(
        [SNAPSHOT, "study", "--stimuli", str(bad), "--port", str(free_port())],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert r.returncode == 2 and "jump/video.mp4 is missing" in r.stderr
