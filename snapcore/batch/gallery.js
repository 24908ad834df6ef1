// The batch gallery (see snapcore/batch/gallery.py). Rows and meta are embedded JSON.
const rows = JSON.parse(document.getElementById('rows').textContent);
const meta = JSON.parse(document.getElementById('meta').textContent);
const $ = (id) => document.getElementById(id);
const url = (p) => p.split('/').map(encodeURIComponent).join('/');
const fmt = (x, d) => (x === null || x === undefined) ? '' : Number(x).toFixed(d);
const served = location.protocol === 'http:' || location.protocol === 'https:';
const byPath = new Map(rows.map(r => [r.path, r]));

// ---- thumbnail choices: source frames; null = back to the chosen pose -------------------
// saved: what OUT/thumb-choices.csv and the index hold; local: made here, not saved yet
const saved = {};
for (const r of rows) if (r.thumb_choice !== null && r.thumb_choice !== undefined) saved[r.path] = r.thumb_choice;
Object.assign(saved, meta.choices);
const store = 'snapshot-thumb-choices@2:' + location.pathname;
let local = {};
if (!served) {
  try { local = JSON.parse(localStorage.getItem(store) || '{}'); } catch (e) { local = {}; }
}
const choiceOf = (r) => {
  const v = r.path in local ? local[r.path] : saved[r.path];
  return v === undefined ? null : v;
};
// the frame the thumbnail will show once rendered: the choice when the clip has it
const inClip = (r, f) => r.first_frame !== null && f >= r.first_frame && f < r.first_frame + r.n_frames;
const willShow = (r) => { const c = choiceOf(r); return c !== null && inClip(r, c) ? c : r.frame; };

// ---- filters ----------------------------------------------------------------------------
function fillSelect(id, values, label) {
  const sel = $(id);
  for (const v of values) {
    const o = document.createElement('option');
    o.value = String(v); o.textContent = label ? label(v) : String(v);
    sel.appendChild(o);
  }
}
const distinct = (key) => [...new Set(rows.map(r => r[key]).filter(v => v !== null && v !== undefined))]
  .sort((a, b) => (typeof a === 'number' ? a - b : String(a).localeCompare(String(b))));
fillSelect('kind', distinct('kind'), (k) => ({bvh: 'BVH', gltf: 'glTF', manifest: 'scene manifest', unknown: 'other'}[k] || k));
fillSelect('rig', distinct('rig'));
fillSelect('fps', distinct('fps'), (f) => `${+Number(f).toFixed(2)} fps`);
fillSelect('chars', distinct('characters'));

