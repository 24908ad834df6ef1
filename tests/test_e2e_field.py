"""The study in the field (issue 14), in real browsers against one `snapshot study` server.

What participants did in the field and what it must leave in the database: a Prolific
id opened in two browsers, Back/Forward/Reload at every step and double clicks on every
button (one participant, one answer per trial, each for the trial on screen), a stale
second tab, odd Prolific ids, a reload in the middle of the frame picker, keyboard use,
the candidates' sizes and the controls' place at four widths, no method names in the
page and only the flow and the researcher page reachable. Firefox ESR (no H.264, a
video failing to load) is in ``test_e2e_firefox.py``. Screenshots of every page at
1366×768 and 390×844 go to ``var/test-artifacts/field/``.

One server for the module (started fresh, so the first test sees a first request), one
Chromium for every test.
"""

from __future__ import annotations

import re
import shutil
import time
from pathlib import Path

import pytest
import test_e2e
from app_helpers import tiny_demo_stimuli
from test_e2e import (
    REPO,
    TOKEN,
    after_resize,
    heading,
    picker_ready,
    settle,
    shown_frame,
    start_study,
    stop_process,
    video_settled,
    watch_through,
)

from snapcore.select.view_methods import VIEW_METHODS
from study_app.design.protocol import estimated_minutes, trial_plan
from study_app.design.stimuli import load_stimuli

pytestmark = [pytest.mark.browser, pytest.mark.slow]

ARTIFACTS = REPO / "var" / "test-artifacts" / "field"
#: Playwright's sync API, Chromium checked (the browser tests' fixture).
playwright_api = test_e2e.playwright_api
#: One headless Chromium for the module (the browser tests' fixture).
browser = test_e2e.browser
PROLIFIC = "PROLIFIC_PID={}&STUDY_ID=5f00aa11&SESSION_ID=s{}"
SCENES = ["jump", "push"]
#: Widths (and heights) the candidates are measured at.
SIZES = [(390, 844), (768, 1024), (1280, 720), (1366, 768)]


def ppid(n: int) -> str:
    """A well-formed, unique Prolific id (24 hex digits)."""
    return f"{n:024x}"


@pytest.fixture(scope="module")
def artifacts():
    if ARTIFACTS.exists():
        shutil.rmtree(ARTIFACTS)
    ARTIFACTS.mkdir(parents=True)
    return ARTIFACTS


@pytest.fixture(scope="module")
def server(tmp_path_factory, playwright_api):
    """A fresh `snapshot study` on the tiny stimuli: (base url, store, server log path)."""
    from study_app.data.store import Store

    stimuli, r = tiny_demo_stimuli(tmp_path_factory)
    if r is not None:
        assert r.returncode == 0, r.stderr
    db = f"sqlite:///{tmp_path_factory.mktemp('field-db') / 'study.db'}"
    log_path = tmp_path_factory.mktemp("field-log") / "server.log"
    proc, base = start_study(stimuli, db, log_path)
    store = Store(db)
    yield base, store, log_path, stimuli
    store.close()
    stop_process(proc)


def new_page(browser, width=1366, height=768):
    ctx = browser.new_context(viewport={"width": width, "height": height})
    pg = ctx.new_page()
    pg.set_default_timeout(20_000)
    return pg


def shot(page, name: str) -> None:
    settle(page)
    page.screenshot(path=str(ARTIFACTS / f"{name}.png"), full_page=False)


def pid_of(page) -> str:
    """The participant id in the address bar, once the app has written it there (after
    Back the browser shows the older address until the app's rerun replaces it)."""
    try:
        page.wait_for_url(re.compile(r"[?&]pid=[A-Za-z0-9_-]+"), timeout=10_000)
    except Exception:
        pass  # the assertion below names the address
    m = re.search(r"[?&]pid=([A-Za-z0-9_-]+)", page.url)
    assert m, page.url
    return m.group(1)


