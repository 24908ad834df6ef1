"""The gallery of a batch: one static ``OUT/index.html`` to browse the library.

Opened straight from disk (``file://``), no server and no outside request: the index
rows are embedded in the page as JSON (a page on ``file://`` may not ``fetch`` files
beside it), the thumbnails, contact sheets and snapshot documents are relative links.
A grid of thumbnails, filtered by name and folder and sorted by name or duration;
clicking a scene opens its contact sheet (or thumbnail), its numbers and its JSON.
"""

from __future__ import annotations

import html
import json
from pathlib import Path

from snapcore.batch.index import atomic_write

__all__ = ["write_gallery", "gallery_html", "GALLERY_NAME"]

GALLERY_NAME = "index.html"
#: Row fields the page uses (hashes and options stay in the CSV).
_FIELDS = ("path", "folder", "name", "kind", "status", "error", "warnings", "characters",
           "n_frames", "fps", "duration_s", "frame", "time_s", "top_frames", "view_x",
           "view_y", "view_z", "json", "thumb", "sheet", "t_total_s")

_CSS = """
body{font:14px system-ui,sans-serif;margin:0;background:#f4f4f2;color:#222}
header{position:sticky;top:0;background:#fff;padding:10px 16px;border-bottom:1px solid #ddd;
display:flex;gap:12px;align-items:center;flex-wrap:wrap;z-index:1}
header h1{font-size:18px;margin:0 12px 0 0}
#grid{display:grid;grid-template-columns:repeat(auto-fill,minmax(190px,1fr));gap:12px;padding:16px}
.card{background:#fff;border:1px solid #ddd;border-radius:6px;overflow:hidden;cursor:pointer;
padding:0;text-align:left;font:inherit;color:inherit;display:flex;flex-direction:column;
justify-content:flex-start}
.card:focus,.card:hover{outline:2px solid #3a6ea5}
.card img{width:100%;aspect-ratio:var(--ratio);object-fit:contain;background:#e8e8e4;display:block}
.card .cap{padding:6px 8px}.card .name{font-weight:600;word-break:break-all}
.card .meta{color:#666;font-size:12px}
.card.error{border-color:#c33}
.card .err{color:#a22;font-size:12px;padding:8px;word-break:break-word;aspect-ratio:var(--ratio);
box-sizing:border-box;width:100%;background:#fbeeee}
dialog{max-width:min(1200px,95vw);width:95vw;border:0;border-radius:8px;padding:16px}
dialog img{max-width:100%;display:block;margin:8px 0;background:#e8e8e4}
dialog table{border-collapse:collapse;margin:8px 0}dialog td{padding:2px 10px 2px 0;vertical-align:top}
dialog iframe{width:100%;height:320px;border:1px solid #ddd}
.links a{margin-right:14px}
"""