// ---- folder tree: a folder holds its sub-folders' scenes -----------------------------
let folder = '';  // '' = the whole library
// a phone starts with the top folders only: the tree sits above the grid there
const phone = matchMedia('(max-width: 600px)').matches;
function buildTree() {
  const root = {name: '', path: '', kids: new Map(), n: 0, e: 0};
  for (const r of rows) {
    let node = root; node.n++; if (r.status !== 'ok') node.e++;
    if (!r.folder) continue;
    let at = '';
    for (const part of r.folder.split('/')) {
      at = at ? at + '/' + part : part;
      if (!node.kids.has(part)) node.kids.set(part, {name: part, path: at, kids: new Map(), n: 0, e: 0});
      node = node.kids.get(part); node.n++; if (r.status !== 'ok') node.e++;
    }
  }
  const line = (node, label, hasKids) => {
    const d = document.createElement('div'); d.className = 'node'; d.dataset.folder = node.path;
    const tw = document.createElement('span'); tw.className = 'tw';
    const l = document.createElement('span'); l.className = 'label'; l.textContent = label; l.title = node.path || label;
    const n = document.createElement('span'); n.className = 'n'; n.textContent = String(node.n);
    d.append(tw, l, n);
    if (node.e) { const e = document.createElement('span'); e.className = 'e'; e.textContent = `${node.e}✕`; e.title = `${node.e} with errors`; d.appendChild(e); }
    d.addEventListener('click', (ev) => {
      if (hasKids && ev.target === tw) return;  // the triangle only opens or closes
      folder = node.path; markFolder(); render();
      if (hasKids) {  // choosing a folder opens it (its triangle alone only toggles)
        ev.preventDefault();
        const det = d.closest('details');
        if (det && !det.open) det.open = true;
      }
    });
    return d;
  };
  const list = (node, depth) => {
    const ul = document.createElement('ul');
    for (const kid of [...node.kids.values()].sort((a, b) => a.name.localeCompare(b.name))) {
      const li = document.createElement('li');
      if (kid.kids.size) {
        const det = document.createElement('details'); det.open = depth < 1 && !phone;
        const sum = document.createElement('summary'); sum.appendChild(line(kid, kid.name, true));
        det.appendChild(sum);
        det.addEventListener('toggle', () => { if (det.open && !det.lastChild.tagName.match(/UL/)) det.appendChild(list(kid, depth + 1)); }, {once: false});
        if (det.open) det.appendChild(list(kid, depth + 1));
        li.appendChild(det);
      } else li.appendChild(line(kid, kid.name, false));
      ul.appendChild(li);
    }
    return ul;
  };
  const top = document.createElement('ul');
  const li = document.createElement('li'); li.appendChild(line(root, 'all folders', false));
  top.appendChild(li);
  const nav = $('tree');
  nav.replaceChildren(top, list(root, 0));
}
function markFolder() {
  for (const n of document.querySelectorAll('#tree .node')) n.classList.toggle('on', n.dataset.folder === folder);
}
const underFolder = (r) => !folder || r.folder === folder || r.folder.startsWith(folder + '/');