def consent(page, *, double: bool = False) -> str:
    from playwright.sync_api import expect

    page.get_by_text("I have read the information").click()
    start = page.get_by_role("button", name="Start the study")
    expect(start).to_be_enabled()
    start.dblclick() if double else start.click()
    heading(page, "About you")
    return pid_of(page)


def background(page, *, double: bool = False) -> None:
    settle(page)
    page.get_by_role("combobox", name="Your age").click()
    page.get_by_role("option", name="35–44").click()
    settle(page)
    page.get_by_text("Prefer not to say", exact=True).first.click()
    settle(page)
    page.get_by_text("Some (a course or a hobby)").click()
    settle(page)
    button = page.get_by_role("button", name="Continue")
    button.dblclick() if double else button.click()


def confirm_pose(page, *, double: bool = False) -> int:
    """Watch the animation through, confirm; return the video frame confirmed."""
    picker_ready(page)
    watch_through(page)
    frame = shown_frame(page)
    confirm = page.get_by_test_id("picker-confirm")
    confirm.dblclick() if double else confirm.click()
    return frame


def choose_view(page, position: int, *, double: bool = False) -> None:
    settle(page)  # the previous trial's chooser is gone
    page.wait_for_selector(".snap-views[data-ready='1']", timeout=30_000)
    b = page.get_by_test_id(f"view-choose-{position}")
    b.dblclick() if double else b.click()


def attention(page, *, double: bool = False) -> None:
    page.wait_for_timeout(1000)  # answers count only after the study's min_answer_s
    page.get_by_test_id("stRadioGroup").get_by_text("A purple circle").click()
    settle(page)
    b = page.get_by_role("button", name="Continue")
    b.dblclick() if double else b.click()


def seeded(server, *, poses_done: int = 0) -> str:
    """A participant registered through the logic layer (consent, background and the
    first ``poses_done`` pose tasks answered), for tests about a later page: their
    browser opens ``?pid=`` straight at it. Returns the participant id."""
    from study_app.session import ParticipantSession

    _, store, _, stimuli = server
    s = ParticipantSession.start(store, load_stimuli(stimuli, verify=False))
    s.submit_background(
        {"age_band": "35–44", "gender": "Prefer not to say", "experience": "No experience"}
    )
    for t in s.plan[:poses_done]:
        s.submit_pose(t.index, 0, response_time_s=5.0, watched=1.0)
    return s.participant_id


def all_html(page) -> str:
    """The page's HTML including every open shadow root (the components live there)."""
    return page.evaluate("""() => {
      const out = [];
      const walk = (node) => {
        if (node.shadowRoot) { out.push(node.shadowRoot.innerHTML); walk(node.shadowRoot); }
        for (const c of node.children || []) walk(c);
      };
      out.push(document.documentElement.outerHTML);
      walk(document.documentElement);
      return out.join('\\n');
    }""")


def store_stimuli(server) -> Path:
    """The stimuli folder the server serves (the tiny study, built once per session)."""
    return server[3]


def until(locator, js: str, timeout_s: float = 30.0) -> None:
    """Wait until ``js`` (a function of the element) is true; locators pierce shadow DOM."""
    deadline = time.monotonic() + timeout_s
    while not locator.evaluate(js):
        if time.monotonic() > deadline:
            state = locator.evaluate("e => JSON.stringify(e.dataset || {})")
            raise AssertionError(f"timed out waiting for {js} (element data: {state})")
        time.sleep(0.1)


def box(locator):
    b = locator.bounding_box()
    assert b is not None
    return b