_JS = r"""
const rows = JSON.parse(document.getElementById('rows').textContent);
const $ = (id) => document.getElementById(id);
const url = (p) => p.split('/').map(encodeURIComponent).join('/');
const fmt = (x, d) => (x === null || x === undefined) ? '' : Number(x).toFixed(d);
const folders = [...new Set(rows.map(r => r.folder))].sort();
for (const f of folders) {
  const o = document.createElement('option');
  o.value = f; o.textContent = f === '' ? '(top)' : f;
  $('folder').appendChild(o);
}
function card(r) {
  const b = document.createElement('button');
  b.className = 'card' + (r.status === 'ok' ? '' : ' error');
  b.dataset.path = r.path;
  if (r.status === 'ok') {
    const img = document.createElement('img');
    img.src = url(r.thumb); img.alt = r.name; img.loading = 'lazy';
    b.appendChild(img);
  } else {
    const e = document.createElement('div');
    e.className = 'err'; e.textContent = r.error;
    b.appendChild(e);
  }
  const cap = document.createElement('div'); cap.className = 'cap';
  const n = document.createElement('div'); n.className = 'name'; n.textContent = r.path;
  const m = document.createElement('div'); m.className = 'meta';
  m.textContent = r.status === 'ok'
    ? `${fmt(r.duration_s, 1)} s · ${r.n_frames} frames · pose at frame ${r.frame}`
    : 'error';
  cap.append(n, m); b.appendChild(cap);
  b.addEventListener('click', () => open_(r));
  return b;
}
function render() {
  const q = $('filter').value.trim().toLowerCase();
  const f = $('folder').value;
  const s = $('sort').value;
  let shown = rows.filter(r => (f === '*' || r.folder === f) &&
                               (!q || r.path.toLowerCase().includes(q)));
  const dur = (r) => r.duration_s === null ? Infinity : r.duration_s;
  if (s === 'duration') shown.sort((a, b) => dur(a) - dur(b) || a.path.localeCompare(b.path));
  else if (s === '-duration') shown.sort((a, b) => (dur(b) === Infinity ? -1 : dur(b)) -
                                                   (dur(a) === Infinity ? -1 : dur(a)) ||
                                                   a.path.localeCompare(b.path));
  else shown.sort((a, b) => a.path.localeCompare(b.path));
  $('grid').replaceChildren(...shown.map(card));
  $('count').textContent = `${shown.length} of ${rows.length} scenes`;
}
function row(t, k, v) {
  const tr = document.createElement('tr');
  const a = document.createElement('td'); a.textContent = k;
  const b = document.createElement('td'); b.textContent = v;
  tr.append(a, b); t.appendChild(tr);
}
function open_(r) {
  $('d-title').textContent = r.path;
  const img = $('d-img');
  const pic = r.sheet || r.thumb;
  img.hidden = !pic; if (pic) img.src = url(pic);
  const t = $('d-table'); t.replaceChildren();
  row(t, 'status', r.status + (r.error ? ': ' + r.error : ''));
  if (r.status === 'ok') {
    row(t, 'characters', r.characters);
    row(t, 'frames', `${r.n_frames} at ${r.fps} fps = ${fmt(r.duration_s, 2)} s`);
    row(t, 'chosen pose', `frame ${r.frame} (t = ${fmt(r.time_s, 2)} s); top: ${r.top_frames.split(';').join(', ')}`);
    row(t, 'view', `(${fmt(r.view_x, 3)}, ${fmt(r.view_y, 3)}, ${fmt(r.view_z, 3)})`);
    row(t, 'time', `${fmt(r.t_total_s, 2)} s`);
  }
  if (r.warnings) row(t, 'warnings', r.warnings);
  const links = $('d-links'); links.replaceChildren();
  for (const [label, p] of [['snapshot JSON', r.json], ['thumbnail', r.thumb], ['contact sheet', r.sheet]]) {
    if (!p) continue;
    const a = document.createElement('a'); a.href = url(p); a.textContent = label;
    a.target = '_blank'; links.appendChild(a);
  }
  const fr = $('d-json');
  fr.hidden = !r.json;
  fr.src = r.json ? url(r.json) : 'about:blank';
  $('detail').showModal();
}
$('close').addEventListener('click', () => $('detail').close());
for (const id of ['filter', 'folder', 'sort']) $(id).addEventListener('input', render);
render();
"""


def gallery_html(rows, *, title: str = "Action Snapshot gallery", ratio: float = 320 / 360) -> str:
    """The gallery page for index ``rows`` (dicts as in the index).

    Parameters
    ----------
    rows : sequence of dict
    title : str
    ratio : float
        Width / height of the thumbnails (the grid keeps their shape).

    Returns
    -------
    str
        A complete HTML document; its only links are relative paths from the rows.
    """
    data = [{k: r.get(k) for k in _FIELDS} for r in rows]
    # "</" would end the script element early; "<\/" reads the same to JSON.parse
    payload = json.dumps(data, allow_nan=False).replace("</", "<\\/")
    n_err = sum(r["status"] != "ok" for r in data)
    summary = f"{len(data)} scenes" + (f", {n_err} with errors" if n_err else "")
    t = html.escape(title)
    return f"""<!doctype html>
<html lang="en"><head><meta charset="utf-8">
<meta name="viewport" content="width=device-width,initial-scale=1">
<title>{t}</title><style>{_CSS}:root{{--ratio:{ratio:.4f}}}</style></head>
<body>
<header><h1>{t}</h1>
<input id="filter" type="search" placeholder="filter by name" aria-label="filter by name">
<label>folder <select id="folder"><option value="*">all</option></select></label>
<label>sort <select id="sort"><option value="name">name</option>
<option value="duration">duration (shortest first)</option>
<option value="-duration">duration (longest first)</option></select></label>
<span id="count"></span><span id="summary">({html.escape(summary)})</span></header>
<main id="grid"></main>
<dialog id="detail"><button id="close" type="button">close</button>
<h2 id="d-title"></h2><img id="d-img" alt="contact sheet"><table id="d-table"></table>
<div class="links" id="d-links"></div><iframe id="d-json" title="snapshot JSON"></iframe>
</dialog>
<script id="rows" type="application/json">{payload}</script>
<script>{_JS}</script>
</body></html>
"""


def write_gallery(out, rows, *, title: str = "Action Snapshot gallery",
                  size: tuple[int, int] = (320, 360)) -> Path:
    """Write ``OUT/index.html`` for ``rows`` (atomically) and return its path."""
    path = Path(out) / GALLERY_NAME
    atomic_write(path, gallery_html(rows, title=title, ratio=size[0] / size[1]))
    return path
