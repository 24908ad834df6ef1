"""The gallery of a batch: one static ``OUT/index.html`` to browse the library.

Opened straight from disk (``file://``), no server and no outside request: the index
rows are embedded in the page as JSON (a page on ``file://`` may not ``fetch`` files
beside it), the thumbnails, contact sheets and snapshot documents are relative links.
A grid of thumbnails, filtered by name, folder and status (errors, warnings) and sorted
by name, score or duration; cards show their warnings, and with ``--sheet`` hovering a
card flips through its top poses (panned across the contact sheet, no extra render).
Clicking a scene opens its contact sheet (or thumbnail), its numbers and its JSON, and
lets one choose pose #2, #3... as its thumbnail: the choices are kept by the browser
and saved as ``thumb-choices.csv`` into OUT, which the next run renders and records in
the index (``thumb_pose``). On a phone the grid has two columns and the header scrolls
away.
"""

from __future__ import annotations

import html
import json
from pathlib import Path

from snapcore.batch.index import atomic_write

__all__ = ["write_gallery", "gallery_html", "GALLERY_NAME"]

GALLERY_NAME = "index.html"
#: Row fields the page uses (hashes and options stay in the CSV).
_FIELDS = (
    "path",
    "folder",
    "name",
    "kind",
    "status",
    "error",
    "warnings",
    "characters",
    "n_frames",
    "fps",
    "duration_s",
    "frame",
    "time_s",
    "top_frames",
    "score",
    "thumb_pose",
    "view_x",
    "view_y",
    "view_z",
    "json",
    "thumb",
    "sheet",
    "t_total_s",
)

_CSS = """
body{font:14px system-ui,sans-serif;margin:0;background:#f4f4f2;color:#222}
header{position:sticky;top:0;background:#fff;padding:10px 16px;border-bottom:1px solid #ddd;
display:flex;gap:8px 12px;align-items:center;flex-wrap:wrap;z-index:1}
header h1{font-size:18px;margin:0 12px 0 0}
#grid{display:grid;grid-template-columns:repeat(auto-fill,minmax(190px,1fr));gap:12px;padding:16px}
.card{background:#fff;border:1px solid #ddd;border-radius:6px;overflow:hidden;cursor:pointer;
padding:0;text-align:left;font:inherit;color:inherit;display:flex;flex-direction:column;
justify-content:flex-start;position:relative}
.card:focus,.card:hover{outline:2px solid #3a6ea5}
.card .pic{position:relative;width:100%;aspect-ratio:var(--ratio);background:#e8e8e4}
.card img{width:100%;height:100%;object-fit:contain;display:block}
.card .flip{position:absolute;inset:0;background-repeat:no-repeat;background-color:#fff;
background-size:calc(var(--steps) * 100%) auto;background-position:0 55%;opacity:0}
.card:hover .flip,.card:focus .flip{opacity:1;
animation:flip var(--flip) steps(var(--steps),jump-none) infinite}
@keyframes flip{from{background-position:0 55%}to{background-position:100% 55%}}
.card .cap{padding:6px 8px}.card .name{font-weight:600;word-break:break-all}
.card .meta{color:#666;font-size:12px}
.card .warn{color:#8a5a00;background:#fff4d6;font-size:12px;padding:3px 8px;
overflow:hidden;text-overflow:ellipsis;white-space:nowrap}
.card .badge{position:absolute;top:6px;left:6px;background:#3a6ea5;color:#fff;font-size:11px;
padding:1px 6px;border-radius:8px}
.card.error{border-color:#c33}
.card .err{color:#a22;font-size:12px;padding:8px;word-break:break-word;aspect-ratio:var(--ratio);
box-sizing:border-box;width:100%;background:#fbeeee}
dialog{max-width:min(1200px,95vw);width:95vw;border:0;border-radius:8px;padding:16px;box-sizing:border-box}
dialog img{max-width:100%;display:block;margin:8px 0;background:#e8e8e4}
dialog [hidden]{display:none}
dialog table{border-collapse:collapse;margin:8px 0}dialog td{padding:2px 10px 2px 0;vertical-align:top}
dialog iframe{width:100%;height:320px;border:1px solid #ddd}
#d-poses button{margin:0 6px 6px 0;font:inherit;padding:4px 10px;border:1px solid #aaa;
border-radius:14px;background:#fff;cursor:pointer}
#d-poses button[aria-pressed=true]{background:#3a6ea5;color:#fff;border-color:#3a6ea5}
#choices{background:#fff4d6;border:1px solid #e0c070;border-radius:6px;padding:2px 8px}
.links a{margin-right:14px}
@media (max-width:600px){
header{position:static;padding:8px 10px;gap:6px}
header h1{font-size:16px;width:100%}
header input,header select{max-width:46vw}
#grid{grid-template-columns:repeat(2,minmax(0,1fr));gap:8px;padding:8px}
.card .cap{padding:4px 6px}
dialog{width:100vw;max-width:100vw;padding:10px}
dialog iframe{height:200px}
}
"""

