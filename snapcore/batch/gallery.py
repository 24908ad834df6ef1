"""The gallery of a batch: one static ``OUT/index.html`` to browse the library.

Opened straight from disk (``file://``), no server and no outside request: the index
rows are embedded in the page as JSON (a page on ``file://`` may not ``fetch`` files
beside it), the pictures and snapshot documents are relative links. It works as an
asset browser: a folder tree whose folders include their sub-folders, filters (name,
errors and warnings, file type, rig, frame rate, characters, length), sorting, a
thumbnail-size slider, and scrubbing through the whole motion by moving over a card
(the scene's preview strip, ``--preview``). The summary names the files the run left
out (a ``.json`` that does not parse, a JSON that is not a scene manifest).

Clicking a scene opens it: picture, numbers, full warnings, copy path, previous and
next, and a frame slider over the whole clip to choose any frame (or one of the top
poses) as its thumbnail. Choices are source frames. Served by ``snapshot gallery OUT``
(:mod:`snapcore.batch.serve`) a choice is written into ``OUT/thumb-choices.csv`` at
once; from disk the page keeps it in the browser and offers the whole set as that file
to save into OUT. The next run renders the chosen frames (:mod:`snapcore.batch.choices`).
The page's script and style are ``gallery.js`` and ``gallery.css`` beside this module.
"""

from __future__ import annotations

import html
import json
from pathlib import Path

from snapcore.batch.index import atomic_write

__all__ = ["write_gallery", "gallery_html", "GALLERY_NAME"]

GALLERY_NAME = "index.html"
#: Row fields the page uses (hashes and timings but the total stay in the CSV).
_FIELDS = (
    "path",
    "folder",
    "name",
    "kind",
    "status",
    "error",
    "warnings",
    "characters",
    "rig",
    "n_frames",
    "fps",
    "duration_s",
    "frame",
    "time_s",
    "first_frame",
    "top_frames",
    "score",
    "thumb_frame",
    "thumb_choice",
    "view_x",
    "view_y",
    "view_z",
    "json",
    "thumb",
    "sheet",
    "preview",
    "preview_frames",
    "t_total_s",
)
_HERE = Path(__file__).resolve().parent


def gallery_html(
    rows,
    *,
    title: str = "Action Snapshot gallery",
    ratio: float = 320 / 360,
    skipped=(),
    choices=None,
    root=None,
) -> str:
    """The gallery page for index ``rows`` (dicts as in the index).

    Parameters
    ----------
    rows : sequence of dict
    title : str
    ratio : float
        Width / height of the thumbnails (the grid keeps their shape).
    skipped : sequence of (str, str)
        Files the run left out and why, listed with the summary.
    choices : dict of str to (int or None), optional
        The entries of ``OUT/thumb-choices.csv`` (some may not be rendered yet): the
        page starts from them, so that a save from disk holds every choice.
    root : path-like, optional
        The library root the keys are relative to (the copied path is absolute then).

    Returns
    -------
    str
        A complete HTML document; its only links are relative paths from the rows.
    """
    data = [{k: r.get(k) for k in _FIELDS} for r in rows]
    meta = {
        "skipped": [[str(p), str(why)] for p, why in skipped],
        "choices": dict(choices or {}),
        "root": None if root is None else Path(root).resolve().as_posix(),
    }
    # "</" would end the script element early; "<\/" reads the same to JSON.parse
    payload = json.dumps(data, allow_nan=False).replace("</", "<\\/")
    meta_json = json.dumps(meta, allow_nan=False).replace("</", "<\\/")
    t = html.escape(title)
    css = (_HERE / "gallery.css").read_text(encoding="utf-8")
    js = (_HERE / "gallery.js").read_text(encoding="utf-8")
    return f"""<!doctype html>
<html lang="en"><head><meta charset="utf-8">
<meta name="viewport" content="width=device-width,initial-scale=1">
<title>{t}</title><style>{css}:root{{--ratio:{ratio:.4f}}}</style></head>
<body>
<header><h1>{t}</h1>
<input id="filter" type="search" placeholder="filter by name" aria-label="filter by name">
<button id="more" type="button" aria-expanded="false">filters</button>
<div id="filters">
<label>show <select id="status"><option value="*">all</option>
<option value="error">errors only</option><option value="warning">with warnings</option>
<option value="clean">ok, no warnings</option>
<option value="chosen">thumbnail chosen</option></select></label>
<label>type <select id="kind"><option value="*">all</option></select></label>
<label>rig <select id="rig"><option value="*">all</option></select></label>
<label>fps <select id="fps"><option value="*">all</option></select></label>
<label>characters <select id="chars"><option value="*">all</option></select></label>
<label>length <input id="len-min" type="number" min="0" step="0.5" placeholder="min"
aria-label="shortest, seconds">–<input id="len-max" type="number" min="0" step="0.5"
placeholder="max" aria-label="longest, seconds"> s</label>
</div>
<label>sort <select id="sort"><option value="name">name</option>
<option value="-score">score (highest first)</option>
<option value="score">score (lowest first)</option>
<option value="duration">length (shortest first)</option>
<option value="-duration">length (longest first)</option></select></label>
<label class="size">size <input id="size" type="range" min="110" max="360" step="10"
value="190" aria-label="thumbnail size"></label>
<span id="count"></span>
<details id="summary"><summary id="summary-line"></summary><ul id="skipped"></ul></details>
<span id="choices" hidden><span id="n-choices"></span>
<a id="save" download="thumb-choices.csv" href="#">save thumb-choices.csv</a><span
id="save-note"> into this folder, then run the batch again</span></span></header>
<div id="body"><nav id="tree" aria-label="folders"></nav><main id="grid"></main></div>
<dialog id="detail"><div class="bar"><button id="prev" type="button">← previous</button>
<button id="next" type="button">next →</button><button id="copy" type="button">copy
path</button><span id="copied" role="status"></span><button id="close"
type="button">close</button></div>
<h2 id="d-title"></h2>
<div id="d-pics"><img id="d-img" alt="thumbnail"><div id="d-scrub" role="img"
aria-label="frame preview"></div></div>
<div id="d-frame"><label>frame <input id="d-slider" type="range" step="1"></label>
<output id="d-at"></output><button id="d-use" type="button">use as thumbnail</button>
<button id="d-reset" type="button">back to the chosen pose</button></div>
<div id="d-poses"></div>
<table id="d-table"></table><ul id="d-warnings"></ul>
<div class="links" id="d-links"></div><iframe id="d-json" title="snapshot JSON"></iframe>
</dialog>
<script id="rows" type="application/json">{payload}</script>
<script id="meta" type="application/json">{meta_json}</script>
<script>{js}</script>
</body></html>
"""


def write_gallery(
    out,
    rows,
    *,
    title: str = "Action Snapshot gallery",
    size: tuple[int, int] = (320, 360),
    skipped=(),
    root=None,
) -> Path:
    """Write ``OUT/index.html`` for ``rows`` (atomically) and return its path; the
    choices in ``OUT/thumb-choices.csv`` go into the page."""
    from snapcore.batch.choices import read_choices

    path = Path(out) / GALLERY_NAME
    page = gallery_html(
        rows,
        title=title,
        ratio=size[0] / size[1],
        skipped=skipped,
        choices=read_choices(out, rows),
        root=root,
    )
    atomic_write(path, page)
    return path
