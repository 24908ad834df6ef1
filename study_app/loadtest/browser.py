"""The browser-level driver: a few participants in headless Chromium (Playwright).

It checks the protocol driver's numbers the way a participant's browser sees them: the
same flow (consent, background, each pose task watched through and confirmed, each view
chosen, the attention check, the completion code), with seeded random choices, every
click timed until Streamlit reports the script run finished
(``[data-testid=stApp][data-test-script-state=notRunning]``), and the same report and
database check (:func:`study_app.loadtest.run.check_database`). Each participant is a
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

from .participant import ParticipantResult
from .run import ServerSampler, build_report

__all__ = ["run_browsers", "CHROMIUM", "CHROMIUM_ARGS"]

CHROMIUM = "/usr/bin/chromium"
CHROMIUM_ARGS = ["--no-sandbox", "--disable-gpu", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync", "--no-first-run",
                 "--disable-quic", "--autoplay-policy=no-user-gesture-required"]
IDLE = "[data-testid=stApp][data-test-script-state=notRunning]"
SELF_DESCRIBE = "Prefer to self-describe"


async def _settled(page) -> None:
    # The click's rerun starts within a frame or two; then wait for it to finish.
    await page.wait_for_timeout(50)
    await page.wait_for_selector(IDLE, timeout=60_000)


async def _timed_click(result, action, page, locator) -> None:
    t0 = time.perf_counter()
    await locator.click()
    await _settled(page)
    result.add(action, time.perf_counter() - t0)


async def _heading(page) -> str:
    hs = await page.locator("h1, h2").all_inner_texts()
    return " | ".join(hs)


async def _participant(browser, url, index, *, seed, think_s) -> ParticipantResult:
    rng = random.Random(f"{seed}:{index}")
    n_pose = n_view = 0  # read from the headings ("Animation k of N")
    prolific_pid = f"{rng.getrandbits(96):024x}"
    r = ParticipantResult(index=index, prolific_pid=prolific_pid)
    ctx = await browser.new_context(viewport={"width": 1366, "height": 768})
    page = await ctx.new_page()
    r.started = time.perf_counter()
    try:
        t0 = time.perf_counter()
        await page.goto(f"{url.rstrip('/')}/?PROLIFIC_PID={prolific_pid}&STUDY_ID=loadtest"
                        f"&SESSION_ID=b{index:05d}")
        await _settled(page)
        r.add("open", time.perf_counter() - t0)
        for _ in range(100):
            h = await _heading(page)
            think = think_s * rng.uniform(0.5, 1.5)
            if "Thank you" in h:
                code = page.get_by_test_id("stCode").first
                r.completion_code = (await code.inner_text()).strip()
                break
            if await page.get_by_role("button", name="Start the study").count():
                await page.wait_for_timeout(think * 500)
                await _timed_click(r, "consent_agree", page,
                                   page.get_by_text("I have read the information"))
                await _timed_click(r, "consent_start", page,
                                   page.get_by_role("button", name="Start the study"))
            elif "About you" in h:
                await page.get_by_role("combobox", name="Your age").click()
                options = await page.get_by_role("option").all_inner_texts()
                await _timed_click(r, "background_field", page,
                                   page.get_by_role("option", name=rng.choice(options)))
                for group in range(2):
                    labels = page.get_by_test_id("stRadioGroup").nth(group).locator("label")
                    texts = [t for t in await labels.all_inner_texts() if t != SELF_DESCRIBE]
                    await _timed_click(r, "background_field", page, labels.filter(
                        has_text=re.compile("^" + re.escape(rng.choice(texts)) + "$")).first)
                await _timed_click(r, "background_submit", page,
                                   page.get_by_role("button", name="Continue"))
            elif m := re.search(r"Animation (\d+) of (\d+)", h):
                trial, n_pose = int(m.group(1)) - 1, int(m.group(2))
                await page.wait_for_selector(".snap-picker[data-ready='1']", timeout=60_000)
                await page.get_by_test_id("picker-play").click()
                await page.wait_for_selector("[data-testid=picker-confirm]:enabled",
                                             timeout=60_000)
                for _ in range(rng.randrange(0, 6)):  # step back a few frames
                    await page.get_by_test_id("picker-back").click()
                await page.wait_for_timeout(think * 300)
                text = await page.get_by_test_id("picker-frame").inner_text()
                frame = int(re.match(r"Frame (\d+)", text).group(1)) - 1
                r.answers[trial] = {"task": "pose", "video_frame": frame}
                await _timed_click(r, "pose_confirm", page, page.get_by_test_id("picker-confirm"))
            elif m := re.search(r"Pictures (\d+) of (\d+)", h):
                n_view = int(m.group(2))
                trial = n_pose + int(m.group(1)) - 1
                await page.wait_for_selector(".snap-views[data-ready='1']", timeout=60_000)
                n = await page.locator("[data-testid^=view-choose-]").count()
                position = rng.randrange(n)
                await page.wait_for_timeout(think * 1000)
                r.answers[trial] = {"task": "view", "position": position}
                await _timed_click(r, "view_choose", page,
                                   page.get_by_test_id(f"view-choose-{position}"))
            elif "One more question" in h:
                labels = page.get_by_test_id("stRadioGroup").locator("label")
                texts = await labels.all_inner_texts()
                choice = rng.choice(texts)
                await page.wait_for_timeout(think * 1000)
                await _timed_click(r, "attention_choice", page, labels.nth(texts.index(choice)))
                r.answers[n_pose + n_view] = {"task": "attention", "value": choice}
                await _timed_click(r, "attention_submit", page,
                                   page.get_by_role("button", name="Continue"))
            else:
                await page.wait_for_timeout(500)
                await _settled(page)
        else:
            r.errors.append("did not finish within the step limit")
        m = re.search(r"[?&]pid=([A-Za-z0-9_-]+)", page.url)
        r.participant_id = m.group(1) if m else None
    except Exception as err:  # noqa: BLE001 - one participant's failure is data
        r.errors.append(f"fatal: {type(err).__name__}: {str(err).splitlines()[0]}")
    finally:
        r.finished = time.perf_counter()
        await ctx.close()
    return r


def run_browsers(url: str, n: int, *, ramp_s: float = 5.0, think_s: float = 1.0,
                 seed: int = 0, server_pids=(), timings=(), db_url: str | None = None):
    """Run ``n`` participants in headless Chromium; return (report, results) like
    :func:`study_app.loadtest.run.run_load`.

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
    config = {"url": url, "participants": n, "ramp_s": ramp_s, "think_s": think_s,
              "seed": seed, "prolific": True, "driver": "browser"}
    return build_report(results, elapsed_s=elapsed, server=server, config=config,
                        timings=timings, window=(wall0, wall1), db_url=db_url), results
