"""The study under faults (issue 29), in Chromium, with the database checked after each:
a picture that fails to load (once, then for good), a video that fails (once, then for
good), the connection cut across a click (a TCP proxy the test controls sits between
the browser and the server), the server restarted mid-study, and the stimuli rebuilt
mid-study. After each: no answer recorded for something not seen, none lost, none
duplicated, no traceback, no frozen control.

One server for the module (behind the proxy; restarted by one test), on its own copy of
the tiny stimuli published as a content-addressed set; one Chromium.
"""

from __future__ import annotations

import hashlib
import json
import re
import shutil
import socket
import threading
import time

import pytest
import test_e2e
from app_helpers import tiny_demo_stimuli
from test_e2e import heading, picker_ready, settle, start_study, stop_process, watch_through

from study_app.design.build import publish_set
from study_app.design.stimuli import load_stimuli, sha256_file

pytestmark = [pytest.mark.browser, pytest.mark.slow]

playwright_api = test_e2e.playwright_api
browser = test_e2e.browser
#: The stimulus videos' URLs (H.264 and WebM), retries' queries included.
VIDEO = re.compile(r".*/media/[^/?]*\.(mp4|webm)(\?.*)?$")
#: The candidate pictures' URLs, retries' queries included.
PICTURE = re.compile(r".*/media/[^/?]*\.png(\?.*)?$")
BACKGROUND = {"age_band": "35–44", "gender": "Prefer not to say", "experience": "No experience"}


class CutProxy:
    """A TCP proxy on a free local port to ``upstream``: :meth:`cut` drops every open
    connection and refuses new ones until :meth:`restore` (optionally to a new port)."""

    def __init__(self, upstream: int):
        self.upstream = upstream
        self.open = True
        self.socks: set[socket.socket] = set()
        self.lock = threading.Lock()
        self.server = socket.create_server(("127.0.0.1", 0))
        self.port = self.server.getsockname()[1]
        threading.Thread(target=self._accept, daemon=True).start()

    def _accept(self) -> None:
        while True:
            try:
                client, _ = self.server.accept()
            except OSError:
                return
            if not self.open:
                client.close()
                continue
            try:
                up = socket.create_connection(("127.0.0.1", self.upstream), timeout=5)
                up.settimeout(None)
            except OSError:
                client.close()
                continue
            with self.lock:
                self.socks |= {client, up}
            for a, b in ((client, up), (up, client)):
                threading.Thread(target=self._pump, args=(a, b), daemon=True).start()

    def _pump(self, a: socket.socket, b: socket.socket) -> None:
        try:
            while data := a.recv(65536):
                b.sendall(data)
        except OSError:
            pass
        finally:
            for s in (a, b):
                try:
                    s.shutdown(socket.SHUT_RDWR)
                except OSError:
                    pass
                s.close()
            with self.lock:
                self.socks -= {a, b}

    def cut(self) -> None:
        self.open = False
        with self.lock:
            socks = list(self.socks)
        for s in socks:
            try:
                s.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass

    def restore(self, upstream: int | None = None) -> None:
        if upstream is not None:
            self.upstream = upstream
        self.open = True

    def close(self) -> None:
        self.cut()
        self.server.close()


@pytest.fixture(scope="module")
def study(tmp_path_factory, playwright_api):
    """The server behind a proxy, on a private set of the tiny stimuli: a dict with the
    proxy, base url, store, the link folder, db url, log path and the server process."""
    from study_app.data.store import Store

    built, r = tiny_demo_stimuli(tmp_path_factory)
    if r is not None:
        assert r.returncode == 0, r.stderr
    root = tmp_path_factory.mktemp("faults")
    shutil.copytree(built.resolve(), root / "build1")
    link = root / "stimuli"
    publish_set(root / "build1", link)
    db = f"sqlite:///{root / 'study.db'}"
    log_path = root / "server.log"
    proc, base = start_study(link, db, log_path)
    proxy = CutProxy(int(base.rsplit(":", 1)[1]))
    env = {
        "proxy": proxy,
        "base": f"http://127.0.0.1:{proxy.port}",
        "store": Store(db),
        "link": link,
        "db": db,
        "log": log_path,
        "proc": proc,
        "root": root,
    }
    yield env
    env["store"].close()
    proxy.close()
    stop_process(env["proc"])


