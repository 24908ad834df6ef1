"""Every answer fully described, and the player's fallbacks and zoom (issue 36, items
4-6), in Chromium (Playwright) and Firefox ESR (WebDriver BiDi), against one `snapshot
study` server on the tiny stimuli; the database is read after each scenario.

- Slider and attention answers carry the viewport, device pixel ratio, input type,
  active time and tab id, as player and view answers do.
- A video that fails (for good, or stalls midway) turns to the slider without any press
  of Play; the slider page says the video could not be played and keeps Confirm on
  screen at 1280×720, 1366×768 and on a phone; the row keeps what was watched.
- At 200% zoom (683×384 CSS px at 2 device px each) the animation is larger, in device
  pixels, than at 100% (512×384), and nothing covers it.
"""

from __future__ import annotations

import json
import re
import time

import pytest
import test_e2e
import test_e2e_field
from test_e2e import REPO, SETTLED, heading, picker_ready, settle
from test_e2e_firefox import DEEP, InterceptingBidi, ff_heading, ff_no_traceback, firefox

from study_app.design.stimuli import load_stimuli

pytestmark = [pytest.mark.browser, pytest.mark.slow]

playwright_api = test_e2e.playwright_api
browser = test_e2e.browser
#: A fresh `snapshot study` on the tiny stimuli: (base, store, log path, stimuli).
server = test_e2e_field.server
#: The stimulus videos' URLs (H.264 and WebM), retries' queries included.
VIDEO = re.compile(r".*/media/[^/?]*\.(mp4|webm)(\?.*)?$")
BACKGROUND = {"age_band": "35–44", "gender": "Prefer not to say", "experience": "No experience"}
#: Screenshots of the pages measured.
ARTIFACTS = REPO / "var" / "test-artifacts" / "described"
ARTIFACTS.mkdir(parents=True, exist_ok=True)
#: The client columns every answer must fill.
CLIENT = ("viewport_width", "viewport_height", "device_pixel_ratio", "input_type", "tab_id")


def seeded(server, *, answered: int = 0) -> tuple[str, list]:
    """A participant with background and the first ``answered`` trials answered (logic
    layer); their browser opens ``?pid=`` at the next. Returns (id, plan)."""
    from study_app.session import ParticipantSession

    _, store, _, stimuli = server
    s = ParticipantSession.start(store, load_stimuli(stimuli, verify=False))
    s.submit_background(BACKGROUND)
    for t in s.plan[:answered]:
        if t.task == "pose":
            s.submit_pose(t.index, 0, response_time_s=5.0, watched=1.0)
        else:
            s.submit_view(t.index, 0, response_time_s=5.0)
    return s.participant_id, s.plan


def rows_of(store, pid: str, n: int, timeout_s: float = 30.0) -> list[dict]:
    deadline = time.monotonic() + timeout_s
    while len(store.responses(pid)) < n:
        assert time.monotonic() < deadline, store.responses(pid)
        time.sleep(0.2)
    rows = store.responses(pid)
    assert len({r["trial_index"] for r in rows}) == len(rows) == n
    return rows


def described(row: dict, width: int, height: int, dpr: float = 1) -> None:
    """The row says what the answer was given on."""
    assert all(row[c] is not None for c in CLIENT), row
    assert (row["viewport_width"], row["viewport_height"]) == (width, height), row
    assert row["device_pixel_ratio"] == dpr and row["input_type"] in ("mouse", "touch")
    assert row["active_time_s"] is not None and 0 <= row["active_time_s"] <= row["response_time_s"]


def in_view(page, locator) -> bool:
    b = locator.bounding_box()
    h = page.evaluate("() => window.innerHeight")
    return b is not None and 0 <= b["y"] and b["y"] + b["height"] <= h


def no_traceback(page, log) -> None:
    assert page.locator("[data-testid=stException]").count() == 0
    assert "Traceback" not in page.inner_text("body") and "Traceback" not in log.read_text()


