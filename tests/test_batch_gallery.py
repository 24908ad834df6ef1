"""The batch gallery in a real browser: opened from disk, it loads, filters, sorts and
opens a scene (contact sheet and JSON), and asks for nothing outside its folder.

Needs Chromium (/usr/bin/chromium) and Playwright for Python (never `playwright install`).
A screenshot of the grid and of an opened scene goes to ``var/test-artifacts/batch/``.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from urllib.parse import unquote

import pytest
from batch_helpers import make_library
from conftest import need
from test_e2e import CHROMIUM, CHROMIUM_ARGS

from snapcore.batch import BatchOptions, discover, run_batch
from snapcore.batch.gallery import gallery_html

pytestmark = [pytest.mark.browser, pytest.mark.slow]

ARTIFACTS = Path(__file__).resolve().parents[1] / "var" / "test-artifacts" / "batch"


@pytest.fixture(scope="module")
def gallery(tmp_path_factory):
    """A real batch of the small library (with a broken file, sheets): OUT folder."""
    lib = make_library(tmp_path_factory.mktemp("glib") / "lib")
    out = tmp_path_factory.mktemp("gout") / "out"
    opts = BatchOptions(snapshot={"baselines": False}, size=(160, 180), sheet=True,
                        sheet_size=(120, 135))
    report = run_batch(discover([lib]).scenes, out, opts)
    assert report.done == 6
    return out, report


@pytest.fixture(scope="module")
def page(gallery):
    sync = pytest.importorskip("playwright.sync_api")
    need(os.path.exists(CHROMIUM), f"no Chromium at {CHROMIUM}")
    with sync.sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        pg = browser.new_page(viewport={"width": 1200, "height": 900})
        pg.requests = []
        pg.on("request", lambda r: pg.requests.append(r.url))
        pg.goto((gallery[0] / "index.html").as_uri())
        pg.wait_for_selector(".card")
        yield pg
        browser.close()


def shown(page) -> list[str]:
    return page.eval_on_selector_all(".card", "cs => cs.map(c => c.dataset.path)")


def test_the_grid_shows_every_scene_with_its_thumbnail(page, gallery):
    """Every scene of the index is a card; the good ones show their thumbnail (loaded),
    the failed ones their error."""
    _, report = gallery
    assert sorted(shown(page)) == sorted(r["path"] for r in report.rows)
    assert page.inner_text("#count") == "6 of 6 scenes"
    widths = page.eval_on_selector_all(
        ".card img", "is => Promise.all(is.map(i => i.decode().then(() => i.naturalWidth)))")
    assert widths == [160, 160, 160]
    errors = page.eval_on_selector_all(".card.error .err", "es => es.map(e => e.textContent)")
    assert any("model.glb: not a readable glTF/GLB file" in e for e in errors), errors
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    page.screenshot(path=str(ARTIFACTS / "grid.png"), full_page=True)


def test_filter_by_name_and_folder_and_sort_by_duration(page, gallery):
    """Typing filters by name, the folder menu by folder; sorting by duration orders the
    cards by the index's durations (failed scenes, without one, last)."""
    page.fill("#filter", "walk")
    assert shown(page) == ["walks/walk.bvh"]
    page.fill("#filter", "")
    page.select_option("#folder", "jumps")
    assert shown(page) == ["jumps/jump.bvh", "jumps/truncated.bvh"]
    page.select_option("#folder", "*")
    page.select_option("#sort", "duration")
    dur = {r["path"]: r["duration_s"] for r in gallery[1].rows}
    order = shown(page)
    values = [dur[p] if dur[p] is not None else float("inf") for p in order]
    assert values == sorted(values) and len(order) == 6
    page.select_option("#sort", "-duration")
    assert shown(page)[0] == max((p for p in dur if dur[p] is not None), key=lambda p: dur[p])
    page.select_option("#sort", "name")


def test_clicking_a_scene_opens_its_sheet_and_json(page, gallery):
    """A click opens the scene: its contact sheet (loaded), its numbers and its snapshot
    JSON (the document itself, in the page)."""
    out, report = gallery
    row = next(r for r in report.rows if r["path"] == "duo/duo.toml")
    page.click('.card[data-path="duo/duo.toml"]')
    page.wait_for_selector("#detail[open]")
    assert page.inner_text("#d-title") == "duo/duo.toml"
    assert page.eval_on_selector("#d-img", "i => i.decode().then(() => i.naturalWidth)") > 0
    assert page.get_attribute("#d-img", "src") == row["sheet"]
    assert f"frame {row['frame']}" in page.inner_text("#d-table")
    frame = page.frame_locator("#d-json")
    assert '"format": "action-snapshot/snapshot@2"' in frame.locator("body").inner_text()
    links = page.eval_on_selector_all("#d-links a", "as => as.map(a => a.href)")
    assert [Path(lk.removeprefix("file://")) for lk in links] == \
        [out / row["json"], out / row["thumb"], out / row["sheet"]]
    page.screenshot(path=str(ARTIFACTS / "scene.png"))
    page.click("#close")
    assert page.query_selector("#detail[open]") is None


def test_nothing_is_requested_from_outside_the_folder(page, gallery):
    """No server, no outside request: every URL the page asked for is a file in OUT."""
    out = gallery[0]
    assert page.requests
    for url in page.requests:
        assert url.startswith("file://"), url
        assert Path(unquote(url.removeprefix("file://"))).resolve().is_relative_to(
            out.resolve()), url


def test_names_are_text_not_markup():
    """A file name or error with markup in it stays data: parsed as HTML, the page has
    no element it did not write, and the embedded rows read back unchanged."""
    from html.parser import HTMLParser

    row = {"path": "x/</script><b>.bvh", "folder": "x", "name": "</script><b>.bvh",
           "status": "error", "error": "<img src=x onerror=alert(1)>"}

    class Tags(HTMLParser):
        def __init__(self):
            super().__init__()
            self.tags, self.data, self._in = [], "", False

        def handle_starttag(self, tag, attrs):
            self.tags.append(tag)
            self._in = ("id", "rows") in attrs

        def handle_data(self, data):
            if self._in:
                self.data += data

        def handle_endtag(self, tag):
            self._in = False

    parser = Tags()
    parser.feed(gallery_html([row]))
    assert "b" not in parser.tags and "img" in parser.tags  # the dialog's own <img> only
    assert parser.tags.count("img") == 1 and parser.tags.count("script") == 2
    assert json.loads(parser.data)[0]["path"] == row["path"]