def seeded(study, *, answered: int = 0) -> str:
    """A participant past consent and background with the first ``answered`` trials
    answered (through the logic layer); their browser opens ``?pid=`` at the next."""
    from study_app.session import ParticipantSession

    store = study["store"]
    s = ParticipantSession.start(store, load_stimuli(study["link"], verify=False))
    s.submit_background(BACKGROUND)
    for t in s.plan[:answered]:
        if t.task == "pose":
            s.submit_pose(t.index, 0, response_time_s=5.0, watched=1.0)
        else:
            s.submit_view(t.index, 0, response_time_s=5.0)
    return s.participant_id


def open_page(browser, study, pid: str, *, width=1366, height=768):
    ctx = browser.new_context(viewport={"width": width, "height": height})
    page = ctx.new_page()
    page.set_default_timeout(30_000)
    page.goto(f"{study['base']}/?pid={pid}")
    return page


def no_traceback(page, study) -> None:
    assert page.locator("[data-testid=stException]").count() == 0
    assert "Traceback" not in page.inner_text("body")
    assert "Traceback" not in study["log"].read_text()


def one_answer_each(store, pid: str) -> list[dict]:
    rows = store.responses(pid)
    idx = [r["trial_index"] for r in rows]
    assert len(idx) == len(set(idx)), idx  # none duplicated
    return rows


def wait_rows(store, pid: str, n: int, timeout_s: float = 30) -> list[dict]:
    deadline = time.monotonic() + timeout_s
    while len(store.responses(pid)) < n:
        assert time.monotonic() < deadline, store.responses(pid)
        time.sleep(0.2)
    return one_answer_each(store, pid)


def until(locator, js: str, timeout_s: float = 30.0) -> None:
    """Wait until ``js`` (a function of the element) is true (locators pierce shadow DOM)."""
    deadline = time.monotonic() + timeout_s
    while not locator.evaluate(js):
        assert time.monotonic() < deadline, f"timed out waiting for {js}"
        time.sleep(0.1)


def failing(page, pattern: str, times: int | None):
    """Abort the first ``times`` requests matching ``pattern`` (all when None); returns
    the list of aborted URLs."""
    aborted = []

    def handle(route):
        if times is None or len(aborted) < times:
            aborted.append(route.request.url)
            route.abort("connectionreset")
        else:
            route.continue_()

    page.route(pattern, handle)
    return aborted


# ----------------------------------------------------------------------------- item 1
def test_picture_failing_once_is_retried_then_answered(study, browser):
    """A candidate whose first request fails is loaded again: the chooser opens with
    every picture loaded, and the answer is an ordinary one."""
    pid = seeded(study, answered=2)
    page = open_page(browser, study, pid)
    aborted = failing(page, PICTURE, 1)
    page.reload()
    heading(page, "Pictures 1 of 2")
    page.wait_for_selector(".snap-views[data-ready='1']")
    assert len(aborted) == 1
    assert page.locator(".snap-views").get_attribute("data-loaded") == "3"
    page.get_by_test_id("view-choose-1").click()
    heading(page, "Pictures 2 of 2")
    rows = wait_rows(study["store"], pid, 3)
    assert rows[2]["chosen_position"] == 1
    no_traceback(page, study)
    page.context.close()


def test_picture_failing_for_good_answers_nothing_until_it_loads(study, browser):
    """A candidate that never loads keeps every Choose off and says so (Try again);
    nothing is stored but a media_failed event; once it loads, one answer."""
    pid = seeded(study, answered=2)
    page = open_page(browser, study, pid)
    first = []

    def handle(route):  # the first picture on screen fails, whatever is asked again
        if not first:
            first.append(route.request.url.split("?")[0])
        if route.request.url.split("?")[0] == first[0]:
            route.abort("connectionreset")
        else:
            route.continue_()

    page.route(PICTURE, handle)
    page.reload()
    heading(page, "Pictures 1 of 2")
    error = page.get_by_test_id("views-error")
    error.wait_for(state="visible")
    assert "could not be loaded" in error.inner_text()
    for i in range(3):
        assert page.get_by_test_id(f"view-choose-{i}").is_disabled()
    store = study["store"]
    deadline = time.monotonic() + 15
    while not [e for e in store.events(pid) if e["kind"] == "media_failed"]:
        assert time.monotonic() < deadline, store.events(pid)
        time.sleep(0.2)
    page.get_by_test_id("view-choose-0").click(force=True)  # a click on a closed button
    assert len(store.responses(pid)) == 2  # nothing answered for what was not seen
    page.unroute(PICTURE)
    page.get_by_test_id("views-retry").click()
    page.wait_for_selector(".snap-views[data-ready='1']")
    page.get_by_test_id("view-choose-2").click()
    heading(page, "Pictures 2 of 2")
    rows = wait_rows(store, pid, 3)
    assert rows[2]["chosen_position"] == 2
    (ev,) = [e for e in store.events(pid) if e["kind"] == "media_failed"]
    assert ev["trial_index"] == 2 and ev["payload"]["what"] == "image"
    no_traceback(page, study)
    page.context.close()