def test_video_failing_for_good_slider_page_and_described_answers(server, browser):
    """The video never loads: the slider page says so, its Confirm is on screen at
    1280×720, 1366×768 and 390×844, and the slider answer, like the attention answer at
    the end, carries every client column."""
    base, store, log, _ = server
    pid, plan = seeded(server)
    ctx = browser.new_context(viewport={"width": 1366, "height": 768})
    page = ctx.new_page()
    page.set_default_timeout(30_000)
    page.route(VIDEO, lambda route: route.abort("connectionreset"))
    page.goto(f"{base}/?pid={pid}")
    heading(page, "Animation 1 of 2")
    page.get_by_text("could not be played in your browser").wait_for(timeout=60_000)
    settle(page)
    confirm = page.get_by_test_id("slider-confirm")
    confirm.wait_for()
    for w, h in ((1280, 720), (1366, 768), (390, 844)):
        page.set_viewport_size({"width": w, "height": h})
        page.evaluate("() => window.scrollTo(0, 0)")
        page.wait_for_function(f"() => window.innerHeight === {h}")
        time.sleep(0.3)
        page.screenshot(path=str(ARTIFACTS / f"slider-{w}x{h}.png"))
        assert in_view(page, confirm), (w, h, confirm.bounding_box())
    page.set_viewport_size({"width": 1366, "height": 768})
    page.wait_for_function("() => window.innerHeight === 768")
    time.sleep(1.1)  # the study's min_answer_s
    confirm.click()
    heading(page, "Animation 2 of 2")
    (row,) = rows_of(store, pid, 1)
    assert row["picked_with"] == "slider" and row["watched"] is None  # nothing played
    described(row, 1366, 768)
    assert [e["kind"] for e in store.events(pid)].count("media_failed") == 1
    page.unroute(VIDEO)
    ctx.close()
    # The attention answer, at the end, is described too.
    pid, plan = seeded(server, answered=len(plan) - 1)
    ctx = browser.new_context(viewport={"width": 1280, "height": 720})
    page = ctx.new_page()
    page.goto(f"{base}/?pid={pid}")
    heading(page, "One more question")
    page.get_by_test_id("stRadioGroup").get_by_text("A purple circle").click()
    settle(page)
    time.sleep(1.1)
    page.get_by_role("button", name="Continue").click()
    heading(page, "Thank you!")
    row = rows_of(store, pid, len(plan))[-1]
    assert row["task"] == "attention" and row["correct"] is True
    described(row, 1280, 720)
    no_traceback(page, log)
    ctx.close()


def test_video_stalling_midway_turns_to_slider_and_keeps_watched(server, browser):
    """A video that stops loading midway while it plays (the picture frozen, the
    requests of its retries failing) turns to the slider with no press of Play after
    the first; the row keeps the share watched before it stopped."""
    base, store, log, _ = server
    pid, _ = seeded(server)
    ctx = browser.new_context(viewport={"width": 1366, "height": 768})
    page = ctx.new_page()
    page.set_default_timeout(30_000)
    page.goto(f"{base}/?pid={pid}")
    heading(page, "Animation 1 of 2")
    picker_ready(page)
    settle(page)
    video = page.get_by_test_id("picker-video")
    page.get_by_test_id("picker-play").click()
    deadline = time.monotonic() + 30
    while video.evaluate("v => v.currentTime") <= 0.4:
        assert time.monotonic() < deadline
        time.sleep(0.1)
    # The body stops arriving: the picture freezes while the video still plays, and
    # every request to load it again fails.
    page.route(VIDEO, lambda route: route.abort("connectionreset"))
    video.evaluate("v => { v.playbackRate = 0; }")
    started = time.monotonic()
    page.get_by_text("could not be played in your browser").wait_for(timeout=60_000)
    assert time.monotonic() - started < 30
    settle(page)
    confirm = page.get_by_test_id("slider-confirm")
    assert in_view(page, confirm)
    confirm.click()
    heading(page, "Animation 2 of 2")
    (row,) = rows_of(store, pid, 1)
    assert row["picked_with"] == "slider"
    assert row["watched"] is not None and 0 < row["watched"] < 0.9, row["watched"]
    described(row, 1366, 768)
    plays = [e for e in store.events(pid) if e["kind"] == "play"]
    assert len(plays) >= 1
    no_traceback(page, log)
    page.unroute(VIDEO)
    ctx.close()