# ----------------------------------------------------------------------------- item 14
def test_only_flow_and_researcher_reachable(server, browser):
    """First request /researcher on a fresh server, then /consent, /pose_task, /common and
    a page two folders deep (/pages/consent): no sidebar of internal modules, no blank
    page, no 404s; only flow and researcher."""
    from playwright.sync_api import expect

    base, store, *_ = server
    page = new_page(browser)
    bad, ok = [], []
    page.on("response", lambda r: (bad if r.status == 404 else ok).append(r.url))
    page.goto(f"{base}/researcher")
    heading(page, "Researcher")
    settle(page)
    assert page.locator("[data-testid=stSidebarNav]").count() == 0
    assert page.locator("[data-testid=stSidebar]").count() == 0
    for path in ("consent", "pose_task", "common", "invalid", "done", "pages/consent"):
        page.goto(f"{base}/{path}")
        heading(page, "Tiny demo")  # the study's first page, never a blank one
        settle(page)
        assert page.locator("[data-testid=stSidebarNav]").count() == 0
        expect(page.get_by_text("I have read the information")).to_have_count(1)
    # Streamlit's frontend guesses the app's base path from the address (is /consent a
    # page, or the app mounted at /consent?) and probes <path>/_stcore/health first:
    # those probes may 404 and fall back to the root. Nothing else may.
    probe = re.compile(re.escape(base) + r"/[a-z_]+/_stcore/(health|host-config)$")
    assert [u for u in bad if not probe.match(u)] == []
    assert f"{base}/_stcore/health" in ok
    assert store.progress()["participants"] == 0
    page.context.close()


# ----------------------------------------------------------------------------- items 1-3, 5, 11, screenshots
@pytest.mark.parametrize("size", [(1366, 768), (390, 844)], ids=["desktop", "phone"])
def test_prolific_participant_back_reload_double_clicks(server, browser, artifacts, size):
    """Back/Forward/Reload at every step (desktop run) and double clicks on every button
    (both): one participant, one answer per trial, each for the trial on screen; a
    second browser with the same Prolific link resumes that participant; every page
    photographed at both sizes."""
    base, store, *_ = server
    w, h = size
    tag = f"{w}x{h}"
    n = 1 if w > 1000 else 2
    link = f"{base}/?" + PROLIFIC.format(ppid(n), n)
    page = new_page(browser, w, h)
    page.goto(link)
    heading(page, "Tiny demo")
    # the duration on the consent page comes from the stimuli (item 15)
    stim = load_stimuli(store_stimuli(server), verify=False)
    minutes = estimated_minutes([sc.n_video_frames / sc.video_fps for sc in stim.scenes.values()])
    # the heading comes first and the page's text after it (Streamlit renders its
    # elements as they arrive): wait for the sentence, not only the heading
    from playwright.sync_api import expect

    expect(page.locator("body")).to_contain_text(
        f"It takes about {minutes} minutes.", timeout=30_000
    )
    shot(page, f"{tag}-01-consent")
    pid = consent(page, double=True)
    shot(page, f"{tag}-02-background")

    def back_forward_reload(title: str) -> None:
        if w < 1000:  # the desktop run does this at every step; the phone run photographs
            return
        # Back leaves nothing behind: the same participant at the same step.
        page.go_back()
        heading(page, title)
        settle(page)
        assert pid_of(page) == pid
        page.go_forward()
        heading(page, title)
        page.reload()
        heading(page, title)
        assert pid_of(page) == pid

    back_forward_reload("About you")
    background(page, double=True)
    heading(page, "Animation 1 of 2")
    back_forward_reload("Animation 1 of 2")
    part = store.get_participant(pid)
    plan = trial_plan(SCENES, part["seed"])

    picker_ready(page)
    confirm = page.get_by_test_id("picker-confirm")
    assert confirm.is_disabled()  # nothing watched yet (item 5)
    if w > 1000:  # item 11: the player and Confirm are above the fold
        for el in ("picker-video", "picker-play", "picker-confirm"):
            b = box(page.get_by_test_id(el))
            assert b["y"] >= 0 and b["y"] + b["height"] <= h, (el, b)
    shot(page, f"{tag}-03-pose-task")
    frames = [confirm_pose(page, double=True)]
    heading(page, "Animation 2 of 2")
    back_forward_reload("Animation 2 of 2")
    frames.append(confirm_pose(page, double=True))

    # A second browser, the same Prolific link: the same participant, where they are.
    other = new_page(browser)
    other.goto(link)
    heading(other, "Pictures 1 of 2")
    assert pid_of(other) == pid
    other.context.close()

    heading(page, "Pictures 1 of 2")
    back_forward_reload("Pictures 1 of 2")
    page.wait_for_selector(".snap-views[data-ready='1']", timeout=30_000)
    shot(page, f"{tag}-04-view-task")
    choose_view(page, 2, double=True)
    heading(page, "Pictures 2 of 2")
    back_forward_reload("Pictures 2 of 2")
    choose_view(page, 0, double=True)
    heading(page, "One more question")
    back_forward_reload("One more question")
    shot(page, f"{tag}-05-attention")
    attention(page, double=True)
    heading(page, "Thank you!")
    shot(page, f"{tag}-06-done")
    page.go_back()
    heading(page, "Thank you!")
    page.context.close()

    parts = [p for p in store.participants() if p["prolific_pid"] == ppid(n)]
    assert len(parts) == 1 and parts[0]["participant_id"] == pid
    rows = store.responses(pid)
    assert [r["trial_index"] for r in rows] == [t.index for t in plan]
    assert [(r["task"], r["scene"]) for r in rows] == [(t.task, t.scene) for t in plan]
    assert [r["chosen_video_frame"] for r in rows[:2]] == frames
    assert (rows[2]["chosen_position"], rows[2]["chosen_method"]) == (2, plan[2].shown_order[2])
    assert (rows[3]["chosen_position"], rows[3]["chosen_method"]) == (0, plan[3].shown_order[0])
    assert rows[4]["correct"] is True
    # no answer came sooner than the minimum time after its trial appeared (item 3)
    assert all(r["response_time_s"] >= 1.0 for r in rows), [r["response_time_s"] for r in rows]
    # how much was watched is stored with each choice (item 5)
    selects = [e for e in store.events(pid) if e["kind"] == "select"]
    assert [e["trial_index"] for e in selects] == [0, 1]
    assert all(e["payload"]["watched"] >= 0.9 for e in selects)
    shown = [e for e in store.events(pid) if e["kind"] == "shown"]
    assert [e["trial_index"] for e in shown] == [t.index for t in plan]
    # the minimum time each answer was held to is stored with the trial's start
    assert all(e["payload"] == {"min_answer_s": 1.0, "require_watch": True} for e in shown)


