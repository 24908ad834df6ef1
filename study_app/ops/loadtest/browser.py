"""The browser-level driver: a few participants in headless Chromium (Playwright).

It checks the protocol driver's numbers the way a participant's browser sees them: the
same flow (consent, background, each pose task watched through and confirmed, each view
chosen, the attention check, the completion code), with seeded choices from the same
participant model as the protocol driver (:func:`~.participant.answering_person`), every
click timed until the script run it caused has finished (read from the page's own
websocket, see :class:`RunWatch`) and, for an answer, until the next step's page is
drawn, and the same report and database check (:func:`study_app.ops.loadtest.run.check_database`). Each participant is a
browser context (about 0.4 GB and a good share of a core), so keep N small: on a
2-core machine 30 browsers starve the server they measure.

Needs Playwright for Python and Chromium at :data:`CHROMIUM` (never ``playwright
install``).
"""

from __future__ import annotations

import asyncio
import random
import re
import time

from .participant import ParticipantResult, answering_person
from .run import ServerSampler, build_report

__all__ = ["run_browsers", "CHROMIUM", "CHROMIUM_ARGS"]

CHROMIUM = "/usr/bin/chromium"
CHROMIUM_ARGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
    "--disable-quic",
    "--autoplay-policy=no-user-gesture-required",
]
IDLE = "[data-testid=stApp][data-test-script-state=notRunning]"
SELF_DESCRIBE = "Prefer to self-describe"


class RunWatch:
    """Counts the app's finished script runs as the page's own websocket delivers them.

    A click waits for the run *it* caused to finish, however late that run starts on a
    loaded server, and a run that ends in ``st.rerun()`` (the frame-slider fallback's
    answer) counts once, when the run after it finishes. The page's script-state attribute cannot tell this: a run
    can pass it by (running and idle drawn in one frame), and it shows idle between the
    two runs of a rerun.
    """

    def __init__(self, page) -> None:
        from streamlit.proto.ForwardMsg_pb2 import ForwardMsg

        self._msg = ForwardMsg
        self.finished = 0  # script runs finished (whole, or of a fragment)
        self.at = time.perf_counter()  # when the last one finished
        self._changed = asyncio.Event()
        page.on("websocket", lambda ws: ws.on("framereceived", self._frame))

    def _frame(self, payload) -> None:
        if isinstance(payload, str):
            return
        fm = self._msg()
        try:
            fm.ParseFromString(payload)
        except Exception:  # noqa: BLE001 - not one of the app's messages
            return
        if fm.WhichOneof("type") == "script_finished" and fm.script_finished in (
            self._msg.FINISHED_SUCCESSFULLY,
            self._msg.FINISHED_FRAGMENT_RUN_SUCCESSFULLY,
            self._msg.FINISHED_WITH_COMPILE_ERROR,
        ):
            self.finished += 1
            self.at = time.perf_counter()
            self._changed.set()

    async def after(self, page, before: int, timeout_s: float = 60) -> float:
        """Wait until more than ``before`` runs have finished and the page has drawn the
        last one; return when it finished (``time.perf_counter`` seconds)."""
        deadline = time.perf_counter() + timeout_s
        while self.finished <= before:
            self._changed.clear()
            left = deadline - time.perf_counter()
            if left <= 0:
                raise TimeoutError(f"no script run finished within {timeout_s:.0f} s")
            try:
                await asyncio.wait_for(self._changed.wait(), left)
            except TimeoutError:
                pass
        await page.wait_for_selector(IDLE, timeout=timeout_s * 1000)
        return self.at


#: The page's headings as :func:`_heading` reads them, in the page.
HEADINGS_JS = "() => Array.from(document.querySelectorAll('h1, h2')).map(e => e.innerText)"