// ---- cards: made once each, re-ordered by filters and sorting --------------------------
const cards = new Map();
function label(r) {
  const c = choiceOf(r);
  const shown = r.thumb_frame === null || r.thumb_frame === undefined ? r.frame : r.thumb_frame;
  let how;
  if (c !== null && !inClip(r, c)) how = `chosen frame ${c} is not in the clip`;
  else if (c !== null && c === shown) how = 'your choice';
  else if (c !== null) how = `frame ${c} chosen, not rendered yet`;
  else {
    const k = (r.top_frames || []).indexOf(shown);
    how = k === 0 ? 'best pose' : k > 0 ? `pose #${k + 1}` : '';
  }
  return {shown, how, c};
}
function badge(r, pic) {
  let b = pic.querySelector('.badge');
  const {shown, c} = label(r);
  if (c === null && shown === r.frame) { if (b) b.remove(); return; }
  if (!b) { b = document.createElement('span'); pic.appendChild(b); }
  b.className = 'badge' + (c !== null && !inClip(r, c) ? ' lost' : c !== null && c !== shown ? ' todo' : '');
  b.textContent = c !== null && !inClip(r, c) ? `choice: frame ${c} missing` : c !== null && c !== shown ? `frame ${c} (not rendered yet)` : `frame ${shown}`;
}
function metaText(r) {
  if (r.status !== 'ok') return 'error';
  const {shown, how} = label(r);
  return `${fmt(r.duration_s, 1)} s · ${r.n_frames} fr · ${+Number(r.fps).toFixed(2)} fps` +
    (r.characters > 1 ? ` · ${r.characters} characters` : '') +
    `\nthumbnail: frame ${shown}` + (how ? ` (${how})` : '');
}
function card(r) {
  const b = document.createElement('button');
  b.className = 'card' + (r.status === 'ok' ? '' : ' error');
  b.dataset.path = r.path; b.type = 'button';
  if (r.status === 'ok') {
    const pic = document.createElement('div'); pic.className = 'pic';
    const img = document.createElement('img');
    img.src = url(r.thumb); img.alt = r.name; img.loading = 'lazy'; img.decoding = 'async';
    pic.appendChild(img);
    if (r.preview && r.preview_frames && r.preview_frames.length > 1) scrubber(b, pic, r);
    badge(r, pic);
    b.appendChild(pic);
  } else {
    const e = document.createElement('div'); e.className = 'err'; e.textContent = r.error;
    b.appendChild(e);
  }
  if (r.warnings && r.warnings.length) {
    const w = document.createElement('div'); w.className = 'warn';
    w.textContent = `\u26a0 ${r.warnings.length > 1 ? r.warnings.length + ' warnings: ' : ''}${r.warnings.join(' · ')}`;
    w.title = r.warnings.join('\n');
    b.appendChild(w);
  }
  const cap = document.createElement('div'); cap.className = 'cap';
  const n = document.createElement('div'); n.className = 'name'; n.textContent = r.name;
  n.title = r.path;
  const m = document.createElement('div'); m.className = 'meta'; m.style.whiteSpace = 'pre-line';
  m.textContent = metaText(r);
  cap.append(n, m); b.appendChild(cap);
  b.addEventListener('click', () => open_(r));
  return b;
}
// moving over a card scrubs through its preview strip (the whole motion, small panels)
function scrubber(b, pic, r) {
  const s = document.createElement('div'); s.className = 'scrub';
  const at = document.createElement('span'); at.className = 'at';
  const bar = document.createElement('span'); bar.className = 'bar';
  const n = r.preview_frames.length;
  s.style.setProperty('--n', String(n));
  pic.append(s, at, bar);
  let loaded = false;
  b.addEventListener('pointermove', (ev) => {
    if (!loaded) { s.style.backgroundImage = `url("${url(r.preview)}")`; loaded = true; }
    const box = pic.getBoundingClientRect();
    const x = Math.min(Math.max((ev.clientX - box.left) / box.width, 0), 0.9999);
    const i = Math.floor(x * n);
    s.style.backgroundPosition = `${n > 1 ? (100 * i / (n - 1)) : 0}% 0`;
    at.textContent = `frame ${r.preview_frames[i]}`;
    bar.style.width = `${100 * (i + 1) / n}%`;
    b.classList.add('scrubbing');
  });
  b.addEventListener('pointerleave', () => b.classList.remove('scrubbing'));
}
function cardOf(r) {
  let c = cards.get(r.path);
  if (!c) { c = card(r); cards.set(r.path, c); }
  return c;
}
function refreshCard(r) {
  const c = cards.get(r.path);
  if (!c) return;
  const pic = c.querySelector('.pic');
  if (pic) badge(r, pic);
  const m = c.querySelector('.meta'); if (m) m.textContent = metaText(r);
}

// ---- filtering and sorting ---------------------------------------------------------------
const last = (x) => (x === null || x === undefined) ? null : x;
function byNumber(key, dir) {  // rows without the number (failed scenes) last either way
  return (a, b) => {
    const x = last(a[key]), y = last(b[key]);
    if (x === null || y === null) return (x === null) - (y === null) || (a.path < b.path ? -1 : a.path > b.path ? 1 : 0);
    return dir * (x - y) || (a.path < b.path ? -1 : a.path > b.path ? 1 : 0);
  };
}
let shown = [];
// the grid gets its cards a screenful or so at a time, the next ones as the end comes
// into view: 2,500 cards made and laid out at once cost well over a second
const CHUNK = 120;
let placed = 0;
const more = document.createElement('div'); more.id = 'more-cards';
function placeMore() {
  if (placed >= shown.length) return;
  const next = shown.slice(placed, placed + CHUNK).map(cardOf);
  placed += next.length;
  more.before(...next);
  requestAnimationFrame(fill);
}
// the observer speaks only when the end enters view: a tall screen may need more at once
function fill() {
  if (placed < shown.length && more.getBoundingClientRect().top < innerHeight + 800) placeMore();
}
new IntersectionObserver((es) => { if (es.some(e => e.isIntersecting)) placeMore(); },
                         {rootMargin: '800px'}).observe(more);