# ----------------------------------------------------------------------------- item 2
def test_video_failing_once_plays_and_for_good_falls_back_for_that_trial(study, browser):
    """A video whose first request fails is loaded again and plays; one that never
    loads turns this trial (only) to the frame slider, and its answer says "slider"
    with nothing watched; the next trial has the player again."""
    pid = seeded(study)
    page = open_page(browser, study, pid)
    aborted = failing(page, VIDEO, 1)
    page.reload()
    heading(page, "Animation 1 of 2")
    picker_ready(page)
    assert len(aborted) == 1 and page.get_by_test_id("picker-play").is_visible()
    page.unroute(VIDEO)
    failing(page, VIDEO, None)
    page.reload()
    heading(page, "Animation 1 of 2")
    slider = page.get_by_role("slider", name="Frame")
    slider.wait_for()
    assert "slider" in page.inner_text("body")
    page.unroute(VIDEO)
    slider.focus()
    for _ in range(4):
        page.keyboard.press("ArrowRight")
    settle(page)
    page.get_by_role("button", name="Confirm this frame").click()
    heading(page, "Animation 2 of 2")
    picker_ready(page)  # the player again
    (row,) = wait_rows(study["store"], pid, 1)
    assert row["picked_with"] == "slider" and row["watched"] is None
    assert row["chosen_video_frame"] == 4
    kinds = [e["kind"] for e in study["store"].events(pid) if e["trial_index"] == 0]
    assert kinds.count("media_failed") == 1
    watch_through(page)
    page.get_by_test_id("picker-confirm").click()
    heading(page, "Pictures 1 of 2")
    rows = wait_rows(study["store"], pid, 2)
    assert rows[1]["picked_with"] == "player" and rows[1]["watched"] >= 0.9
    assert rows[1]["viewport_width"] == 1366 and rows[1]["input_type"] == "mouse"
    assert rows[1]["tab_id"] and 0 < rows[1]["active_time_s"] <= rows[1]["response_time_s"]
    no_traceback(page, study)
    page.context.close()


# ----------------------------------------------------------------------------- item 6
def test_watching_is_kept_across_a_reload(study, browser):
    """Half watched, reload, the rest watched: Confirm opens without starting over."""
    pid = seeded(study)
    page = open_page(browser, study, pid)
    heading(page, "Animation 1 of 2")
    picker_ready(page)
    settle(page)
    video = page.get_by_test_id("picker-video")
    page.get_by_test_id("picker-play").click()
    until(page.locator(".snap-picker"), "r => Number(r.dataset.watched) >= 0.5")
    video.evaluate("v => v.pause()")
    store = study["store"]
    deadline = time.monotonic() + 15
    while not any((e["payload"] or {}).get("ranges") for e in store.events(pid)):
        assert time.monotonic() < deadline, store.events(pid)
        time.sleep(0.2)
    stored = max(
        sum(b - a for a, b in (e["payload"] or {}).get("ranges", [])) for e in store.events(pid)
    )
    page.reload()
    heading(page, "Animation 1 of 2")
    picker_ready(page)
    settle(page)
    # Seek to where the stored ranges end, play the rest: enough with what was kept.
    end = int(stored) + 1
    picker = page.locator(".snap-picker")
    n = int(picker.evaluate("r => r.querySelector('.snap-scrub').max")) + 1
    assert end < n * 0.9  # the rest alone would not open Confirm
    picker.evaluate(
        f"r => {{ const s = r.querySelector('.snap-scrub'); s.value = '{end}'; "
        "s.dispatchEvent(new Event('input')); }"
    )
    page.get_by_test_id("picker-play").click()
    page.wait_for_selector("[data-testid=picker-confirm]:enabled", timeout=30_000)
    page.get_by_test_id("picker-confirm").click()
    heading(page, "Animation 2 of 2")
    (row,) = wait_rows(store, pid, 1)
    assert row["watched"] >= 0.9
    page.context.close()