_JS = r"""
const rows = JSON.parse(document.getElementById('rows').textContent);
const $ = (id) => document.getElementById(id);
const url = (p) => p.split('/').map(encodeURIComponent).join('/');
const fmt = (x, d) => (x === null || x === undefined) ? '' : Number(x).toFixed(d);
// thumbnail choices made here, kept by the browser until saved as thumb-choices.csv
const store = 'snapshot-thumb-choices:' + location.pathname;
let choices = {};
try { choices = JSON.parse(localStorage.getItem(store) || '{}'); } catch (e) { choices = {}; }
const shownPose = (r) => choices[r.path] || r.thumb_pose || 1;
const folders = [...new Set(rows.map(r => r.folder))].sort();
for (const f of folders) {
  const o = document.createElement('option');
  o.value = f; o.textContent = f === '' ? '(top)' : f;
  $('folder').appendChild(o);
}
function card(r) {
  const b = document.createElement('button');
  b.className = 'card' + (r.status === 'ok' ? '' : ' error') + (r.warnings ? ' warned' : '');
  b.dataset.path = r.path;
  if (r.status === 'ok') {
    const pic = document.createElement('div'); pic.className = 'pic';
    const img = document.createElement('img');
    img.src = url(r.thumb); img.alt = r.name; img.loading = 'lazy';
    pic.appendChild(img);
    const k = r.top_frames ? r.top_frames.split(';').length : 1;
    if (r.sheet && k > 1) {  // hover: the top poses one after the other, from the sheet
      // (its k panels side by side: the sheet k cards wide shows one panel at a time)
      const flip = document.createElement('div');
      flip.className = 'flip'; flip.dataset.sheet = r.sheet;
      pic.style.setProperty('--steps', String(k));
      pic.style.setProperty('--flip', `${0.7 * k}s`);
      b.addEventListener('pointerenter', () => {  // loaded on the first hover only
        flip.style.backgroundImage = `url("${url(r.sheet)}")`;
      }, {once: true});
      b.addEventListener('focus', () => {
        flip.style.backgroundImage = `url("${url(r.sheet)}")`;
      }, {once: true});
      pic.appendChild(flip);
    }
    const chosen = shownPose(r);
    if (chosen !== 1) {
      const badge = document.createElement('span'); badge.className = 'badge';
      badge.textContent = `pose #${chosen}` + (choices[r.path] && choices[r.path] !== r.thumb_pose ? ' (not saved)' : '');
      pic.appendChild(badge);
    }
    b.appendChild(pic);
  } else {
    const e = document.createElement('div');
    e.className = 'err'; e.textContent = r.error;
    b.appendChild(e);
  }
  if (r.warnings) {
    const w = document.createElement('div'); w.className = 'warn';
    w.textContent = '\u26a0 ' + r.warnings; w.title = r.warnings;
    b.appendChild(w);
  }
  const cap = document.createElement('div'); cap.className = 'cap';
  const n = document.createElement('div'); n.className = 'name'; n.textContent = r.path;
  const m = document.createElement('div'); m.className = 'meta';
  m.textContent = r.status === 'ok'
    ? `${fmt(r.duration_s, 1)} s · ${r.n_frames} frames · pose at frame ${r.frame}` +
      (r.score === null || r.score === undefined ? '' : ` · score ${fmt(r.score, 2)}`)
    : 'error';
  cap.append(n, m); b.appendChild(cap);
  b.addEventListener('click', () => open_(r));
  return b;
}
const last = (x) => (x === null || x === undefined) ? null : x;
function byNumber(key, dir) {  // rows without the number (failed scenes) last either way
  return (a, b) => {
    const x = last(a[key]), y = last(b[key]);
    if (x === null || y === null) return (x === null) - (y === null) || a.path.localeCompare(b.path);
    return dir * (x - y) || a.path.localeCompare(b.path);
  };
}
function render() {
  const q = $('filter').value.trim().toLowerCase();
  const f = $('folder').value;
  const st = $('status').value;
  const s = $('sort').value;
  const keep = {'*': () => true, error: (r) => r.status !== 'ok', warning: (r) => !!r.warnings,
                clean: (r) => r.status === 'ok' && !r.warnings}[st];
  let shown = rows.filter(r => (f === '*' || r.folder === f) && keep(r) &&
                               (!q || r.path.toLowerCase().includes(q)));
  if (s === 'duration') shown.sort(byNumber('duration_s', 1));
  else if (s === '-duration') shown.sort(byNumber('duration_s', -1));
  else if (s === '-score') shown.sort(byNumber('score', -1));
  else if (s === 'score') shown.sort(byNumber('score', 1));
  else shown.sort((a, b) => a.path.localeCompare(b.path));
  $('grid').replaceChildren(...shown.map(card));
  $('count').textContent = `${shown.length} of ${rows.length} scenes`;
  showChoices();
}
function row(t, k, v) {
  const tr = document.createElement('tr');
  const a = document.createElement('td'); a.textContent = k;
  const b = document.createElement('td'); b.textContent = v;
  tr.append(a, b); t.appendChild(tr);
}
function pending() {  // choices that differ from what the index already shows
  return Object.entries(choices).filter(([p, k]) => {
    const r = rows.find(x => x.path === p);
    return r && k !== (r.thumb_pose || 1);
  });
}
function showChoices() {
  const todo = pending();
  const box = $('choices');
  box.hidden = todo.length === 0;
  if (!todo.length) return;
  const csv = 'path,pose\n' + todo.map(([p, k]) => `"${p.replace(/"/g, '""')}",${k}`).join('\n') + '\n';
  const a = $('save');
  a.href = 'data:text/csv;charset=utf-8,' + encodeURIComponent(csv);
  $('n-choices').textContent = `${todo.length} thumbnail choice${todo.length > 1 ? 's' : ''}`;
}
function choose(r, k) {
  if (k === (r.thumb_pose || 1)) delete choices[r.path]; else choices[r.path] = k;
  localStorage.setItem(store, JSON.stringify(choices));
  poses(r);
  render();
}
function poses(r) {
  const box = $('d-poses'); box.replaceChildren();
  if (r.status !== 'ok' || !r.top_frames) { box.hidden = true; return; }
  box.hidden = false;
  const label = document.createElement('span'); label.textContent = 'thumbnail: ';
  box.appendChild(label);
  r.top_frames.split(';').forEach((fr, i) => {
    const b = document.createElement('button'); b.type = 'button';
    b.textContent = `#${i + 1} frame ${fr}`;
    b.setAttribute('aria-pressed', String(shownPose(r) === i + 1));
    b.addEventListener('click', () => choose(r, i + 1));
    box.appendChild(b);
  });
}
function open_(r) {
  $('d-title').textContent = r.path;
  const img = $('d-img');
  const pic = r.sheet || r.thumb;
  img.hidden = !pic;
  if (pic) img.src = url(pic); else img.removeAttribute('src');
  const t = $('d-table'); t.replaceChildren();
  row(t, 'status', r.status + (r.error ? ': ' + r.error : ''));
  if (r.status === 'ok') {
    row(t, 'characters', r.characters);
    row(t, 'frames', `${r.n_frames} at ${r.fps} fps = ${fmt(r.duration_s, 2)} s`);
    row(t, 'chosen pose', `frame ${r.frame} (t = ${fmt(r.time_s, 2)} s); top: ${r.top_frames.split(';').join(', ')}`);
    if (r.score !== null && r.score !== undefined) row(t, 'score', fmt(r.score, 3));
    row(t, 'view', `(${fmt(r.view_x, 3)}, ${fmt(r.view_y, 3)}, ${fmt(r.view_z, 3)})`);
    row(t, 'time', `${fmt(r.t_total_s, 2)} s`);
  }
  if (r.warnings) row(t, 'warnings', r.warnings);
  poses(r);
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
for (const id of ['filter', 'folder', 'status', 'sort']) $(id).addEventListener('input', render);
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
<label>show <select id="status"><option value="*">all</option>
<option value="error">errors only</option><option value="warning">with warnings</option>
<option value="clean">ok, no warnings</option></select></label>
<label>sort <select id="sort"><option value="name">name</option>
<option value="-score">score (highest first)</option>
<option value="score">score (lowest first)</option>
<option value="duration">duration (shortest first)</option>
<option value="-duration">duration (longest first)</option></select></label>
<span id="count"></span><span id="summary">({html.escape(summary)})</span>
<span id="choices" hidden><span id="n-choices"></span>:
<a id="save" download="thumb-choices.csv" href="#">save thumb-choices.csv</a> into this
folder, then run the batch again</span></header>
<main id="grid"></main>
<dialog id="detail"><button id="close" type="button">close</button>
<h2 id="d-title"></h2><img id="d-img" alt="contact sheet"><div id="d-poses"></div>
<table id="d-table"></table>
<div class="links" id="d-links"></div><iframe id="d-json" title="snapshot JSON"></iframe>
</dialog>
<script id="rows" type="application/json">{payload}</script>
<script>{_JS}</script>
</body></html>
"""


def write_gallery(
    out, rows, *, title: str = "Action Snapshot gallery", size: tuple[int, int] = (320, 360)
) -> Path:
    """Write ``OUT/index.html`` for ``rows`` (atomically) and return its path."""
    path = Path(out) / GALLERY_NAME
    atomic_write(path, gallery_html(rows, title=title, ratio=size[0] / size[1]))
    return path
