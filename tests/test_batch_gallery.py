"""The batch gallery in a real browser: opened from disk, it loads, filters, sorts, opens
a scene (contact sheet and JSON), and asks for nothing outside its folder; served by
`snapshot gallery`, a chosen frame is saved into OUT and the next runs render it.

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
    # a sub-folder of a sub-folder, and a would-be manifest that does not parse
    (lib / "studio" / "day1").mkdir(parents=True)
    write_bvh(synth.humanoid_document("punch", seconds=1.0), lib / "studio" / "day1" / "take.bvh")
    (lib / "studio" / "scene.json").write_text('{"characters": [', encoding="utf-8")
    return lib


@pytest.fixture(scope="module")
def gallery(glib, tmp_path_factory):
    """A real batch of that library (sheets): OUT folder and report."""
    lib = glib
    out = tmp_path_factory.mktemp("gout") / "out"
    found = discover([lib])
    report = run_batch(found.scenes, out, OPTS, skipped=found.left_out, root=lib)
    assert report.done == 8
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
    the failed ones their error; each card names the frame its thumbnail shows."""
    _, report = gallery
    assert sorted(shown(page)) == sorted(r["path"] for r in report.rows)
    assert page.inner_text("#count") == "8 of 8 scenes"
    widths = page.eval_on_selector_all(
        ".card img", "is => Promise.all(is.map(i => i.decode().then(() => i.naturalWidth)))"
    )
    assert widths == [160] * 5
    errors = page.eval_on_selector_all(".card.error .err", "es => es.map(e => e.textContent)")
    assert any("model.glb: not a readable glTF/GLB file" in e for e in errors), errors
    walk = next(r for r in report.rows if r["path"] == "walks/walk.bvh")
    meta = page.inner_text('.card[data-path="walks/walk.bvh"] .meta')
    assert f"thumbnail: frame {walk['frame']} (best pose)" in meta
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    page.screenshot(path=str(ARTIFACTS / "grid.png"), full_page=True)


def test_the_summary_lists_the_json_that_does_not_parse(page, gallery):
    """A would-be scene manifest that does not parse is named, with why, where the
    gallery gives the run's summary (it once showed up only as a line on stderr)."""
    line = page.inner_text("#summary-line")
    assert line == "8 scenes, 3 with errors, 2 files skipped", line
    page.click("#summary-line")
    items = page.eval_on_selector_all("#skipped li", "ls => ls.map(l => l.textContent)")
    broken = [t for t in items if t.split(" — ")[0].endswith("studio/scene.json")]
    assert broken and "does not parse" in broken[0], items
    assert any("notes.json" in t and "no characters list" in t for t in items), items
    page.screenshot(path=str(ARTIFACTS / "summary.png"))
    page.click("#summary-line")


def test_the_folder_tree_includes_sub_folders_and_filters_narrow_the_grid(page, gallery):
    """A folder of the tree shows its scenes and its sub-folders' (with counts); name,
    length, type, rig, fps and character filters keep exactly the rows that match; a
    sort by length follows the index (failed scenes last)."""
    rows = {r["path"]: r for r in gallery[1].rows}
    page.click('#tree .node[data-folder="studio"] .label')
    assert shown(page) == ["studio/day1/take.bvh"]
    assert page.inner_text('#tree .node[data-folder="studio"] .n') == "1"
    page.click('#tree .node[data-folder="jumps"]')
    assert shown(page) == ["jumps/jump.bvh", "jumps/truncated.bvh"]
    page.click('#tree .node[data-folder=""]')
    assert len(shown(page)) == 8
    page.fill("#filter", "walk")
    assert shown(page) == ["walks/walk.bvh"]
    page.fill("#filter", "")
    page.fill("#len-min", "1.2")
    page.fill("#len-max", "1.6")
    assert sorted(shown(page)) == sorted(
        p for p, r in rows.items() if r["duration_s"] is not None and 1.2 <= r["duration_s"] <= 1.6
    )
    page.fill("#len-min", "")
    page.fill("#len-max", "")
    page.select_option("#kind", "manifest")
    assert sorted(shown(page)) == ["duo/duo.toml", "pair/pair.toml"]
    page.select_option("#kind", "*")
    page.select_option("#chars", "2")
    assert sorted(shown(page)) == ["duo/duo.toml", "pair/pair.toml"]
    page.select_option("#chars", "*")
    rig = rows["walks/walk.bvh"]["rig"]
    page.select_option("#rig", rig)
    assert sorted(shown(page)) == sorted(p for p, r in rows.items() if r["rig"] == rig)
    page.select_option("#rig", "*")
    page.select_option("#fps", "30")
    assert len(shown(page)) == 5
    page.select_option("#fps", "*")
    page.select_option("#sort", "duration")
    order = shown(page)
    values = [rows[p]["duration_s"] if rows[p]["duration_s"] is not None else 1e9 for p in order]
    assert values == sorted(values) and len(order) == 8
    page.select_option("#sort", "name")