async def _timed_click(
    result, watch: RunWatch, action, page, locator, *, leaves: str | None = None
) -> None:
    """Click and wait for the run it caused; with ``leaves``, until the page's headings
    are no longer ``leaves`` (an answer moves to the next step). Counting runs alone
    cannot tell the answer's run from a run the player's event log started just before."""
    before, t0 = watch.finished, time.perf_counter()
    await locator.click()
    done = await watch.after(page, before)
    if leaves is not None:
        await page.wait_for_function(
            f"h => ({HEADINGS_JS})().join(' | ') !== h", arg=leaves, timeout=60_000, polling=50
        )
        await page.wait_for_selector(IDLE, timeout=60_000)
        done = time.perf_counter()
    result.add(action, done - t0)


async def _heading(page) -> str:
    return " | ".join(await page.evaluate(HEADINGS_JS))


async def _participant(browser, url, index, *, seed, think_s) -> ParticipantResult:
    rng = random.Random(f"{seed}:{index}")
    n_pose = n_view = 0  # read from the headings ("Animation k of N")
    prolific_pid = f"{rng.getrandbits(96):024x}"
    person = answering_person(rng)  # the answers, as the protocol driver's; rng: timing
    r = ParticipantResult(index=index, prolific_pid=prolific_pid)
    ctx = await browser.new_context(viewport={"width": 1366, "height": 768})
    page = await ctx.new_page()
    watch = RunWatch(page)
    r.started = time.perf_counter()
    try:
        t0 = time.perf_counter()
        await page.goto(
            f"{url.rstrip('/')}/?PROLIFIC_PID={prolific_pid}&STUDY_ID=loadtest"
            f"&SESSION_ID=b{index:05d}"
        )
        r.add("open", await watch.after(page, 0) - t0)
        for _ in range(100):
            h = await _heading(page)
            think = think_s * rng.uniform(0.5, 1.5)
            if "Thank you" in h:
                code = page.get_by_test_id("stCode").first
                r.completion_code = (await code.inner_text()).strip()
                break
            if await page.get_by_role("button", name="Start the study").count():
                await page.wait_for_timeout(think * 500)
                await _timed_click(
                    r, watch, "consent_agree", page, page.get_by_text("I have read the information")
                )
                await _timed_click(
                    r,
                    watch,
                    "consent_start",
                    page,
                    page.get_by_role("button", name="Start the study"),
                    leaves=h,
                )
            elif "About you" in h:
                await page.get_by_role("combobox", name="Your age").click()
                await page.get_by_role("option").first.wait_for()  # the list opens
                options = await page.get_by_role("option").all_inner_texts()
                await _timed_click(
                    r,
                    watch,
                    "background_field",
                    page,
                    page.get_by_role("option", name=person.choose(options)),
                )
                for group in range(2):
                    labels = page.get_by_test_id("stRadioGroup").nth(group).locator("label")
                    texts = [t for t in await labels.all_inner_texts() if t != SELF_DESCRIBE]
                    await _timed_click(
                        r,
                        watch,
                        "background_field",
                        page,
                        labels.filter(
                            has_text=re.compile("^" + re.escape(person.choose(texts)) + "$")
                        ).first,
                    )
                await _timed_click(
                    r,
                    watch,
                    "background_submit",
                    page,
                    page.get_by_role("button", name="Continue"),
                    leaves=h,
                )
            elif m := re.search(r"Animation (\d+) of (\d+)", h):
                trial, n_pose = int(m.group(1)) - 1, int(m.group(2))
                # This trial's player (its key starts with the trial index): the last
                # trial's may still be on the page while the new one mounts.
                mine = f".snap-picker[data-key^='{trial}|']"
                await page.wait_for_selector(f"{mine}[data-ready='1']", timeout=60_000)
                player = page.locator(mine)
                await player.get_by_test_id("picker-play").click()
                await page.wait_for_selector(
                    f"{mine} [data-testid=picker-confirm]:enabled", timeout=60_000
                )
                # The played clip ends on its last frame; the frame is chosen among the
                # last six (a few steps back: clicks, not a drag of the scrub bar).
                last = int(await player.get_by_test_id("picker-scrub").get_attribute("max") or 0)
                target = person.pose_frame(max(0, last - 5), last)
                for _ in range(last - target):  # step back to it
                    await player.get_by_test_id("picker-back").click()
                await page.wait_for_timeout(think * 300)
                text = await player.get_by_test_id("picker-frame").inner_text()
                shown = re.match(r"Frame (\d+)", text)
                if shown is None:
                    raise ValueError(f"the picker shows {text!r}, not a frame number")
                frame = int(shown.group(1)) - 1
                r.answers[trial] = {"task": "pose", "video_frame": frame}
                await _timed_click(
                    r,
                    watch,
                    "pose_confirm",
                    page,
                    player.get_by_test_id("picker-confirm"),
                    leaves=h,
                )
            elif m := re.search(r"Pictures (\d+) of (\d+)", h):
                n_view = int(m.group(2))
                trial = n_pose + int(m.group(1)) - 1
                mine = f".snap-views[data-key^='{trial}|']"
                await page.wait_for_selector(f"{mine}[data-ready='1']", timeout=60_000)
                views = page.locator(mine)
                n = await views.locator("[data-testid^=view-choose-]").count()
                position = person.view_position(n)
                await page.wait_for_timeout(think * 1000)
                r.answers[trial] = {"task": "view", "position": position}
                await _timed_click(
                    r,
                    watch,
                    "view_choose",
                    page,
                    views.get_by_test_id(f"view-choose-{position}"),
                    leaves=h,
                )
            elif "One more question" in h:
                labels = page.get_by_test_id("stRadioGroup").locator("label")
                texts = await labels.all_inner_texts()
                choice = person.attention_answer(texts)
                await page.wait_for_timeout(think * 1000)
                await _timed_click(
                    r, watch, "attention_choice", page, labels.nth(texts.index(choice))
                )
                r.answers[n_pose + n_view] = {"task": "attention", "value": choice}
                await _timed_click(
                    r,
                    watch,
                    "attention_submit",
                    page,
                    page.get_by_role("button", name="Continue"),
                    leaves=h,
                )
            else:
                await page.wait_for_timeout(500)  # a page between steps: let it go on
                await watch.after(page, watch.finished - 1)
        else:
            r.errors.append("did not finish within the step limit")
        m = re.search(r"[?&]pid=([A-Za-z0-9_-]+)", page.url)
        r.participant_id = m.group(1) if m else None
    except Exception as err:  # noqa: BLE001 - one participant's failure is data
        try:
            where = await _heading(page)
        except Exception:  # noqa: BLE001 - the page itself may be gone
            where = "?"
        r.errors.append(
            f"fatal on page '{where}': {type(err).__name__}: {str(err).splitlines()[0]}"
        )
    finally:
        r.finished = time.perf_counter()
        await ctx.close()
    return r


