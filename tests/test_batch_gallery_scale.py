"""The batch gallery with a library's 2,500 scenes in a real browser (Chromium): how
long the first card, a filter and a sort take (printed, a measurement, not a timed
assertion), and the screenshots of docs/batch-gallery.md (desktop and phone).

The 2,500 rows are the real outputs of a batch over the shared motion folder (every
clip processed for real), each used under many names in a made-up studio tree
(studio / project / session / take), so that the page holds 2,500 cards, 500 leaf
folders and their pictures. Run with ``-s`` to see the table.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest
from conftest import need
from test_e2e import CHROMIUM, CHROMIUM_ARGS

from snapcore.batch import BatchOptions, discover, run_batch
from snapcore.batch.gallery import write_gallery

pytestmark = [pytest.mark.browser, pytest.mark.slow]

REPO = Path(__file__).resolve().parents[1]
ARTIFACTS = REPO / "var" / "test-artifacts" / "batch"
N_CARDS = 2500
STUDIOS = ("studioA", "studioB", "mocap_stage", "outsourced", "archive")


@pytest.fixture(scope="module")
def big(motions_dir):
    """OUT with a real batch of the motion folder and the salsa manifests, and a
    gallery of 2,500 rows made of those rows under studio paths."""
    # kept between runs under var/: a re-run of the batch skips the finished scenes
    out = ARTIFACTS / "library-out"
    found = discover([motions_dir, REPO / "snapcore" / "batch" / "scenes"])
    opts = BatchOptions(snapshot={"baselines": False}, size=(240, 270), preview=12)
    report = run_batch(found.scenes, out, opts)
    real = [r for r in report.rows if r["status"] == "ok"]
    assert len(real) >= 10
    rows = []
    for i in range(N_CARDS):
        src = real[(i * 7) % len(real)]
        studio = STUDIOS[i % len(STUDIOS)]
        folder = f"{studio}/project_{(i // 5) % 10:02d}/session_{(i // 50) % 10:02d}"
        name = f"take_{i:04d}_{src['name']}"
        rows.append(dict(src, path=f"{folder}/{name}", folder=folder, name=name))
    # a few failed scenes and warnings, as a real library has
    for i in range(0, N_CARDS, 97):
        rows[i] = dict(rows[i], status="error", error=f"{rows[i]['path']}:12: expected 'HIERARCHY'")
    write_gallery(out, rows, size=opts.size, title="Studio motion library")
    return out, rows


#: Waits (at most 5 s) for the first N thumbnails to be decoded: a lazy image below the
#: fold never loads, and its decode() would never settle.
DECODE = """n => Promise.race([
  Promise.all([...document.querySelectorAll('.card img')].slice(0, n)
    .map(i => i.decode().catch(() => 0))),
  new Promise(r => setTimeout(r, 5000))])"""


def _measure(page) -> dict:
    """Milliseconds: page start to the first render done; a name filter; a sort; each
    with the layout that follows (the next animation frame)."""
    return page.evaluate(
        """async () => {
        // the next frame (layout and paint of what changed); a timer as a bound
        const frame = () => new Promise(r => { requestAnimationFrame(() => setTimeout(r, 0));
                                              setTimeout(r, 2000); });
        const ready = performance.getEntriesByName('gallery-ready')[0].startTime;
        const first = document.querySelector('.card img');
        const t = {ready_ms: ready};
        let t0 = performance.now();
        const f = document.getElementById('filter');
        f.value = 'session_03'; f.dispatchEvent(new Event('input'));
        document.getElementById('grid').offsetHeight; await frame();
        t.filter_ms = performance.now() - t0;
        t.filtered = document.getElementById('count').textContent;
        f.value = ''; f.dispatchEvent(new Event('input')); await frame();
        const s = document.getElementById('sort');
        t0 = performance.now();
        s.value = '-duration'; s.dispatchEvent(new Event('input'));
        document.getElementById('grid').offsetHeight; await frame();
        t.sort_ms = performance.now() - t0;
        s.value = 'name'; s.dispatchEvent(new Event('input')); await frame();
        t.count = document.getElementById('count').textContent;
        t.placed = document.querySelectorAll('#grid .card').length;
        t.first_card = !!first;
        return t;
    }"""
    )


@pytest.mark.timeout(1800)
def test_2500_cards_first_card_filter_and_sort(big):
    """With 2,500 cards the page shows its first card, filters and sorts; the times are
    printed (a measurement of this machine, not a pass mark) and the grid holds every
    card, the filter exactly the matching ones."""
    sync = pytest.importorskip("playwright.sync_api")
    need(os.path.exists(CHROMIUM), f"no Chromium at {CHROMIUM}")
    out, rows = big
    with sync.sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        try:
            pg = browser.new_page(viewport={"width": 1440, "height": 900})
            pg.goto((out / "index.html").as_uri())
            pg.wait_for_selector(".card")
            t = _measure(pg)
            print(
                f"\n2,500 cards (Chromium, this machine): first render done at "
                f"{t['ready_ms']:.0f} ms, filter {t['filter_ms']:.0f} ms, "
                f"sort {t['sort_ms']:.0f} ms ({t['placed']} cards placed at first)"
            )
            assert t["count"] == f"{N_CARDS} of {N_CARDS} scenes" and t["first_card"]
            n = sum("session_03" in r["path"] for r in rows)
            assert t["filtered"] == f"{n} of {N_CARDS} scenes"
            # cards are placed as the end of the grid comes into view: all, at the bottom
            assert 0 < t["placed"] < N_CARDS
            for _ in range(40):
                pg.mouse.wheel(0, 20000)
                pg.wait_for_timeout(50)
            assert pg.eval_on_selector_all("#grid .card", "cs => cs.length") == N_CARDS
            pg.evaluate("window.scrollTo(0, 0)")
            ARTIFACTS.mkdir(parents=True, exist_ok=True)
            pg.click('#tree .node[data-folder="studioA"] .label')
            pg.wait_for_timeout(300)
            pg.evaluate(DECODE, 40)
            pg.screenshot(path=str(ARTIFACTS / "gallery_2500_desktop.png"))
            card = pg.query_selector(".card:not(.error) .pic")
            box = card.bounding_box()
            pg.mouse.move(box["x"] + box["width"] * 0.62, box["y"] + box["height"] / 2)
            pg.mouse.move(box["x"] + box["width"] * 0.63, box["y"] + box["height"] / 2)
            pg.wait_for_timeout(300)
            pg.screenshot(path=str(ARTIFACTS / "gallery_2500_scrub.png"))
            pg.click(".card:not(.error)")
            pg.wait_for_selector("#detail[open]")
            pg.wait_for_timeout(300)
            pg.screenshot(path=str(ARTIFACTS / "gallery_2500_detail.png"))
            phone = browser.new_page(viewport={"width": 390, "height": 844}, device_scale_factor=2)
            phone.goto((out / "index.html").as_uri())
            phone.wait_for_selector(".card")
            phone.evaluate(DECODE, 8)
            phone.screenshot(path=str(ARTIFACTS / "gallery_2500_phone.png"))
        finally:
            browser.close()
    docs = REPO / "docs" / "images"
    if os.environ.get("SNAPSHOT_UPDATE_DOCS"):  # refresh the pictures of docs/batch-gallery.md
        for name in ("desktop", "phone", "detail", "scrub"):
            shutil.copy(ARTIFACTS / f"gallery_2500_{name}.png", docs / f"gallery_2500_{name}.png")