def test_the_size_slider_changes_the_cards_width(page, gallery):
    """The thumbnail-size control sets the width of the grid's cards."""

    def width():
        return page.eval_on_selector(".card", "c => c.getBoundingClientRect().width")

    page.fill("#size", "120")
    page.dispatch_event("#size", "input")
    small = width()
    page.fill("#size", "320")
    page.dispatch_event("#size", "input")
    big = width()
    assert 120 <= small < 180 and big >= 320, (small, big)
    page.fill("#size", "190")
    page.dispatch_event("#size", "input")


def test_clicking_a_scene_opens_its_sheet_and_json(page, gallery, glib):
    """A click opens the scene: its contact sheet (loaded), its numbers and its snapshot
    JSON (the document itself, in the page); next and previous walk the grid's order;
    copy path copies the file's absolute path."""
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
        out / row["preview"],
    ]
    page.click("#next")
    assert page.inner_text("#d-title") == shown(page)[shown(page).index("duo/duo.toml") + 1]
    page.click("#prev")
    assert page.inner_text("#d-title") == "duo/duo.toml"
    page.click("#copy")
    assert page.inner_text("#copied") == f"copied: {glib.resolve().as_posix()}/duo/duo.toml"
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
    parser.feed(gallery_html([row], skipped=[("y/</script><i>.json", "why <u>")]))
    assert (
        not {"b", "i", "u"} & set(parser.tags) and "img" in parser.tags
    )  # the dialog's own <img> only
    assert parser.tags.count("img") == 1 and parser.tags.count("script") == 3
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


def test_status_filters_and_full_warnings(page, gallery):
    """'errors only' shows exactly the failed scenes, 'with warnings' those with a
    warning, whose card shows it whole (it once showed one cut line, often only the
    file's path) and whose detail view lists each; sorting by score follows the index's
    scores, highest first, failed scenes last."""
    rows = {r["path"]: r for r in gallery[1].rows}
    page.select_option("#status", "error")
    assert sorted(shown(page)) == sorted(p for p, r in rows.items() if r["status"] == "error")
    page.select_option("#status", "warning")
    warned = sorted(p for p, r in rows.items() if r["warnings"])
    assert "pair/pair.toml" in warned and sorted(shown(page)) == warned
    card = '.card[data-path="pair/pair.toml"] .warn'
    assert all(w in page.text_content(card) for w in rows["pair/pair.toml"]["warnings"])
    assert "different frame counts" in page.text_content(card)
    page.click('.card[data-path="pair/pair.toml"]')
    items = page.eval_on_selector_all("#d-warnings li", "ls => ls.map(l => l.textContent)")
    assert items == rows["pair/pair.toml"]["warnings"]
    page.click("#close")
    page.select_option("#status", "clean")
    assert sorted(shown(page)) == sorted(
        p for p, r in rows.items() if r["status"] == "ok" and not r["warnings"]
    )
    page.select_option("#status", "*")
    page.select_option("#sort", "-score")
    scores = [rows[p]["score"] for p in shown(page)]
    good = [x for x in scores if x is not None]
    assert len(good) == 5 and good == sorted(good, reverse=True)
    assert scores[: len(good)] == good  # the failed scenes, without a score, last
    page.select_option("#sort", "name")


def test_moving_over_a_card_scrubs_through_the_whole_motion(page, gallery):
    """Moving the pointer across a card shows the preview strip's panel under it: at
    the left edge the first frame, at the right edge the last, the card saying which."""
    row = next(r for r in gallery[1].rows if r["path"] == "walks/walk.bvh")
    card = '.card[data-path="walks/walk.bvh"]'
    box = page.eval_on_selector(
        card + " .pic",
        "p => { const b = p.getBoundingClientRect(); return [b.x, b.y, b.width, b.height]; }",
    )
    x, y, w, h = box
    page.mouse.move(x + 2, y + h / 2)
    page.mouse.move(x + 3, y + h / 2)
    assert page.inner_text(card + " .at") == f"frame {row['preview_frames'][0]}"
    scrub = page.eval_on_selector(
        card + " .scrub",
        "s => [getComputedStyle(s).display, getComputedStyle(s).backgroundImage,"
        " getComputedStyle(s).backgroundPosition]",
    )
    assert scrub[0] == "block" and row["preview"].rsplit("/", 1)[-1] in scrub[1]
    assert scrub[2].startswith("0%")
    page.mouse.move(x + w - 2, y + h / 2)
    assert page.inner_text(card + " .at") == f"frame {row['preview_frames'][-1]}"
    assert page.eval_on_selector(
        card + " .scrub", "s => getComputedStyle(s).backgroundPosition"
    ).startswith("100%")
    page.screenshot(path=str(ARTIFACTS / "scrub.png"))
    page.mouse.move(0, 0)
    assert page.eval_on_selector(card + " .scrub", "s => getComputedStyle(s).display") == "none"


