"""The study in Firefox ESR (issue 14 item 12, issue 29), against one `snapshot study`
server: Firefox has no H.264, so the picker plays the WebM; a video that fails to load
(its requests failed through a WebDriver BiDi intercept) is retried, then answered on
the slider, and the database says so. Firefox is driven over WebDriver BiDi (its
built-in remote agent), one Firefox ESR per test. Screenshots go to
``var/test-artifacts/firefox/``. The Chromium field tests are in ``test_e2e_field.py``.
"""

from __future__ import annotations

import base64
import contextlib
import json
import os
import re
import shutil
import subprocess
import tempfile
import time
from pathlib import Path

import pytest
import test_e2e
import test_e2e_field
from conftest import need
from test_e2e import (
    REPO,
    SETTLED,
    free_port,
    stop_process,
)
from test_e2e_field import seeded

pytestmark = [pytest.mark.browser, pytest.mark.slow]

FIREFOX = "/usr/bin/firefox-esr"
ARTIFACTS = REPO / "var" / "test-artifacts" / "firefox"
#: Playwright's sync API, Chromium checked (the field tests' server fixture needs it).
playwright_api = test_e2e.playwright_api
#: A fresh `snapshot study` on the tiny stimuli (the field tests' fixture).
server = test_e2e_field.server


@pytest.fixture(scope="module")
def artifacts():
    if ARTIFACTS.exists():
        shutil.rmtree(ARTIFACTS)
    ARTIFACTS.mkdir(parents=True)
    return ARTIFACTS


# ----------------------------------------------------------------------------- item 12
class Bidi:
    """A minimal WebDriver BiDi client for Firefox (its built-in remote agent)."""

    def __init__(self, port: int):
        from websockets.sync.client import connect

        self._stack = contextlib.ExitStack()
        self.ws = self._stack.enter_context(
            connect(f"ws://127.0.0.1:{port}/session", max_size=50 * 2**20, open_timeout=10)
        )
        self.n = 0
        self.send("session.new", {"capabilities": {}})
        tree = self.send("browsingContext.getTree", {})
        self.ctx = tree["contexts"][0]["context"]

    def send(self, method: str, params: dict) -> dict:
        self.n += 1
        self.ws.send(json.dumps({"id": self.n, "method": method, "params": params}))
        while True:
            msg = json.loads(self.ws.recv(timeout=60))
            if msg.get("id") == self.n:
                if msg.get("type") == "error":
                    raise AssertionError(f"{method}: {msg.get('error')}: {msg.get('message')}")
                return msg["result"]

    def js(self, expression: str):
        r = self.send(
            "script.evaluate",
            {"expression": expression, "awaitPromise": True, "target": {"context": self.ctx}},
        )
        if r.get("type") == "exception":
            raise AssertionError(f"{expression[:80]}: {r['exceptionDetails'].get('text')}")
        return r["result"].get("value")

    def click(self, selector: str, text: str, *, exact: bool = False) -> None:
        """Wait for the element matching ``selector`` whose text has ``text``; click it."""
        find = (
            f"[...document.querySelectorAll({json.dumps(selector)})].find(e => "
            + (
                f"e.innerText.trim() === {json.dumps(text)}"
                if exact
                else f"e.innerText.includes({json.dumps(text)})"
            )
            + " && !e.disabled)"
        )
        self.wait(f"!!{find}")
        self.js(f"{find}.click()")

    def wait(self, expression: str, timeout_s: float = 30.0):
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            v = self.js(expression)
            if v:
                return v
            time.sleep(0.25)
        raise AssertionError(f"timed out waiting for {expression}")

    def close(self):
        try:
            self.send("session.end", {})
        except Exception:  # noqa: BLE001 - the browser may already be gone
            pass
        self._stack.close()


