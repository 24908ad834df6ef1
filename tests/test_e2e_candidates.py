"""Candidate pictures in the browser (issue 36): alike candidates merged into one picture
that stands for each of its methods, and a picture that never loads, which leaves a way
on ("I can't see the pictures") stored as a skipped trial, never as a choice, up to the
completion code. Chromium (Playwright) and Firefox ESR (WebDriver BiDi), one `snapshot
study` server on fixture stimuli whose manifest merges pictures; the database is read
after each scenario.
"""

from __future__ import annotations

import json
import re
import time

import pytest
import test_e2e
from app_helpers import fixture_study_doc, write_fixture_stimuli
from test_e2e import SETTLED, completion_code, heading, settle, start_study, stop_process
from test_e2e_described import ff_press
from test_e2e_firefox import DEEP, InterceptingBidi, ff_heading, ff_no_traceback, firefox

from study_app.design.stimuli import load_stimuli

pytestmark = [pytest.mark.browser, pytest.mark.slow]

playwright_api = test_e2e.playwright_api
browser = test_e2e.browser
#: walk: ours and motion area alike (two pictures); jump: three; kick: all alike (no
#: view task).
SHOWN = {
    "walk": [["ours", "motion_area"], ["viewpoint_entropy"]],
    "kick": [["ours", "viewpoint_entropy", "motion_area"]],
}
#: The candidate pictures' URLs, retries' queries included.
PICTURE = re.compile(r".*/media/[^/?]*\.png(\?.*)?$")
BACKGROUND = {"age_band": "35–44", "gender": "Prefer not to say", "experience": "No experience"}


@pytest.fixture(scope="module")
def study(tmp_path_factory, playwright_api):
    """The server on fixture stimuli with merged pictures: (base url, store, log, folder)."""
    from study_app.data.store import Store

    root = tmp_path_factory.mktemp("candidates")
    write_fixture_stimuli(
        root / "stimuli", fixture_study_doc(("walk", "jump", "kick")), shown=SHOWN
    )
    db = f"sqlite:///{root / 'study.db'}"
    log = root / "server.log"
    proc, base = start_study(root / "stimuli", db, log)
    store = Store(db)
    yield base, store, log, root / "stimuli"
    store.close()
    stop_process(proc)


def seeded(study) -> tuple[str, list]:
    """A participant with background and pose tasks answered (logic layer); returns the
    id and the plan (their browser opens ``?pid=`` at the first view task)."""
    from study_app.session import ParticipantSession

    _, store, _, folder = study
    s = ParticipantSession.start(store, load_stimuli(folder, verify=False))
    s.submit_background(BACKGROUND)
    for t in s.plan:
        if t.task == "pose":
            s.submit_pose(t.index, 0, response_time_s=5.0, watched=1.0)
    return s.participant_id, s.plan


def rows_of(store, pid: str, n: int, timeout_s: float = 30.0) -> list[dict]:
    deadline = time.monotonic() + timeout_s
    while len(store.responses(pid)) < n:
        assert time.monotonic() < deadline, store.responses(pid)
        time.sleep(0.2)
    rows = store.responses(pid)
    assert len({r["trial_index"] for r in rows}) == len(rows) == n
    return rows


def no_traceback(page, log) -> None:
    assert page.locator("[data-testid=stException]").count() == 0
    assert "Traceback" not in page.inner_text("body") and "Traceback" not in log.read_text()


def new_page(browser, base: str, pid: str):
    ctx = browser.new_context(viewport={"width": 1366, "height": 768})
    page = ctx.new_page()
    page.set_default_timeout(30_000)
    page.goto(f"{base}/?pid={pid}")
    return page


def finish(page, store, pid: str) -> str:
    """Answer the attention check and return the completion code shown."""
    heading(page, "One more question")
    page.get_by_test_id("stRadioGroup").get_by_text("A purple circle").click()
    time.sleep(1.2)  # the study's min_answer_s
    page.get_by_role("button", name="Continue").click()
    heading(page, "Thank you!")
    code = completion_code(page)
    part = store.get_participant(pid)
    assert part["completion_code"] == code and part["completed_at"] is not None
    return code