def test_zoom_200_video_larger_and_uncovered(server, browser):
    """At 200% zoom (683×384 CSS px, 2 device px each) the animation is at least 512×384
    device px (its size at 100%) and the sticky controls cover none of it; Confirm is on
    screen."""
    base, store, log, _ = server
    pid, _ = seeded(server)
    sizes = {}
    for scale, vw, vh in ((1, 1366, 768), (2, 683, 384)):
        ctx = browser.new_context(viewport={"width": vw, "height": vh}, device_scale_factor=scale)
        page = ctx.new_page()
        page.set_default_timeout(30_000)
        page.goto(f"{base}/?pid={pid}")
        heading(page, "Animation 1 of 2")
        picker_ready(page)
        settle(page)
        video = page.get_by_test_id("picker-video")
        box = video.bounding_box()
        # The picture inside the element (object-fit: contain), in device pixels.
        aspect = video.evaluate("v => v.videoWidth / v.videoHeight")
        shown_w = min(box["width"], box["height"] * aspect)
        sizes[scale] = (shown_w * scale, shown_w / aspect * scale)
        if scale == 2:
            controls = page.locator(".snap-controls").bounding_box()
            assert box["y"] >= -1 and box["y"] + box["height"] <= controls["y"] + 0.5, (
                box,
                controls,
            )
            # Nothing drawn over the picture: the topmost element near its corners and at
            # its bottom edge is the video (asked in the component's shadow root).
            x0 = box["x"] + (box["width"] - shown_w) / 2
            for fx, fy in ((0.05, 0.05), (0.95, 0.95), (0.5, 0.98)):
                top = video.evaluate(
                    "(v, [x, y]) => { const e = v.getRootNode().elementFromPoint(x, y);"
                    " return e && e.tagName; }",
                    [x0 + fx * shown_w, box["y"] + fy * box["height"]],
                )
                assert top == "VIDEO", (fx, fy, top)
            assert in_view(page, page.get_by_test_id("picker-confirm"))
        ctx.close()
    assert sizes[2][0] >= sizes[1][0] - 1 and sizes[2][1] >= sizes[1][1] - 1, sizes


def test_firefox_esr_slider_and_attention_answers_described(server):
    """Firefox ESR, the video's requests failed by a WebDriver BiDi intercept: the slider
    page says the video could not be played, Confirm is on screen at 1280×720, and the
    slider and attention answers carry every client column."""
    base, store, log, _ = server
    pid, plan = seeded(server)
    video_url = re.compile(r"/media/[^/?]*\.(mp4|webm)(\?.*)?$")
    with firefox(InterceptingBidi, width=1280, height=720) as ff:
        ff.send("session.subscribe", {"events": ["network.beforeRequestSent"]})
        ff.send("network.setCacheBehavior", {"cacheBehavior": "bypass", "contexts": [ff.ctx]})
        ff.send("network.addIntercept", {"phases": ["beforeRequestSent"], "contexts": [ff.ctx]})
        ff.fail = lambda url: bool(video_url.search(url))
        ff.send(
            "browsingContext.navigate",
            {"context": ff.ctx, "url": f"{base}/?pid={pid}", "wait": "complete"},
        )
        ff_heading(ff, "Animation 1 of 2")
        ff.wait("document.body.innerText.includes('could not be played in your browser')", 60)
        ff.wait(f"({SETTLED})()")
        confirm = "(() => {" + DEEP + "return deep('[data-testid=slider-confirm]'); })()"
        ff.wait(f"!!{confirm}")
        ff.js("window.scrollTo(0, 0)")
        rect = json.loads(
            ff.js(
                f"(() => {{ const r = {confirm}.getBoundingClientRect();"
                " return JSON.stringify([r.top, r.bottom]); })()"
            )
        )
        assert 0 <= rect[0] and rect[1] <= 720, rect
        time.sleep(1.1)
        ff_press(ff, "(() => {" + DEEP + "return deep('[data-testid=slider-confirm]'); })()")
        ff_heading(ff, "Animation 2 of 2")
        (row,) = rows_of(store, pid, 1)
        assert row["picked_with"] == "slider"
        described(row, 1280, 720)
        ff_no_traceback(ff, log)
    pid, plan = seeded(server, answered=len(plan) - 1)
    with firefox(Bidi_plain(), width=1280, height=720) as ff:
        ff.send(
            "browsingContext.navigate",
            {"context": ff.ctx, "url": f"{base}/?pid={pid}", "wait": "complete"},
        )
        ff_heading(ff, "One more question")
        ff.wait(f"({SETTLED})()")
        radio = (
            "[...document.querySelectorAll('[data-testid=stRadioGroup] label')]"
            ".find(l => l.innerText.includes('A purple circle'))"
        )
        ff.wait(f"!!{radio}")
        ff.js(f"{radio}.querySelector('input').click()")
        ff.wait(f"{radio}.querySelector('input').checked")
        ff.wait(f"({SETTLED})()")
        time.sleep(1.1)
        ff_press(ff, "(() => {" + DEEP + "return deep('[data-testid=attention-submit]'); })()")
        ff_heading(ff, "Thank you!")
        row = rows_of(store, pid, len(plan))[-1]
        assert row["task"] == "attention"
        described(row, 1280, 720)
        ff_no_traceback(ff, log)