# ----------------------------------------------------------------------------- item 5
def test_connection_cut_across_a_click(study, browser):
    """Confirm pressed while the connection is down: the answer is sent again when it
    is back (stored once) or Confirm opens again saying nothing was saved; never a
    frozen "Saving…"."""
    pid = seeded(study)
    page = open_page(browser, study, pid)
    heading(page, "Animation 1 of 2")
    picker_ready(page)
    watch_through(page)
    proxy = study["proxy"]
    proxy.cut()
    page.get_by_test_id("picker-confirm").click()
    assert len(study["store"].responses(pid)) == 0
    page.wait_for_timeout(1500)  # the connection stays down across the click
    proxy.restore()
    _answered_or_told(page, "Animation 2 of 2")
    (row,) = wait_rows(study["store"], pid, 1)
    assert row["trial_index"] == 0
    no_traceback(page, study)
    page.context.close()


def _answered_or_told(page, next_heading: str) -> None:
    """The page moves on, or says the answer was not saved with Confirm open (then it is
    pressed again); fails if neither happens (a frozen control)."""
    page.wait_for_function(
        "(h) => [...document.querySelectorAll('h1,h2,h3')].some(e => e.innerText.includes(h))"
        " || [...document.querySelectorAll('*')].some(e => e.shadowRoot && "
        "e.shadowRoot.querySelector('.snap-picker[data-lost=\"1\"]'))",
        arg=next_heading,
        timeout=60_000,
    )
    lost = page.locator(".snap-picker[data-lost='1']")
    if lost.count():
        assert "not saved" in page.get_by_test_id("picker-error").inner_text()
        page.get_by_test_id("picker-confirm").click()
    heading(page, next_heading)


def test_server_restart_mid_study(study, browser, playwright_api):
    """The server restarts while a Confirm is on its way: the participant goes on with
    the same stimuli, the answer is stored once, no traceback."""
    pid = seeded(study, answered=1)
    page = open_page(browser, study, pid)
    heading(page, "Animation 2 of 2")
    picker_ready(page)
    watch_through(page)
    proxy = study["proxy"]
    proxy.cut()
    stop_process(study["proc"])
    page.get_by_test_id("picker-confirm").click()
    proc, base = start_study(study["link"], study["db"], study["log"])
    study["proc"] = proc
    proxy.restore(int(base.rsplit(":", 1)[1]))
    _answered_or_told(page, "Pictures 1 of 2")
    rows = wait_rows(study["store"], pid, 2)
    assert rows[1]["trial_index"] == 1
    no_traceback(page, study)
    page.context.close()