# ----------------------------------------------------------------------------- item 1 (link)
def test_resume_link_is_shown_and_works_elsewhere(server, browser):
    """The personal ?pid= link is on the page; opened in another browser it resumes."""
    base, store, *_ = server
    page = new_page(browser)
    page.goto(f"{base}/")
    pid = consent(page)
    code = page.locator("[data-testid=stCode]").last
    link = code.inner_text().strip()
    assert link.endswith(f"/?pid={pid}"), link
    other = new_page(browser, 390, 844)
    other.goto(link)
    heading(other, "About you")
    page.context.close()
    other.context.close()
    assert sum(p["participant_id"] == pid for p in store.participants()) == 1


# ----------------------------------------------------------------------------- item 4
def test_stale_second_tab_is_told(server, browser):
    """Two tabs on the same trial: the first answer is stored, the second tab is told."""
    base, store, *_ = server
    pid = seeded(server)
    a = new_page(browser)
    a.goto(f"{base}/?pid={pid}")
    heading(a, "Animation 1 of 2")
    b = a.context.new_page()
    b.goto(a.url)
    heading(b, "Animation 1 of 2")
    fa = confirm_pose(a)
    heading(a, "Animation 2 of 2")
    # Tab b still shows animation 1; whatever it sends now is about a step already
    # answered: it moves on, and says why.
    picker_ready(b)
    b.get_by_test_id("picker-play").click()
    heading(b, "Animation 2 of 2")
    alert = b.locator("[data-testid=stAlert]")
    alert.wait_for()
    assert "already been answered in another window" in alert.inner_text()
    (row,) = store.responses(pid)
    assert row["trial_index"] == 0 and row["chosen_video_frame"] == fa
    a.context.close()


