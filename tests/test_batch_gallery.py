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
from snapcore.motion import synth
from snapcore.motion.bvh import write_bvh

pytestmark = [pytest.mark.browser, pytest.mark.slow]

ARTIFACTS = Path(__file__).resolve().parents[1] / "var" / "test-artifacts" / "batch"
OPTS = BatchOptions(
    snapshot={"baselines": False}, size=(160, 180), sheet=True, sheet_size=(120, 135)
)


@pytest.fixture(scope="module")
def glib(tmp_path_factory):
    """The small library (with broken files) and a pair of clips of different lengths:
    a scene with a warning."""
    lib = make_library(tmp_path_factory.mktemp("glib") / "lib")
    (lib / "pair").mkdir()
    write_bvh(synth.humanoid_document("kick", seconds=1.5), lib / "pair" / "p1.bvh")
    write_bvh(synth.humanoid_document("walk", seconds=2.0), lib / "pair" / "p2.bvh")
    (lib / "pair" / "pair.toml").write_text(
        '[[characters]]\nfile = "p1.bvh"\n[[characters]]\nfile = "p2.bvh"\n'
        "offset = [1.5, 0.0, 0.0]\n",
        encoding="utf-8",
    )
    return lib


@pytest.fixture(scope="module")
def gallery(glib, tmp_path_factory):
    """A real batch of that library (sheets): OUT folder and report."""
    lib = glib
    out = tmp_path_factory.mktemp("gout") / "out"
    report = run_batch(discover([lib]).scenes, out, OPTS)
    assert report.done == 7
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
    assert page.inner_text("#count") == "7 of 7 scenes"
    widths = page.eval_on_selector_all(
        ".card img", "is => Promise.all(is.map(i => i.decode().then(() => i.naturalWidth)))"
    )
    assert widths == [160, 160, 160, 160]
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
    assert values == sorted(values) and len(order) == 7
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
    assert [Path(lk.removeprefix("file://")) for lk in links] == [
        out / row["json"],
        out / row["thumb"],
        out / row["sheet"],
    ]
    page.screenshot(path=str(ARTIFACTS / "scene.png"))
    page.click("#close")
    assert page.query_selector("#detail[open]") is None


def test_nothing_is_requested_from_outside_the_folder(page, gallery):
    """No server, no outside request: every URL the page asked for is a file in OUT."""
    out = gallery[0]
    assert page.requests
    for url in page.requests:
        assert url.startswith("file://"), url
        assert Path(unquote(url.removeprefix("file://"))).resolve().is_relative_to(out.resolve()), (
            url
        )


def test_names_are_text_not_markup():
    """A file name or error with markup in it stays data: parsed as HTML, the page has
    no element it did not write, and the embedded rows read back unchanged."""
    from html.parser import HTMLParser

    row = {
        "path": "x/</script><b>.bvh",
        "folder": "x",
        "name": "</script><b>.bvh",
        "status": "error",
        "error": "<img src=x onerror=alert(1)>",
    }

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


def test_an_error_opened_after_a_scene_shows_no_picture(page, gallery):
    """The detail view of a failed scene opened right after a good one shows its error
    and no picture (the previous clip's sheet once stayed, `display: block` winning
    over `hidden`)."""
    page.click('.card[data-path="walks/walk.bvh"]')
    page.wait_for_selector("#detail[open]")
    assert page.is_visible("#d-img")
    page.click("#close")
    page.click('.card[data-path="notes.bvh"]')
    page.wait_for_selector("#detail[open]")
    assert not page.is_visible("#d-img")
    assert not page.is_visible("#d-json")
    assert "error: notes.bvh:" in page.inner_text("#d-table")
    page.screenshot(path=str(ARTIFACTS / "error.png"))
    page.click("#close")


def test_status_filters_warnings_on_cards_and_sort_by_score(page, gallery):
    """'errors only' shows exactly the failed scenes, 'with warnings' those with a
    warning, whose card shows it; sorting by score follows the index's scores, highest
    first, failed scenes last."""
    rows = {r["path"]: r for r in gallery[1].rows}
    page.select_option("#status", "error")
    assert sorted(shown(page)) == sorted(p for p, r in rows.items() if r["status"] == "error")
    page.select_option("#status", "warning")
    warned = sorted(p for p, r in rows.items() if r["warnings"])
    assert "pair/pair.toml" in warned and sorted(shown(page)) == warned
    text = page.inner_text('.card[data-path="pair/pair.toml"] .warn')
    assert "different frame counts" in text
    page.select_option("#status", "clean")
    assert sorted(shown(page)) == sorted(
        p for p, r in rows.items() if r["status"] == "ok" and not r["warnings"]
    )
    page.select_option("#status", "*")
    page.select_option("#sort", "-score")
    order = shown(page)
    scores = [rows[p]["score"] for p in order]
    good = [x for x in scores if x is not None]
    assert len(good) == 4 and good == sorted(good, reverse=True)
    assert scores[: len(good)] == good  # the failed scenes, without a score, last
    page.select_option("#sort", "name")