# ----------------------------------------------------------------------------- items 3, 4
def test_stimuli_rebuilt_mid_study(study, browser):
    """A rebuild with a changed picture while a participant is mid-study: the running
    server keeps serving the set it started with; after a restart the participant
    resumes on that set (the pictures they were shown, their answers against its
    manifest), and a new participant gets the new set."""
    store = study["store"]
    link = study["link"]
    old = load_stimuli(link)
    pid = seeded(study, answered=2)
    page = open_page(browser, study, pid)
    heading(page, "Pictures 1 of 2")
    page.wait_for_selector(".snap-views[data-ready='1']")
    shown = _picture_digests(page)
    # The rebuild: the same study with one candidate picture changed.
    new_build = study["root"] / "build2"
    shutil.copytree(old.folder, new_build)
    changed = next(iter(old.scenes.values())).views["ours"].relative_to(old.folder)
    from PIL import Image

    Image.new("RGB", (160, 120), (0, 200, 0)).save(new_build / changed)
    m = json.loads((new_build / "manifest.json").read_text())
    m["files"][changed.as_posix()] = sha256_file(new_build / changed)
    (new_build / "manifest.json").write_text(json.dumps(m))
    publish_set(new_build, link)
    new = load_stimuli(link)
    assert new.sha256 != old.sha256 and old.folder.is_dir()
    page.reload()  # the running server: still the set it started with
    heading(page, "Pictures 1 of 2")
    page.wait_for_selector(".snap-views[data-ready='1']")
    assert _picture_digests(page) == shown
    stop_process(study["proc"])
    proc, base = start_study(link, study["db"], study["log"])
    study["proc"] = proc
    study["proxy"].restore(int(base.rsplit(":", 1)[1]))
    page.reload()  # the restarted server: this participant's own set
    heading(page, "Pictures 1 of 2")
    page.wait_for_selector(".snap-views[data-ready='1']")
    assert _picture_digests(page) == shown
    page.get_by_test_id("view-choose-0").click()
    heading(page, "Pictures 2 of 2")
    rows = wait_rows(store, pid, 3)
    assert {r["manifest_sha256"] for r in rows} == {old.sha256}
    no_traceback(page, study)
    page.context.close()
    # the restarted server serves the new set to everyone else
    assert f"manifest {new.sha256[:12]}" in study["log"].read_text()


def _picture_digests(page) -> list[str]:
    """sha256 of each candidate picture the page shows, fetched from its own URL."""
    srcs = page.locator(".snap-views img").evaluate_all("imgs => imgs.map(i => i.src)")
    out = []
    for src in srcs:
        body = page.request.get(src).body()
        out.append(hashlib.sha256(body).hexdigest())
    return out


# ----------------------------------------------------------------------------- small items
def test_small_items(study, browser):
    """Deep addresses land on the participant's step without Streamlit's "Page not
    found"; Confirm is on screen at 683×384 (200% zoom) and on a landscape phone; the
    step buttons and the video have names; the live frame number is not re-announced
    on every frame of a play; the personal link has a copy button that copies it."""
    pid = seeded(study)
    ctx = browser.new_context(viewport={"width": 683, "height": 384})
    ctx.grant_permissions(["clipboard-read", "clipboard-write"], origin=study["base"])
    page = ctx.new_page()
    page.set_default_timeout(30_000)
    for path in ("study", "pose_task", f"done?pid={pid}"):
        page.goto(f"{study['base']}/{path}")
        heading(page, "Animation 1 of 2" if "pid" in path else "Tiny demo")
        settle(page)
        assert "Page not found" not in page.inner_text("body"), path
    assert f"pid={pid}" in page.url
    picker_ready(page)
    settle(page)
    for size in ({"width": 683, "height": 384}, {"width": 844, "height": 390}):
        page.set_viewport_size(size)
        page.evaluate("() => window.scrollTo(0, 0)")
        page.wait_for_function(f"() => window.innerHeight === {size['height']}")
        b = page.get_by_test_id("picker-confirm").bounding_box()
        assert b is not None and 0 <= b["y"] and b["y"] + b["height"] <= size["height"], (size, b)
    page.get_by_role("button", name="Previous frame").wait_for()
    page.get_by_role("button", name="Next frame").wait_for()
    assert page.get_by_test_id("picker-video").get_attribute("aria-label")
    live = page.get_by_test_id("picker-frame-live")
    assert live.get_attribute("aria-live") == "polite"
    assert page.get_by_test_id("picker-frame").get_attribute("aria-live") is None
    live.evaluate(
        "el => { window.__changes = 0; new MutationObserver(() => window.__changes++)"
        ".observe(el, {childList: true, characterData: true, subtree: true}); }"
    )
    video = page.get_by_test_id("picker-video")
    page.get_by_test_id("picker-play").click()
    until(video, "v => v.ended || (v.paused && v.currentTime > 0.5)")
    assert page.evaluate("() => window.__changes") <= 2  # the 24 frames played: not 24 times
    copy = page.get_by_test_id("copy-link")
    copy.scroll_into_view_if_needed()
    copy.click()
    until(copy, "b => b.dataset.done === '1'")
    assert page.evaluate("() => navigator.clipboard.readText()").endswith(f"/?pid={pid}")
    no_traceback(page, study)
    ctx.close()