def test_merged_pictures_shown_once_and_recorded(study, browser):
    """Walk shows two pictures (ours standing for motion area too), jump three, kick no
    view task; the rows record which methods each shown picture stood for."""
    base, store, log, _ = study
    pid, plan = seeded(study)
    views = [t for t in plan if t.task == "view"]
    assert [t.scene for t in views] != [] and {t.scene for t in views} == {"walk", "jump"}
    n_pose = sum(t.task == "pose" for t in plan)
    page = new_page(browser, base, pid)
    for k, t in enumerate(views, start=1):
        heading(page, f"Pictures {k} of 2")
        settle(page)
        page.wait_for_selector(".snap-views[data-ready='1']")
        n = len(t.shown_order)
        assert page.locator(".snap-view img").count() == n
        assert ("two directions" if n == 2 else "three directions") in page.inner_text("body")
        pos = next(p for p, g in enumerate(t.shown_groups) if "motion_area" in g)
        page.get_by_test_id(f"view-choose-{pos}").click()
        rows = rows_of(store, pid, n_pose + k)
        row = rows[-1]
        assert row["shown_order"] == list(t.shown_order)
        assert row["shown_groups"] == [list(g) for g in t.shown_groups]
        assert row["chosen_position"] == pos and row["chosen_method"] == t.shown_order[pos]
        assert row["skipped"] is None
    walk = next(r for r in store.responses(pid) if r["stimulus_id"] == "walk/view")
    assert sorted(walk["shown_groups"]) == [["ours", "motion_area"], ["viewpoint_entropy"]]
    assert walk["chosen_method"] == "ours"  # the picture of ours, standing for motion area
    finish(page, store, pid)
    assert not [r for r in store.responses(pid) if r["scene"] == "kick" and r["task"] == "view"]
    no_traceback(page, log)
    page.context.close()


def test_picture_never_loading_leaves_a_way_on(study, browser):
    """A picture that never loads: Choose stays off, a forged choice of its position is
    refused by the server, "I can't see the pictures" stores a skipped row (no method,
    no position, the client described) and the study goes on to its completion code."""
    base, store, log, _ = study
    pid, plan = seeded(study)
    first_view = next(t for t in plan if t.task == "view")
    n_pose = sum(t.task == "pose" for t in plan)
    page = new_page(browser, base, pid)
    failing = []

    def handle(route):  # the first picture asked for fails, whatever is asked again
        url = route.request.url.split("?")[0]
        if not failing:
            failing.append(url)
        if url == failing[0]:
            route.abort("connectionreset")
        else:
            route.continue_()

    page.route(PICTURE, handle)
    page.reload()
    heading(page, "Pictures 1 of 2")
    error = page.get_by_test_id("views-error")
    error.wait_for(state="visible")
    skip = page.get_by_test_id("views-skip")
    assert skip.is_visible() and page.get_by_test_id("views-retry").is_visible()
    n = len(first_view.shown_order)
    assert all(page.get_by_test_id(f"view-choose-{i}").is_disabled() for i in range(n))
    deadline = time.monotonic() + 15
    while not [e for e in store.events(pid) if e["kind"] == "media_failed"]:
        assert time.monotonic() < deadline, store.events(pid)
        time.sleep(0.2)
    (ev,) = [e for e in store.events(pid) if e["kind"] == "media_failed"]
    (bad,) = ev["payload"]["positions"]
    # "Try again" changes nothing while the picture still fails.
    page.get_by_test_id("views-retry").click()
    page.wait_for_selector(".snap-views [data-testid=views-retry]:visible")
    # A choice of the failed position sent from the console is refused by the server.
    page.locator(".snap-views").evaluate(
        "(el, a) => el._api.setTriggerValue('choice', {trial: a[0], position: a[1]})",
        [first_view.index, bad],
    )
    page.get_by_text("did not load in your browser").wait_for()
    assert len(store.responses(pid)) == n_pose
    settle(page)
    page.get_by_test_id("views-skip").click()
    heading(page, "Pictures 2 of 2")
    rows = rows_of(store, pid, n_pose + 1)
    row = rows[-1]
    assert row["trial_index"] == first_view.index and row["skipped"] == "media_failed"
    assert row["chosen_method"] is None and row["chosen_position"] is None
    assert row["shown_groups"] == [list(g) for g in first_view.shown_groups]
    assert row["viewport_width"] == 1366 and row["viewport_height"] == 768
    assert row["device_pixel_ratio"] == 1 and row["input_type"] == "mouse"
    assert row["tab_id"] and row["active_time_s"] is not None
    page.unroute(PICTURE)
    settle(page)
    page.wait_for_selector(".snap-views[data-ready='1']")
    page.get_by_test_id("view-choose-0").click()
    rows_of(store, pid, n_pose + 2)
    finish(page, store, pid)
    # The analysis counts no vote from the skipped trial.
    from analysis.load import tidy_responses, view_choices

    choices = view_choices(tidy_responses(store.export_rows()))
    assert first_view.index not in set(choices.loc[choices["participant_id"] == pid, "trial_index"])
    no_traceback(page, log)
    page.context.close()