function render() {
  const q = $('filter').value.trim().toLowerCase();
  const st = $('status').value, kind = $('kind').value, rig = $('rig').value;
  const fps = $('fps').value, ch = $('chars').value;
  const lo = parseFloat($('len-min').value), hi = parseFloat($('len-max').value);
  const keep = {'*': () => true, error: (r) => r.status !== 'ok',
                warning: (r) => !!(r.warnings && r.warnings.length),
                clean: (r) => r.status === 'ok' && !(r.warnings && r.warnings.length),
                chosen: (r) => choiceOf(r) !== null}[st];
  shown = rows.filter(r => underFolder(r) && keep(r) &&
    (kind === '*' || r.kind === kind) && (rig === '*' || r.rig === rig) &&
    (fps === '*' || String(r.fps) === fps) && (ch === '*' || String(r.characters) === ch) &&
    (isNaN(lo) || (r.duration_s !== null && r.duration_s >= lo)) &&
    (isNaN(hi) || (r.duration_s !== null && r.duration_s <= hi)) &&
    (!q || r.path.toLowerCase().includes(q)));
  const s = $('sort').value;
  if (s === 'duration') shown.sort(byNumber('duration_s', 1));
  else if (s === '-duration') shown.sort(byNumber('duration_s', -1));
  else if (s === '-score') shown.sort(byNumber('score', -1));
  else if (s === 'score') shown.sort(byNumber('score', 1));
  else shown.sort((a, b) => (a.path < b.path ? -1 : a.path > b.path ? 1 : 0));
  placed = Math.min(CHUNK, shown.length);
  $('grid').replaceChildren(...shown.slice(0, placed).map(cardOf));
  $('grid').appendChild(more);
  requestAnimationFrame(fill);
  $('count').textContent = `${shown.length} of ${rows.length} scenes` + (folder ? ` in ${folder}/` : '');
}

// ---- summary: scenes, errors, files left out ----------------------------------------------
function summary() {
  const err = rows.filter(r => r.status !== 'ok').length;
  const sk = meta.skipped;
  $('summary-line').textContent = `${rows.length} scenes` + (err ? `, ${err} with errors` : '') +
    (sk.length ? `, ${sk.length} file${sk.length > 1 ? 's' : ''} skipped` : '');
  const ul = $('skipped');
  for (const [p, why] of sk) {
    const li = document.createElement('li');
    const a = document.createElement('span'); a.textContent = p;
    const b = document.createElement('span'); b.className = 'skip-why'; b.textContent = ` — ${why}`;
    li.append(a, b); ul.appendChild(li);
  }
  if (!sk.length) $('summary').removeAttribute('open');
}

// ---- saving choices: to the server, or as a file from disk ------------------------------
function csvOfAll() {
  const all = {...saved, ...local};
  const lines = Object.keys(all).sort().map(p => `"${p.replace(/"/g, '""')}",${all[p] === null ? '' : all[p]}`);
  return 'path,frame\n' + lines.join('\n') + (lines.length ? '\n' : '');
}
function showChoices(state, text) {
  const box = $('choices');
  const todo = Object.keys(local);
  box.className = state || '';
  if (served) {
    box.hidden = !text; $('n-choices').textContent = text || '';
    $('save').hidden = true; $('save-note').hidden = true;
    return;
  }
  box.hidden = todo.length === 0;
  if (!todo.length) return;
  $('save').href = 'data:text/csv;charset=utf-8,' + encodeURIComponent(csvOfAll());
  $('n-choices').textContent = `${todo.length} thumbnail choice${todo.length > 1 ? 's' : ''} not saved:`;
}
async function choose(r, frame) {
  const before = saved[r.path] === undefined ? null : saved[r.path];
  if (frame === before) delete local[r.path]; else local[r.path] = frame;
  if (served) {
    try {
      const res = await fetch('choices', {method: 'POST', headers: {'Content-Type': 'application/json'},
                                          body: JSON.stringify({[r.path]: frame})});
      const answer = await res.json();
      if (!res.ok) throw new Error(answer.error || res.statusText);
      saved[r.path] = frame; delete local[r.path];
      showChoices('saved', `saved into ${answer.file}: frame ${frame === null ? r.frame + ' (the chosen pose)' : frame} for ${r.name}; run the batch again to render it`);
    } catch (e) {
      showChoices('failed', `not saved: ${e.message}`);
    }
  } else {
    localStorage.setItem(store, JSON.stringify(local));
    showChoices();
  }
  refreshCard(r);
  if (current === r) detailChoice(r);
}