def test_hovering_a_card_flips_through_its_top_poses(page, gallery):
    """With contact sheets, hovering a card shows its sheet panned pose by pose (a CSS
    animation over the sheet already made, no extra file)."""
    # a scene with several top poses (a one-peak clip, such as the jump, has one moment)
    many = next(
        r
        for r in gallery[1].rows
        if r["status"] == "ok" and len(str(r["top_frames"] or "").split(";")) > 1
    )
    sheet = many["path"].rsplit("/", 1)[-1] + ".sheet.png"
    card = f'.card[data-path="{many["path"]}"]'
    flip = page.query_selector(card + " .flip")
    assert flip is not None and flip.get_attribute("data-sheet").endswith(sheet)
    assert flip.evaluate("e => getComputedStyle(e).opacity") == "0"
    page.hover(card)
    page.wait_for_timeout(300)
    style = flip.evaluate(
        "e => [getComputedStyle(e).opacity, getComputedStyle(e).animationName,"
        " getComputedStyle(e).backgroundImage]"
    )
    assert style[:2] == ["1", "flip"] and sheet in style[2]
    # one panel a card: the sheet is drawn as wide as its top poses side by side
    k = len(many["top_frames"].split(";"))
    assert flip.evaluate("e => getComputedStyle(e).backgroundSize") == f"{100 * k}% auto"
    page.screenshot(path=str(ARTIFACTS / "hover.png"))
    page.mouse.move(0, 0)


def test_choosing_pose_2_as_thumbnail_is_saved_and_a_rerun_renders_it(
    page, gallery, glib, tmp_path
):
    """In the detail view, '#2' becomes the scene's thumbnail choice: the card says so,
    the page offers thumb-choices.csv; saved into OUT, a re-run renders pose #2 as the
    thumbnail (the still of that frame) and the index keeps thumb_pose = 2, also through
    the next re-run."""
    import io
    import shutil
    from urllib.parse import unquote as unq

    import numpy as np
    from PIL import Image

    from snapcore.batch.index import read_index
    from snapcore.motion.load import load_scene
    from snapcore.render.renderer import render_still

    out = tmp_path / "out"
    shutil.copytree(gallery[0], out)
    page.click('.card[data-path="walks/walk.bvh"]')
    page.wait_for_selector("#detail[open]")
    page.click("#d-poses button:nth-of-type(2)")
    assert page.get_attribute("#d-poses button:nth-of-type(2)", "aria-pressed") == "true"
    page.click("#close")
    assert "pose #2" in page.inner_text('.card[data-path="walks/walk.bvh"] .badge')
    assert page.is_visible("#choices")
    page.screenshot(path=str(ARTIFACTS / "choice.png"))
    href = page.get_attribute("#save", "href")
    csv_text = unq(href.split(",", 1)[1])
    assert csv_text == 'path,pose\n"walks/walk.bvh",2\n'
    (out / "thumb-choices.csv").write_text(csv_text, encoding="utf-8")
    src = glib
    report = run_batch(discover([src]).scenes, out, OPTS)
    assert report.done == 1
    row = next(r for r in read_index(out / "index.csv") if r["path"] == "walks/walk.bvh")
    assert row["thumb_pose"] == 2
    second = int(row["top_frames"].split(";")[1])
    scene = load_scene([str(src / "walks" / "walk.bvh")])
    expected = render_still(
        scene,
        scene.internal_frame(second),
        np.array([row["view_x"], row["view_y"], row["view_z"]]),
        size=OPTS.size,
    )[..., :3]
    thumb = np.asarray(Image.open(io.BytesIO((out / row["thumb"]).read_bytes())).convert("RGB"))
    assert np.abs(thumb.astype(int) - expected).max() <= 1
    (out / "thumb-choices.csv").unlink()
    again = run_batch(discover([src]).scenes, out, OPTS)
    assert again.done == 0
    assert next(r for r in again.rows if r["path"] == "walks/walk.bvh")["thumb_pose"] == 2
    page.evaluate("localStorage.clear()")


def test_on_a_phone_the_grid_has_two_columns_and_the_header_scrolls_away(page, gallery):
    """At 390x844 (a phone): two cards a row, a header that is not sticky and takes
    less than a fifth of the screen."""
    pg = page.context.browser.new_page(
        viewport={"width": 390, "height": 844}, device_scale_factor=2
    )
    try:
        pg.goto((gallery[0] / "index.html").as_uri())
        pg.wait_for_selector(".card")
        lefts = pg.eval_on_selector_all(
            ".card", "cs => cs.map(c => c.getBoundingClientRect().left)"
        )
        assert len(set(lefts)) == 2
        header = pg.eval_on_selector(
            "header", "h => [getComputedStyle(h).position, h.getBoundingClientRect().height]"
        )
        assert header[0] == "static" and header[1] < 844 / 5, header
        widths = pg.eval_on_selector_all(
            ".card", "cs => cs.map(c => c.getBoundingClientRect().right)"
        )
        assert max(widths) <= 390
        pg.screenshot(path=str(ARTIFACTS / "phone.png"))
    finally:
        pg.close()