#: JavaScript helpers evaluated in Firefox: find elements across open shadow roots.
DEEP = """
const deepAll = (sel, root = document) => {
  const out = [...root.querySelectorAll(sel)];
  for (const el of root.querySelectorAll('*')) if (el.shadowRoot) out.push(...deepAll(sel, el.shadowRoot));
  return out;
};
const deep = (sel) => deepAll(sel)[0] || null;
"""


@contextlib.contextmanager
def firefox(client=None, *, width: int = 1366, height: int = 768):
    """A headless Firefox ESR on a fresh profile, driven over WebDriver BiDi: yields the
    client (``client(port)``, :class:`Bidi` by default) on its first tab at
    ``width`` × ``height``; the browser and its profile are removed afterwards."""
    need(os.path.exists(FIREFOX), f"no Firefox ESR at {FIREFOX}")
    pytest.importorskip("websockets")
    client = client or Bidi
    profile = tempfile.mkdtemp(prefix="ff-profile-")
    port = free_port()
    proc = subprocess.Popen(
        [
            FIREFOX,
            "--headless",
            "--no-remote",
            "--profile",
            profile,
            f"--remote-debugging-port={port}",
            "about:blank",
        ],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    ff = None
    try:
        deadline = time.monotonic() + 60
        while True:
            try:
                ff = client(port)
                break
            except OSError:
                if time.monotonic() > deadline:
                    raise
                time.sleep(0.5)
        ff.send(
            "browsingContext.setViewport",
            {"context": ff.ctx, "viewport": {"width": width, "height": height}},
        )
        yield ff
    finally:
        if ff is not None:
            ff.close()
        stop_process(proc)
        shutil.rmtree(profile, ignore_errors=True)


def test_firefox_esr_plays_webm(server, artifacts):
    """Firefox ESR without H.264 plays the WebM/VP9 source with the full player; steps
    taken just before a reload are stored once; the participant answers a pose task and
    the database holds it."""
    base, store, *_ = server
    with firefox() as ff:
        ff.send(
            "browsingContext.navigate", {"context": ff.ctx, "url": f"{base}/", "wait": "complete"}
        )
        # no H.264 decoder in this Firefox (that is why the WebM copy exists)
        assert (
            ff.js(
                "document.createElement('video').canPlayType('video/mp4; codecs=\"avc1.42E01E\"')"
            )
            == ""
        )
        ff.wait("[...document.querySelectorAll('h1')].some(h => h.innerText.includes('Tiny demo'))")
        ff.wait("!!document.querySelector('[data-testid=stCheckbox] input')")
        ff.wait(f"({SETTLED})()")
        ff.js("document.querySelector('[data-testid=stCheckbox] input').click()")
        ff.click("button", "Start the study")
        ff.wait(
            "[...document.querySelectorAll('h2, h1')].some(h => h.innerText.includes('About you'))"
        )
        pid = re.search(r"pid=([A-Za-z0-9_-]+)", ff.js("location.href")).group(1)
        assert store.get_participant(pid) is not None
        # The background form is Chromium's business (tested above); answer it in the
        # store and reload: the pose task is what differs in this browser.
        store.set_background(
            pid, {"age_band": "35–44", "gender": "Prefer not to say", "experience": "No experience"}
        )
        ff.send("browsingContext.reload", {"context": ff.ctx, "wait": "complete"})
        ff.wait(
            "[...document.querySelectorAll('h2, h1')].some(h => h.innerText.includes('Animation 1 of 2'))"
        )
        # The full player, on the WebM source; the instructions name its controls.
        ff.wait(
            "(() => {"
            + DEEP
            + "const r = deep('.snap-picker'); return r && r.dataset.ready === '1'; })()"
        )
        src = ff.js("(() => {" + DEEP + "return deep('video').currentSrc; })()")
        assert src and ff.js(
            "(() => {" + DEEP + "return deep('video').currentSrc.length > 0 && "
            "deep('video source[type=\"video/webm\"]').src === deep('video').currentSrc; })()"
        ), src
        body = ff.js("document.body.innerText")
        assert "Play" in body and "arrow keys" in body and "slider" not in body.lower()
        # Two steps and a reload at once: the steps reach the database all the same
        ff.js(
            "(() => {" + DEEP + "deep('[data-testid=picker-forward]').click(); "
            "deep('[data-testid=picker-forward]').click(); })()"
        )
        ff.send("browsingContext.reload", {"context": ff.ctx, "wait": "complete"})
        ff.wait(
            "(() => {"
            + DEEP
            + "const r = deep('.snap-picker'); return r && r.dataset.ready === '1'; })()"
        )
        deadline = time.monotonic() + 15
        while [e["kind"] for e in store.events(pid)].count("step") < 2:
            assert time.monotonic() < deadline, store.events(pid)
            time.sleep(0.2)
        # back to the first frame (the player came back at the third), so playing shows
        # the whole animation: from the third frame on, a 24-frame one is 89.6% of it
        ff.js(
            "(() => {" + DEEP + "deep('[data-testid=picker-back]').click(); "
            "deep('[data-testid=picker-back]').click(); })()"
        )
        ff.wait("(() => {" + DEEP + "return deep('.snap-picker').dataset.frame === '0'; })()")
        ff.js("(() => {" + DEEP + "deep('[data-testid=picker-play]').click(); })()")
        ff.wait(
            "(() => {" + DEEP + "return !deep('[data-testid=picker-confirm]').disabled; })()", 40
        )
        shot_b64 = ff.send("browsingContext.captureScreenshot", {"context": ff.ctx})["data"]
        (ARTIFACTS / "firefox-1366x768-pose-task.png").write_bytes(base64.b64decode(shot_b64))
        frame = ff.js("(() => {" + DEEP + "return Number(deep('.snap-picker').dataset.frame); })()")
        ff.js("(() => {" + DEEP + "deep('[data-testid=picker-confirm]').click(); })()")
        ff.wait(
            "[...document.querySelectorAll('h2, h1')].some(h => h.innerText.includes('Animation 2 of 2'))"
        )
    (row,) = store.responses(pid)
    assert row["task"] == "pose" and row["chosen_video_frame"] == frame
    assert row["chosen_frame"] is not None
    sel = [e for e in store.events(pid) if e["kind"] == "select"]
    assert len(sel) == 1 and sel[0]["payload"]["watched"] >= 0.9
    assert [e["kind"] for e in store.events(pid)].count("step") == 4  # once each


# ------------------------------------------------------------------- issue 29, item 2
class InterceptingBidi(Bidi):
    """:class:`Bidi` with a reader thread, so requests the browser holds at an intercept
    can be failed or let through while the test waits on its own commands.

    ``fail(url)`` (set by the test) says whether a held request is to fail; every other
    held request continues. Failed URLs are listed in ``failed``.
    """

    def __init__(self, port: int):
        import threading

        from websockets.sync.client import connect

        self._stack = contextlib.ExitStack()
        self.ws = self._stack.enter_context(
            connect(f"ws://127.0.0.1:{port}/session", max_size=50 * 2**20, open_timeout=10)
        )
        self.n = 0
        self._send_lock = threading.Lock()
        self._replies: dict[int, dict] = {}
        self._arrived = threading.Condition()
        self.fail = lambda url: False
        self.failed: list[str] = []
        threading.Thread(target=self._read, daemon=True).start()
        self.send("session.new", {"capabilities": {}})
        self.ctx = self.send("browsingContext.getTree", {})["contexts"][0]["context"]

    def _post(self, method: str, params: dict) -> int:
        with self._send_lock:
            self.n += 1
            n = self.n
            self.ws.send(json.dumps({"id": n, "method": method, "params": params}))
        return n

    def _read(self) -> None:
        while True:
            try:
                msg = json.loads(self.ws.recv())
            except Exception:  # noqa: BLE001 - the connection closed: wake any waiter
                with self._arrived:
                    self._replies[-1] = {}
                    self._arrived.notify_all()
                return
            if "id" in msg:
                with self._arrived:
                    self._replies[msg["id"]] = msg
                    self._arrived.notify_all()
            elif msg.get("method") == "network.beforeRequestSent" and msg["params"]["isBlocked"]:
                req = msg["params"]["request"]
                # Answered without waiting for the reply (this thread delivers replies).
                if self.fail(req["url"]):
                    self.failed.append(req["url"])
                    self._post("network.failRequest", {"request": req["request"]})
                else:
                    self._post("network.continueRequest", {"request": req["request"]})

    def send(self, method: str, params: dict) -> dict:
        n = self._post(method, params)
        with self._arrived:
            ok = self._arrived.wait_for(lambda: n in self._replies or -1 in self._replies, 60)
            msg = self._replies.pop(n, None)
        if not ok or msg is None:
            raise AssertionError(f"{method}: no reply from Firefox")
        if msg.get("type") == "error":
            raise AssertionError(f"{method}: {msg.get('error')}: {msg.get('message')}")
        return msg["result"]


#: The stimulus videos' URLs (H.264 and WebM), retries' queries included.
VIDEO_URL = re.compile(r"/media/[^/?]*\.(mp4|webm)(\?.*)?$")


def ff_heading(ff, text: str, timeout_s: float = 60.0) -> None:
    ff.wait(
        f"[...document.querySelectorAll('h1, h2')].some(h => h.innerText.includes({json.dumps(text)}))",
        timeout_s,
    )


def ff_no_traceback(ff, log_path) -> None:
    assert not ff.js("!!document.querySelector('[data-testid=stException]')")
    assert "Traceback" not in ff.js("document.body.innerText")
    assert "Traceback" not in Path(log_path).read_text()


def ff_responses(store, pid: str, n: int, timeout_s: float = 30.0) -> list[dict]:
    """The participant's answers once there are ``n``; none duplicated."""
    deadline = time.monotonic() + timeout_s
    while len(store.responses(pid)) < n:
        assert time.monotonic() < deadline, store.responses(pid)
        time.sleep(0.2)
    rows = store.responses(pid)
    idx = [r["trial_index"] for r in rows]
    assert len(idx) == len(set(idx)) == n, idx
    return rows


def test_firefox_esr_video_failing_for_good_falls_back_and_failing_once_plays(server, artifacts):
    """Issue 29 item 2 in Firefox ESR (the browser that plays the WebM copy), the video
    requests failed by the browser's own network layer (a WebDriver BiDi intercept): a
    video that never loads is tried again, then turns this trial only to the frame
    slider, whose answer says "slider" with nothing watched; on the next trial the
    first request for the video fails once, the page loads it again and the player
    plays. The database holds exactly one answer per trial answered, how its frame was
    picked, one media_failed event; no traceback, no control left frozen.

    (For good first: Firefox keeps a loaded video in its media cache, which a later
    request for the same address reaches without the network, intercept or not.)"""
    base, store, log_path, _ = server
    pid = seeded(server)
    with firefox(InterceptingBidi) as ff:
        ff.send("session.subscribe", {"events": ["network.beforeRequestSent"]})
        ff.send("network.setCacheBehavior", {"cacheBehavior": "bypass", "contexts": [ff.ctx]})
        intercept = ff.send(
            "network.addIntercept", {"phases": ["beforeRequestSent"], "contexts": [ff.ctx]}
        )["intercept"]
        picker = "(() => {" + DEEP + "const r = deep('.snap-picker'); return r && %s; })()"
        # Streamlit's slider: a range input in its thumb (what Playwright's role finds)
        slider = "document.querySelector('[data-testid=stSlider] input[type=range]')"

        # Failing for good: every request for the first trial's video fails (MP4 and
        # WebM, the retries too); the page says so and gives the slider.
        ff.fail = lambda url: bool(VIDEO_URL.search(url))
        ff.send(
            "browsingContext.navigate",
            {"context": ff.ctx, "url": f"{base}/?pid={pid}", "wait": "complete"},
        )
        ff_heading(ff, "Animation 1 of 2")
        try:
            ff.wait(f"!!{slider}", 60)
        except AssertionError as err:
            state = ff.js(
                "(() => {" + DEEP + "const r = deep('.snap-picker'); "
                "return JSON.stringify({data: r && {...r.dataset}, "
                "body: document.body.innerText.slice(0, 600)}); })()"
            )
            raise AssertionError(f"{err}: failed {ff.failed}; page {state}") from None
        ff.wait(f"({SETTLED})()")
        first = {u.split("?")[0] for u in ff.failed}
        webm = [u for u in ff.failed if u.split("?")[0].endswith(".webm")]
        assert len(webm) == 3, ff.failed  # the first load and two retries
        assert "slider" in ff.js("document.body.innerText")
        assert store.responses(pid) == []  # nothing answered for a video not seen
        # The slider works (four steps right, real key presses) and Confirm answers.
        start = int(ff.js(f"{slider}.value"))
        ff.js(f"{slider}.focus()")
        right = "\ue014"
        keys = [{"type": t, "value": right} for _ in range(4) for t in ("keyDown", "keyUp")]
        ff.send(
            "input.performActions",
            {"context": ff.ctx, "actions": [{"type": "key", "id": "kb", "actions": keys}]},
        )
        ff.wait(f"{slider}.value === '{start + 4}'")
        # the slider sends its value when the keys stop; the app's rerun captions it
        ff.wait(f"document.body.innerText.includes('Frame {start + 4} / ')")
        ff.wait(f"({SETTLED})()")
        # Failing once: the next trial's first WebM request (the copy this Firefox
        # plays: it asks for the MP4 first and gives up on H.264) fails.
        ff.failed.clear()
        ff.fail = lambda url: (
            url.split("?")[0].endswith(".webm") and url.split("?")[0] not in first and not ff.failed
        )
        # The slider's Confirm reports the client as the pickers do: a component too
        ff.js("(() => {" + DEEP + "deep('[data-testid=slider-confirm]').click(); })()")
        ff_heading(ff, "Animation 2 of 2")
        (row,) = ff_responses(store, pid, 1)
        assert row["trial_index"] == 0 and row["picked_with"] == "slider"
        assert row["watched"] is None and row["chosen_video_frame"] == 4
        kinds = [e["kind"] for e in store.events(pid) if e["trial_index"] == 0]
        assert kinds.count("media_failed") == 1

        # ... is loaded again and plays in the full player; watched, answered.
        ff.wait(picker % "r.dataset.ready === '1'")
        assert len(ff.failed) == 1, ff.failed
        ff.send("network.removeIntercept", {"intercept": intercept})
        assert ff.js(picker % "r.dataset.retries === '1' && !r.dataset.error")
        assert "retry=1" in ff.js("(() => {" + DEEP + "return deep('video').currentSrc; })()")
        assert "slider" not in ff.js("document.body.innerText").lower()
        ff.wait("(() => {" + DEEP + "return deep('.snap-picker').dataset.frame === '0'; })()")
        ff.js("(() => {" + DEEP + "deep('[data-testid=picker-play]').click(); })()")
        ff.wait(
            "(() => {" + DEEP + "return !deep('[data-testid=picker-confirm]').disabled; })()", 40
        )
        ff.js("(() => {" + DEEP + "deep('[data-testid=picker-confirm]').click(); })()")
        ff_heading(ff, "Pictures 1 of 2")
        rows = ff_responses(store, pid, 2)
        assert rows[1]["trial_index"] == 1 and rows[1]["picked_with"] == "player"
        assert rows[1]["watched"] >= 0.9
        assert [e["kind"] for e in store.events(pid)].count("media_failed") == 1
        ff_no_traceback(ff, log_path)
        shot_b64 = ff.send("browsingContext.captureScreenshot", {"context": ff.ctx})["data"]
        (ARTIFACTS / "firefox-video-fault-after.png").write_bytes(base64.b64decode(shot_b64))