def test_firefox_esr_zoom_200_video_larger_and_uncovered(server):
    """Firefox ESR at 683×384 CSS px and 2 device px each (200% zoom): the animation is
    at least 512×384 device px and ends above the sticky controls."""
    base, store, log, _ = server
    pid, _ = seeded(server)
    with firefox(Bidi_plain(), width=683, height=384) as ff:
        ff.send(
            "browsingContext.setViewport",
            {"context": ff.ctx, "viewport": {"width": 683, "height": 384}, "devicePixelRatio": 2},
        )
        ff.send(
            "browsingContext.navigate",
            {"context": ff.ctx, "url": f"{base}/?pid={pid}", "wait": "complete"},
        )
        ff_heading(ff, "Animation 1 of 2")
        ready = (
            "(() => {"
            + DEEP
            + "const r = deep('.snap-picker'); return r && r.dataset.ready === '1'; })()"
        )
        ff.wait(ready, 60)
        ff.wait(f"({SETTLED})()")
        time.sleep(0.5)
        got = json.loads(
            ff.js(
                "(() => {" + DEEP + "const e = deep('video'); const v = e.getBoundingClientRect();"
                " const c = deep('.snap-controls').getBoundingClientRect();"
                " const a = e.videoWidth / e.videoHeight;"
                " return JSON.stringify([v.top, v.bottom, Math.min(v.width, v.height * a), a,"
                " c.top, window.devicePixelRatio]); })()"
            )
        )
        top, bottom, w, aspect, controls_top, dpr = got
        assert dpr == 2
        # The picture (object-fit: contain) at least its size at 100%: 512×384 device px.
        assert w * dpr >= 511 and w / aspect * dpr >= 383, got
        assert top >= -1 and bottom <= controls_top + 0.5, got
        ff_no_traceback(ff, log)


def ff_press(ff, expression: str) -> None:
    """A real mouse press (pointer move, down, up) on the element ``expression`` gives."""
    r = ff.send(
        "script.evaluate",
        {"expression": expression, "awaitPromise": False, "target": {"context": ff.ctx}},
    )
    element = {"sharedId": r["result"]["sharedId"]}
    actions = [
        {"type": "pointerMove", "x": 0, "y": 0, "origin": {"type": "element", "element": element}},
        {"type": "pointerDown", "button": 0},
        {"type": "pointerUp", "button": 0},
    ]
    ff.send(
        "input.performActions",
        {
            "context": ff.ctx,
            "actions": [
                {
                    "type": "pointer",
                    "id": "mouse",
                    "parameters": {"pointerType": "mouse"},
                    "actions": actions,
                }
            ],
        },
    )


def Bidi_plain():  # noqa: N802 - the plain client class, named as the field tests name it
    from test_e2e_firefox import Bidi

    return Bidi


def test_copy_button_says_when_it_could_not_copy(server, browser):
    """Item 7: when neither the clipboard API nor the old copy command copies the
    personal link, the button says so (it said "Copied")."""
    base, store, log, _ = server
    pid, _ = seeded(server)
    ctx = browser.new_context(viewport={"width": 1366, "height": 768})
    ctx.add_init_script(
        "navigator.clipboard.writeText = () => Promise.reject(new Error('denied'));"
        "document.execCommand = () => false;"
    )
    page = ctx.new_page()
    page.set_default_timeout(30_000)
    page.goto(f"{base}/?pid={pid}")
    heading(page, "Animation 1 of 2")
    settle(page)
    copy = page.get_by_test_id("copy-link")
    copy.scroll_into_view_if_needed()
    copy.click()
    deadline = time.monotonic() + 10
    while copy.evaluate("b => b.dataset.done") != "failed":
        assert time.monotonic() < deadline
        time.sleep(0.1)
    assert "Could not copy" in copy.inner_text() and "Copied" not in copy.inner_text()
    assert store.responses(pid) == []  # nothing answered by it
    no_traceback(page, log)
    ctx.close()