def test_firefox_esr_picture_never_loading_leaves_a_way_on(study):
    """The same in Firefox ESR, the picture's requests failed by a WebDriver BiDi
    intercept: the skip is stored as skipped, and the completion code is reached."""
    base, store, log, _ = study
    pid, plan = seeded(study)
    first_view = next(t for t in plan if t.task == "view")
    n_pose = sum(t.task == "pose" for t in plan)
    png = re.compile(r"/media/[^/?]*\.png(\?.*)?$")
    with firefox(InterceptingBidi) as ff:
        ff.send("session.subscribe", {"events": ["network.beforeRequestSent"]})
        ff.send("network.setCacheBehavior", {"cacheBehavior": "bypass", "contexts": [ff.ctx]})
        intercept = ff.send(
            "network.addIntercept", {"phases": ["beforeRequestSent"], "contexts": [ff.ctx]}
        )["intercept"]
        first: list[str] = []

        def fail(url: str) -> bool:
            if not png.search(url):
                return False
            if not first:
                first.append(url.split("?")[0])
            return url.split("?")[0] == first[0]

        ff.fail = fail
        ff.send(
            "browsingContext.navigate",
            {"context": ff.ctx, "url": f"{base}/?pid={pid}", "wait": "complete"},
        )
        ff_heading(ff, "Pictures 1 of 2")
        skip = (
            "(() => {"
            + DEEP
            + "const b = deep('[data-testid=views-skip]'); return b && !b.hidden; })()"
        )
        ff.wait(skip, 60)
        assert len([u for u in ff.failed if u.split("?")[0] == first[0]]) == 3  # + 2 retries
        assert ff.js(
            "(() => {" + DEEP + "return deepAll('.snap-view button').every(b => b.disabled); })()"
        )
        assert len(store.responses(pid)) == n_pose  # nothing answered for what was not seen
        ff.js("(() => {" + DEEP + "deep('[data-testid=views-skip]').click(); })()")
        ff_heading(ff, "Pictures 2 of 2")
        deadline = time.monotonic() + 30
        while len(store.responses(pid)) < n_pose + 1:
            assert time.monotonic() < deadline, store.responses(pid)
            time.sleep(0.2)
        row = store.responses(pid)[-1]
        assert row["trial_index"] == first_view.index and row["skipped"] == "media_failed"
        assert row["chosen_method"] is None and row["chosen_position"] is None
        assert row["viewport_width"] == 1366 and row["tab_id"]
        ff.send("network.removeIntercept", {"intercept": intercept})
        ready = (
            "(() => {"
            + DEEP
            + "const r = deep('.snap-views'); return r && r.dataset.ready === '1'; })()"
        )
        ff.wait(ready, 60)
        ff.js("(() => {" + DEEP + "deep('[data-testid=view-choose-0]').click(); })()")
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
        time.sleep(1.2)  # the study's min_answer_s
        ff_press(ff, "(() => {" + DEEP + "return deep('[data-testid=attention-submit]'); })()")
        ff_heading(ff, "Thank you!")
        part = store.get_participant(pid)
        assert part["completion_code"] and part["completed_at"] is not None
        assert json.dumps(part["completion_code"]).strip('"') in ff.js("document.body.innerText")
        ff_no_traceback(ff, log)