def run_browsers(
    url: str,
    n: int,
    *,
    ramp_s: float = 5.0,
    think_s: float = 1.0,
    seed: int = 0,
    server_pids=(),
    timings=(),
    db_url: str | None = None,
):
    """Run ``n`` participants in headless Chromium; return (report, results) like
    :func:`study_app.ops.loadtest.run.run_load`.

    Trial indices (for the database check) come from the pages' headings: "Animation
    k of N" is pose trial k-1, "Pictures k of M" trial N+k-1, the attention check N+M.
    """
    from playwright.async_api import async_playwright

    async def main():
        async with async_playwright() as p:
            browser = await p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
            try:

                async def one(i):
                    await asyncio.sleep(ramp_s * i / max(n, 1))
                    return await _participant(browser, url, i, seed=seed, think_s=think_s)

                t0 = time.perf_counter()
                results = await asyncio.gather(*(one(i) for i in range(n)))
                return results, time.perf_counter() - t0
            finally:
                await browser.close()

    sampler = ServerSampler(server_pids).start() if server_pids else None
    wall0 = time.time()
    results, elapsed = asyncio.run(main())
    wall1 = time.time()
    server = sampler.stop() if sampler else {}
    config = {
        "url": url,
        "participants": n,
        "ramp_s": ramp_s,
        "think_s": think_s,
        "seed": seed,
        "prolific": True,
        "driver": "browser",
    }
    return build_report(
        results,
        elapsed_s=elapsed,
        server=server,
        config=config,
        timings=timings,
        window=(wall0, wall1),
        db_url=db_url,
    ), results