def test_on_a_phone_the_grid_has_two_columns_and_the_header_scrolls_away(page, gallery):
    """At 390x844 (a phone): two cards a row, a header that is not sticky and takes
    less than a fifth of the screen; the folder tree opens folder by folder."""
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
        # the tree starts with the top folders; a tapped folder opens and filters
        day1 = '#tree .node[data-folder="studio/day1"]'
        assert not pg.is_visible(day1)
        pg.click('#tree .node[data-folder="studio"] .label')
        # the tree opens in the page's click handler: wait for it (on a loaded machine
        # the check ran before the handler had)
        pg.wait_for_selector(day1, state="visible", timeout=10_000)
        pg.wait_for_function(
            "() => [...document.querySelectorAll('.card')].map(c => c.dataset.path).join()"
            " === 'studio/day1/take.bvh'",
            timeout=10_000,
        )
        assert shown(pg) == ["studio/day1/take.bvh"]
    finally:
        pg.close()


@pytest.fixture
def served(gallery, tmp_path):
    """A copy of the gallery's OUT served by `snapshot gallery OUT --port 0`: (OUT, URL)."""
    import shutil
    import subprocess
    import sys

    out = tmp_path / "out"
    shutil.copytree(gallery[0], out)
    snapshot = str(Path(sys.executable).with_name("snapshot"))
    proc = subprocess.Popen(
        [snapshot, "gallery", str(out), "--port", "0"], stdout=subprocess.PIPE, text=True
    )
    try:
        line = proc.stdout.readline()
        assert " at http://" in line, line
        yield out, line.split(" at ", 1)[1].split()[0]
    finally:
        proc.terminate()
        proc.wait(timeout=10)


def _pick(page, frame: int) -> None:
    """Move the detail view's frame slider to ``frame`` and use it as the thumbnail."""
    page.eval_on_selector(
        "#d-slider",
        "(s, f) => { s.value = String(f); s.dispatchEvent(new Event('input')); }",
        frame,
    )
    assert page.inner_text("#d-at").startswith(f"frame {frame} ")
    page.click("#d-use")


def test_a_frame_chosen_in_the_served_gallery_stays_the_thumbnail(page, served, gallery, glib):
    """Served by `snapshot gallery`, choosing any frame (not one of the top poses) in
    the detail view writes it into OUT/thumb-choices.csv at once, a second choice
    keeping the first; a re-run with --force, then one with --pose-method paper, renders
    that frame as the thumbnail, and the page says so."""
    import numpy as np
    from test_batch_rerun import _thumb_is_frame

    from snapcore.batch.index import read_index

    out, url = served
    rows = {r["path"]: r for r in gallery[1].rows}
    walk = rows["walks/walk.bvh"]
    chosen = next(f for f in range(walk["first_frame"] + 3, 99) if f not in walk["top_frames"])
    pg = page.context.browser.new_page()
    pg.set_viewport_size({"width": 1200, "height": 900})
    try:
        pg.goto(url)
        pg.wait_for_selector(".card")
        pg.click('.card[data-path="walks/walk.bvh"]')
        _pick(pg, chosen)
        pg.wait_for_selector("#choices.saved")
        assert "saved into thumb-choices.csv" in pg.inner_text("#choices")
        pg.click("#prev")  # another scene's choice must not replace the first
        second = pg.inner_text("#d-title")
        frame2 = rows[second]["first_frame"] + 2
        _pick(pg, frame2)
        pg.wait_for_function(
            "n => document.querySelector('#choices').textContent.includes('frame ' + n)", arg=frame2
        )
        pg.click("#close")
        assert (out / "thumb-choices.csv").read_text() == (
            f"path,frame\n{second},{frame2}\nwalks/walk.bvh,{chosen}\n"
        )
        assert "not rendered yet" in pg.inner_text('.card[data-path="walks/walk.bvh"] .badge')
        paper = BatchOptions(
            snapshot={"baselines": False, "pose_method": "paper"},
            size=OPTS.size,
            sheet=True,
            sheet_size=OPTS.sheet_size,
        )
        for opts, force in ((OPTS, True), (paper, False)):
            run_batch(discover([glib]).scenes, out, opts, force=force)
            row = next(r for r in read_index(out / "index.csv") if r["path"] == "walks/walk.bvh")
            assert (row["thumb_frame"], row["thumb_choice"]) == (chosen, chosen)
            assert _thumb_is_frame(out, row, glib / "walks" / "walk.bvh", chosen, OPTS.size)
            pg.reload()
            pg.wait_for_selector(".card")
            card = '.card[data-path="walks/walk.bvh"]'
            assert f"thumbnail: frame {chosen} (your choice)" in pg.inner_text(card + " .meta")
            assert pg.inner_text(card + " .badge") == f"frame {chosen}"
            src = pg.eval_on_selector(card + " img", "i => i.decode().then(() => i.currentSrc)")
            assert src.endswith(row["thumb"])
        assert row["options_hash"] != walk["options_hash"]  # the paper run did redo it
        assert np.isfinite(row["score"])
        pg.screenshot(path=str(ARTIFACTS / "chosen.png"))
    finally:
        pg.close()


