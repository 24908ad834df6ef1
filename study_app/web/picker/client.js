// What an answer was given on (viewport, device pixel ratio, input, active time, tab
// id): shared by the study's components, each given this file before its own
// (study_app/web/picker/__init__.py, _components).

// The tab's id (kept across reloads of the tab, new in another tab).
function tabId() {
  try {
    let id = sessionStorage.getItem("snap-tab");
    if (!id) {
      id = Math.random().toString(36).slice(2, 12);
      sessionStorage.setItem("snap-tab", id);
    }
    return id;
  } catch (e) { return "unknown"; }
}

// Time the page was visible (ms), across reloads of this tab (kept under key).
function activeClock(key) {
  const store = key ? `snap-active:${key}` : null;
  let before = 0;
  if (store) { try { before = Number(sessionStorage.getItem(store)) || 0; } catch (e) { before = 0; } }
  let since = document.visibilityState === "visible" ? performance.now() : null;
  const ms = () => before + (since === null ? 0 : performance.now() - since);
  const save = () => { if (store) { try { sessionStorage.setItem(store, String(ms())); } catch (e) { /* full */ } } };
  document.addEventListener("visibilitychange", () => {
    if (document.visibilityState === "visible") { if (since === null) since = performance.now(); }
    else if (since !== null) { before += performance.now() - since; since = null; save(); }
  });
  window.addEventListener("pagehide", save);
  return { ms, clear: () => { if (store) sessionStorage.removeItem(store); } };
}

// What an answer was given on; input from the event that gave it.
function clientInfo(ev, lastPointer, clock) {
  const keyboard = ev && ev.detail === 0 && !lastPointer.recent();
  return { viewport: [window.innerWidth, window.innerHeight],
           dpr: window.devicePixelRatio || 1,
           input: keyboard ? "keyboard" : (lastPointer.type || "mouse"),
           active_s: Math.round(clock.ms()) / 1000, tab: tabId() };
}

function pointerTracker(root) {
  const p = { type: null, at: -1e9, recent: () => performance.now() - p.at < 1500 };
  root.addEventListener("pointerdown", (e) => { p.type = e.pointerType || "mouse"; p.at = performance.now(); }, true);
  return p;
}