# ----------------------------------------------------------------------------- item 6
@pytest.mark.parametrize(
    "value",
    ["a" * 65, "Ünïcødé5f1e2d3c", "<script>alert(1)</script>", "1' OR '1'='1"],
    ids=["65-chars", "unicode", "script", "sql"],
)
def test_odd_prolific_ids_refused(server, browser, value):
    """An odd PROLIFIC_PID: a clear message on the first page, nothing stored, logged."""
    from urllib.parse import quote

    base, store, log_path, _ = server
    n_before = len(store.participants())
    w, h = (390, 844) if value.startswith("1'") else (1366, 768)
    page = new_page(browser, w, h)
    page.goto(f"{base}/?PROLIFIC_PID={quote(value)}&STUDY_ID=x1&SESSION_ID=y1")
    heading(page, "This link does not work")
    text = page.locator("[data-testid=stAlert]").first.inner_text()
    assert "PROLIFIC_PID" in text and "not a valid Prolific value" in text
    assert page.get_by_text("I have read the information").count() == 0
    assert page.get_by_role("button", name="Start the study").count() == 0
    assert page.get_by_role("button", name="Start a new session").count() == 0
    if value.startswith(("<", "1'")):
        shot(page, f"{w}x{h}-07-invalid-link")
    page.context.close()
    assert len(store.participants()) == n_before
    assert "refused a study link with malformed Prolific parameters" in log_path.read_text()
    assert ascii(value)[:40] in log_path.read_text()


# ----------------------------------------------------------------------------- items 7, 13
def _at_first_pose_page(server, browser):
    """(page, store, pid): a seeded participant's browser on the first pose page, its
    player ready."""
    base, store, *_ = server
    pid = seeded(server)
    page = new_page(browser)
    page.goto(f"{base}/?pid={pid}")
    heading(page, "Animation 1 of 2")
    picker_ready(page)
    settle(page)
    return page, store, pid


def test_reload_keeps_player_and_keys_work(server, browser):
    """Keys work without clicking into the player; a reload keeps the frame and the log;
    Space on a focused Confirm confirms."""
    page, store, pid = _at_first_pose_page(server, browser)
    video_settled(page)
    picker = page.locator(".snap-picker")
    start = shown_frame(page)
    for _ in range(6):
        page.keyboard.press("ArrowRight")  # no click into the player first
    page.keyboard.press("ArrowLeft")
    until(picker, f"r => r.dataset.frame === '{start + 5}'", 10)
    page.keyboard.press(" ")  # Space plays
    video = page.get_by_test_id("picker-video")
    until(video, "v => !v.paused", 10)
    until(video, "v => v.ended || v.paused")
    # Played from frame 5 on: not yet the whole animation, so Confirm stays off ...
    assert page.get_by_test_id("picker-confirm").is_disabled()
    assert page.get_by_test_id("picker-hint").is_visible()
    page.keyboard.press(" ")  # ... until it was played from the start (Space replays)
    page.wait_for_selector("[data-testid=picker-confirm]:enabled", timeout=30_000)
    until(video, "v => v.ended || v.paused")
    for _ in range(3):
        page.keyboard.press("ArrowLeft")
    here = shown_frame(page)

    def kinds():
        return [e["kind"] for e in store.events(pid) if e["trial_index"] == 0]

    deadline = time.monotonic() + 20
    while kinds().count("step") < 10:  # the log goes out in batches, as it happens
        assert time.monotonic() < deadline, kinds()
        time.sleep(0.2)
    assert {"play", "ended", "step"} <= set(kinds()) and "select" not in kinds()
    page.reload()
    heading(page, "Animation 1 of 2")
    picker_ready(page)
    until(page.locator(".snap-picker"), f"r => r.dataset.frame === '{here}'", 10)  # restored
    page.set_viewport_size({"width": 1280, "height": 720})  # item 11 at the smaller size
    after_resize(page)
    for el in ("picker-video", "picker-play", "picker-confirm"):
        b = box(page.get_by_test_id(el))
        assert b["y"] >= 0 and b["y"] + b["height"] <= 720, (el, b)
    confirm = page.get_by_test_id("picker-confirm")
    page.wait_for_selector("[data-testid=picker-confirm]:enabled", timeout=10_000)
    confirm.focus()
    page.keyboard.press(" ")  # Space on Confirm confirms (it used to play)
    heading(page, "Animation 2 of 2")
    (row,) = store.responses(pid)
    assert row["chosen_video_frame"] == here
    assert kinds().count("step") == 10 and kinds()[-1] == "select"  # nothing lost on reload
    page.context.close()