// ---- the detail view ------------------------------------------------------------------------
let current = null;
function row(t, k, v) {
  const tr = document.createElement('tr');
  const a = document.createElement('td'); a.textContent = k;
  const b = document.createElement('td'); b.textContent = v;
  tr.append(a, b); t.appendChild(tr);
}
function scrubTo(r, f) {
  const pf = r.preview_frames || [];
  $('d-slider').value = String(f);
  const box = $('d-scrub');
  if (!pf.length || !r.preview) { box.hidden = true; $('d-at').textContent = `frame ${f}`; return; }
  box.hidden = false;
  let i = 0;
  for (let k = 1; k < pf.length; k++) if (Math.abs(pf[k] - f) < Math.abs(pf[i] - f)) i = k;
  box.style.backgroundImage = `url("${url(r.preview)}")`;
  box.style.backgroundSize = `${pf.length * 100}% 100%`;
  box.style.backgroundPosition = `${pf.length > 1 ? 100 * i / (pf.length - 1) : 0}% 0`;
  $('d-at').textContent = `frame ${f} (${fmt((f - r.first_frame) / r.fps, 2)} s)` +
    (pf[i] === f ? '' : ` · preview shows frame ${pf[i]}`);
}
function detailChoice(r) {
  const box = $('d-poses'); box.replaceChildren();
  const c = choiceOf(r);
  $('d-reset').hidden = c === null;
  if (r.status !== 'ok') { box.hidden = true; return; }
  box.hidden = false;
  const l = document.createElement('span'); l.textContent = 'top poses: '; box.appendChild(l);
  (r.top_frames || []).forEach((fr, i) => {
    const b = document.createElement('button'); b.type = 'button';
    b.textContent = `#${i + 1} frame ${fr}`;
    b.setAttribute('aria-pressed', String(willShow(r) === fr));
    b.addEventListener('click', () => { scrubTo(r, fr); choose(r, i === 0 ? null : fr); });
    box.appendChild(b);
  });
  const note = document.createElement('div');
  const {how} = label(r);
  note.textContent = `thumbnail: frame ${willShow(r)}` + (how ? ` (${how})` : '');
  note.id = 'd-choice';
  box.appendChild(note);
}
function open_(r) {
  current = r;
  $('d-title').textContent = r.path;
  const img = $('d-img');
  const pic = r.sheet || r.thumb;
  img.hidden = !pic;
  if (pic) img.src = url(pic); else img.removeAttribute('src');
  const t = $('d-table'); t.replaceChildren();
  row(t, 'status', r.status + (r.error ? ': ' + r.error : ''));
  const frameBox = $('d-frame');
  if (r.status === 'ok') {
    row(t, 'characters', `${r.characters}` + (r.rig ? ` (${r.rig})` : ''));
    row(t, 'frames', `${r.first_frame}..${r.first_frame + r.n_frames - 1} (${r.n_frames}) at ${r.fps} fps = ${fmt(r.duration_s, 2)} s`);
    row(t, 'chosen pose', `frame ${r.frame} (t = ${fmt(r.time_s, 2)} s); top: ${(r.top_frames || []).join(', ')}`);
    if (r.score !== null && r.score !== undefined) row(t, 'score', fmt(r.score, 3));
    row(t, 'view', `(${fmt(r.view_x, 3)}, ${fmt(r.view_y, 3)}, ${fmt(r.view_z, 3)})`);
    row(t, 'time', `${fmt(r.t_total_s, 2)} s`);
    frameBox.hidden = false;
    const sl = $('d-slider');
    sl.min = String(r.first_frame); sl.max = String(r.first_frame + r.n_frames - 1);
    scrubTo(r, willShow(r));
  } else {
    frameBox.hidden = true; $('d-scrub').hidden = true;
  }
  const w = $('d-warnings'); w.replaceChildren();
  for (const text of r.warnings || []) { const li = document.createElement('li'); li.textContent = text; w.appendChild(li); }
  detailChoice(r);
  const links = $('d-links'); links.replaceChildren();
  for (const [name, p] of [['snapshot JSON', r.json], ['thumbnail', r.thumb], ['contact sheet', r.sheet], ['preview strip', r.preview]]) {
    if (!p) continue;
    const a = document.createElement('a'); a.href = url(p); a.textContent = name;
    a.target = '_blank'; links.appendChild(a);
  }
  const fr = $('d-json');
  fr.hidden = !r.json;
  fr.src = r.json ? url(r.json) : 'about:blank';
  $('copied').textContent = '';
  const at = shown.indexOf(r);
  $('prev').disabled = at <= 0; $('next').disabled = at < 0 || at >= shown.length - 1;
  if (!$('detail').open) $('detail').showModal();
}
function step(d) {
  const at = shown.indexOf(current);
  if (at >= 0 && shown[at + d]) open_(shown[at + d]);
}
function copyPath() {
  const text = meta.root ? `${meta.root}/${current.path}` : current.path;
  // a selected text area copies on every origin, file:// included, and at once (the
  // clipboard API may wait on a permission); the API only where that fails
  const ta = document.createElement('textarea'); ta.value = text;
  $('detail').appendChild(ta); ta.select();
  let ok = false;
  try { ok = document.execCommand('copy'); } catch (e) { ok = false; }
  ta.remove();
  if (!ok && navigator.clipboard) navigator.clipboard.writeText(text).catch(() => {});
  $('copied').textContent = `copied: ${text}`;
}