def test_from_disk_the_saved_file_holds_every_choice(page, gallery, tmp_path):
    """Opened from disk, a new choice is offered as a thumb-choices.csv that also holds
    the choices already in OUT (a second save once replaced the first); the server
    refuses a frame the clip does not have and a page of another origin."""
    import json as js
    import urllib.request
    from urllib.error import HTTPError
    from urllib.parse import unquote as unq

    from snapcore.batch.choices import write_choices
    from snapcore.batch.gallery import write_gallery
    from snapcore.batch.serve import gallery_server

    out = tmp_path / "out"
    import shutil

    shutil.copytree(gallery[0], out)
    rows = {r["path"]: r for r in gallery[1].rows}
    write_choices(out, {"jumps/jump.bvh": rows["jumps/jump.bvh"]["first_frame"] + 4})
    write_gallery(out, gallery[1].rows, size=OPTS.size)
    pg = page.context.browser.new_page()
    try:
        pg.goto((out / "index.html").as_uri())
        pg.evaluate("localStorage.clear()")
        pg.reload()
        pg.click('.card[data-path="walks/walk.bvh"]')
        walk = rows["walks/walk.bvh"]
        _pick(pg, walk["first_frame"] + 1)
        pg.click("#close")
        assert pg.is_visible("#choices") and pg.is_visible("#save")
        csv_text = unq(pg.get_attribute("#save", "href").split(",", 1)[1])
        assert csv_text == (
            f'path,frame\n"jumps/jump.bvh",{rows["jumps/jump.bvh"]["first_frame"] + 4}\n'
            f'"walks/walk.bvh",{walk["first_frame"] + 1}\n'
        )
        pg.evaluate("localStorage.clear()")
    finally:
        pg.close()
    server = gallery_server(out, port=0)
    import threading

    threading.Thread(target=server.serve_forever, daemon=True).start()
    base = f"http://127.0.0.1:{server.server_address[1]}"

    def post(doc, origin=None):
        req = urllib.request.Request(
            f"{base}/choices",
            data=js.dumps(doc).encode(),
            method="POST",
            headers={"Content-Type": "application/json", **({"Origin": origin} if origin else {})},
        )
        try:
            with urllib.request.urlopen(req) as r:
                return r.status, js.loads(r.read())
        except HTTPError as err:
            return err.code, js.loads(err.read())

    try:
        before = (out / "thumb-choices.csv").read_text()
        code, answer = post({"walks/walk.bvh": 10_000})
        assert code == 400 and "frame 10000 is not in the clip" in answer["error"]
        code, answer = post({"nowhere.bvh": 3})
        assert code == 400 and "not a scene of this gallery" in answer["error"]
        code, answer = post({"walks/walk.bvh": 5}, origin="http://evil.example")
        assert code == 403
        assert (out / "thumb-choices.csv").read_text() == before
        code, answer = post({"walks/walk.bvh": walk["first_frame"]})
        assert code == 200
        with urllib.request.urlopen(f"{base}/choices") as r:
            assert js.loads(r.read()) == {
                "jumps/jump.bvh": rows["jumps/jump.bvh"]["first_frame"] + 4,
                "walks/walk.bvh": walk["first_frame"],
            }
    finally:
        server.shutdown()
        server.server_close()