def test_a_reload_right_after_clicks_loses_no_event(server, browser):
    """Steps taken less than the log's batching delay before a reload are kept in the tab
    and sent when the player is back: each stored once, and the player restored to the
    frame they reached."""
    page, store, pid = _at_first_pose_page(server, browser)
    start = shown_frame(page)
    for _ in range(3):
        page.keyboard.press("ArrowRight")
    page.reload()  # at once: the 0.8 s batch of these steps has not gone out

    def steps():
        return [e for e in store.events(pid) if e["trial_index"] == 0 and e["kind"] == "step"]

    heading(page, "Animation 1 of 2")
    picker_ready(page)
    deadline = time.monotonic() + 15
    while len(steps()) < 3:
        assert time.monotonic() < deadline, store.events(pid)
        time.sleep(0.2)
    until(page.locator(".snap-picker"), f"r => r.dataset.frame === '{start + 3}'", 10)
    page.wait_for_timeout(1500)  # nothing is sent twice
    assert len(steps()) == 3
    page.context.close()


# ----------------------------------------------------------------------------- items 8, 10, 11
def test_candidates_same_size_no_methods_in_page(server, browser, artifacts):
    """At 390, 768, 1280 and 1366 px the three candidates have the same rendered size,
    the page names no method, and at desktop sizes the Choose buttons are in view."""
    base, store, *_ = server
    pid = seeded(server, poses_done=1)
    page = new_page(browser)
    page.goto(f"{base}/?pid={pid}")
    heading(page, "Animation 2 of 2")
    html = all_html(page)
    confirm_pose(page)
    heading(page, "Pictures 1 of 2")
    page.wait_for_selector(".snap-views[data-ready='1']", timeout=30_000)
    for w, h in SIZES:
        page.set_viewport_size({"width": w, "height": h})
        after_resize(page)
        boxes = [box(page.get_by_test_id(f"view-image-{i}")) for i in range(3)]
        for b in boxes[1:]:
            assert (
                abs(b["width"] - boxes[0]["width"]) <= 1
                and abs(b["height"] - boxes[0]["height"]) <= 1
            ), (w, boxes)
        assert boxes[0]["width"] > 80, (w, boxes)
        if w >= 1280:
            for i in range(3):
                b = box(page.get_by_test_id(f"view-choose-{i}"))
                assert b["y"] + b["height"] <= h, (w, i, b)
        if (w, h) == (390, 844):
            shot(page, "390x844-04b-view-task-sizes")
    html += all_html(page)
    for word in (*VIEW_METHODS, "data-method", "view_ours", "entropy", "motion_area"):
        assert word not in html, word
    assert store.answered_trials(pid) == {0, 1}
    page.context.close()


# ----------------------------------------------------------------------------- researcher screenshots
def test_researcher_screenshots(server, browser, artifacts):
    """The researcher page at both sizes (locked and open)."""
    base, store, *_ = server
    for w, h in ((1366, 768), (390, 844)):
        page = new_page(browser, w, h)
        page.goto(f"{base}/researcher")
        heading(page, "Researcher")
        field = page.get_by_label("Access token")
        field.fill(TOKEN)
        field.press("Enter")
        page.locator("[data-testid=stMetric]").first.wait_for(timeout=60_000)
        shot(page, f"{w}x{h}-08-researcher")
        metrics = page.locator("[data-testid=stMetric]").all_inner_texts()
        n = store.progress()["participants"]
        assert any(t.startswith("Participants") and t.split()[-1] == str(n) for t in metrics)
        page.context.close()