// ---- wiring -----------------------------------------------------------------------------
$('close').addEventListener('click', () => $('detail').close());
$('prev').addEventListener('click', () => step(-1));
$('next').addEventListener('click', () => step(1));
$('copy').addEventListener('click', copyPath);
$('d-slider').addEventListener('input', () => scrubTo(current, Number($('d-slider').value)));
$('d-use').addEventListener('click', () => {
  const f = Number($('d-slider').value);
  choose(current, f === current.frame ? null : f);
});
$('d-reset').addEventListener('click', () => { scrubTo(current, current.frame); choose(current, null); });
$('detail').addEventListener('keydown', (ev) => {
  if (ev.target.tagName === 'INPUT') return;
  if (ev.key === 'ArrowLeft') step(-1); else if (ev.key === 'ArrowRight') step(1);
});
$('more').addEventListener('click', () => {
  const open = $('filters').classList.toggle('open');
  $('more').setAttribute('aria-expanded', String(open));
});
for (const id of ['filter', 'status', 'kind', 'rig', 'fps', 'chars', 'len-min', 'len-max', 'sort']) $(id).addEventListener('input', render);
const sizeKey = 'snapshot-card-size';
$('size').value = localStorage.getItem(sizeKey) || $('size').value;
const setSize = () => { document.body.style.setProperty('--card', `${$('size').value}px`); localStorage.setItem(sizeKey, $('size').value); };
$('size').addEventListener('input', setSize);
setSize();
const head = () => document.documentElement.style.setProperty('--head', `${document.querySelector('header').offsetHeight}px`);
window.addEventListener('resize', head);
buildTree(); markFolder(); summary(); render(); head(); showChoices();
performance.mark('gallery-ready');  // read by the 2,500-card measurement
if (served) {  // choices saved since the page was written
  fetch('choices').then(r => r.ok ? r.json() : {}).then(all => {
    Object.assign(saved, all);
    for (const p of Object.keys(all)) if (byPath.has(p)) refreshCard(byPath.get(p));
  }).catch(() => {});
}
