// Frame-accurate video frame picker (Streamlit components v2, no build step).
//
// data: [{sources: [{src, type}], fps, n_frames, trial, start_frame, watched,
//        watched_ranges, require_watch, watch_min, min_answer_s, labels, log_key}]
//        (one-item list)
// Triggers:
//   "log": {trial, events}      the log of plays, pauses, seeks and steps ({kind, t:
//                               seconds since mounted, frame, watched, ranges, tab}),
//                               sent in small batches as it happens, so a reload loses
//                               nothing; while playing, a "watch" entry every 2 s keeps
//                               the frames watched (ranges) stored;
//   "confirm": {trial, frame, events, watched, ranges, client, resend}  frame is the
//                               0-based video frame on screen when the participant
//                               pressed Confirm, events the entries not sent yet,
//                               watched the share of the animation played (0-1),
//                               client what the answer was given on (viewport, device
//                               pixel ratio, input, active time, tab id);
//   "error": {trial, message}   the browser can play none of the sources, after retries.
//
// Watching is kept as ranges of video frames played ([[from, to], ...]): the stored
// ranges of earlier page loads (watched_ranges) and this page's played ranges are
// united, so half watched before a reload and the other half after it is the whole.
//
// An answer sent while the connection is down is lost by the browser: if the page has
// not moved on RESEND_MS after Confirm, the answer is sent again (the server stores it
// once), and after RESENDS tries Confirm opens again with a message that nothing was
// saved. A video that fails to load, or stalls while playing (STALL_MS), is loaded
// again (VIDEO_RETRIES) and resumed before the error.
//
// A reload (or leaving the page) before a batch went out keeps its entries in the tab's
// sessionStorage under log_key (participant and trial); the player mounted again for
// that key sends them first and starts from the frame they reached. Nothing is kept
// for a player whose answer was sent.
//
// Confirm stays off until the video is ready, has been on screen min_answer_s seconds
// and, with require_watch, was played through once (its played ranges cover watch_min
// of the duration; a restored `watched` from before a reload counts).
// Keys work as soon as the page shows the player (no click into it first): ← / → step
// one frame, Space plays/pauses — except on a focused button or the slider, which keep
// their own keys (Space on Confirm confirms).
//
// Frame accuracy: the frame on screen is read from requestVideoFrameCallback's
// mediaTime (the presentation time of the composited frame), frame = round(t * fps);
// seeking to frame f targets the middle of its display interval, (f + 0.5) / fps, so
// rounding can never land on a neighbour.

const RESEND_MS = 4000;
const RESENDS = 3;
const VIDEO_RETRIES = 2;
// A video playing whose picture has not moved this long has stopped loading (its body
// cut midway): it is loaded again and resumed where it was, as a failed load is, and
// after the retries the trial turns to the slider, without any press of Play.
const STALL_MS = 3000;
// Windows this short or shorter (CSS px) get the short layout (picker.css).
const SHORT_WINDOW_PX = 520;

// United [from, to] ranges (sorted, overlaps merged).
function unite(ranges) {
  const r = ranges.filter((x) => Array.isArray(x) && x.length === 2 && x[1] > x[0])
    .map((x) => [Number(x[0]), Number(x[1])]).sort((a, b) => a[0] - b[0]);
  const out = [];
  for (const x of r) {
    if (out.length && x[0] <= out[out.length - 1][1] + 1e-6) out[out.length - 1][1] = Math.max(out[out.length - 1][1], x[1]);
    else out.push(x);
  }
  return out;
}

function buildPicker(root, data) {
  const n = data.n_frames;
  const fps = data.fps;
  const L = data.labels || {};
  root.innerHTML = `
    <div class="snap-stage">
      <video class="snap-video" data-testid="picker-video" preload="auto" muted playsinline
             disablepictureinpicture aria-label="${L.video || "The animation"}"></video>
      <div class="snap-error" data-testid="picker-error" hidden></div>
    </div>
    <input class="snap-scrub" data-testid="picker-scrub" type="range" min="0" max="${n - 1}"
           step="1" value="0" aria-label="${L.scrub || "Position in the animation"}">
    <div class="snap-controls">
      <button type="button" data-testid="picker-back" title="${L.back || "Previous frame"} (←)"
              aria-label="${L.back || "Previous frame"}">◀ 1</button>
      <button type="button" data-testid="picker-play" class="snap-play">${L.play || "Play"}</button>
      <button type="button" data-testid="picker-forward" title="${L.forward || "Next frame"} (→)"
              aria-label="${L.forward || "Next frame"}">1 ▶</button>
      <span class="snap-frame" data-testid="picker-frame"></span>
      <span class="snap-sr" data-testid="picker-frame-live" aria-live="polite"></span>
      <button type="button" data-testid="picker-confirm" class="snap-confirm" disabled>
        ${L.confirm || "Confirm this frame"}</button>
    </div>
    <div class="snap-hint" data-testid="picker-hint" hidden>${L.watch_first || "Watch the whole animation once to choose a frame."}</div>`;
  const video = root.querySelector("video");
  const scrub = root.querySelector(".snap-scrub");
  const label = root.querySelector(".snap-frame");
  const play = root.querySelector("[data-testid=picker-play]");
  const back = root.querySelector("[data-testid=picker-back]");
  const fwd = root.querySelector("[data-testid=picker-forward]");
  const confirm = root.querySelector("[data-testid=picker-confirm]");
  const errorBox = root.querySelector(".snap-error");
  const hint = root.querySelector(".snap-hint");
  const live = root.querySelector(".snap-sr");
  const pointer = pointerTracker(root);
  const clock = activeClock(data.log_key);

  const t0 = performance.now();
  const state = { frame: Math.min(Math.max(data.start_frame || 0, 0), n - 1), events: [],
                  sent: false, ready: false, seeking: false, pendingSeek: null,
                  watched: Math.min(Math.max(Number(data.watched) || 0, 0), 1), logged: 0,
                  ranges: unite(data.watched_ranges || []), resends: 0, retries: 0 };
  root._snap = state;
  // Entries a reload interrupted (see the header), sent before anything new.
  state.pendingKey = data.log_key ? `snap-pending-log:${data.log_key}` : null;
  let pending = [];
  if (state.pendingKey) {
    try { pending = JSON.parse(sessionStorage.getItem(state.pendingKey) || "[]"); }
    catch (e) { pending = []; }
    sessionStorage.removeItem(state.pendingKey);
  }
  if (pending.length) {
    const last = pending[pending.length - 1];
    if (Number.isFinite(last.frame)) state.frame = Math.min(Math.max(last.frame, 0), n - 1);
    state.watched = Math.max(state.watched, ...pending.map((e) => Number(e.watched) || 0));
    state.ranges = unite([...state.ranges, ...pending.flatMap((e) => e.ranges || [])]);
    setTimeout(() => root._api.setTriggerValue("log", { trial: data.trial, events: pending }), 0);
  }
  const minAnswerMs = 1000 * (Number(data.min_answer_s) || 0);
  const watchMin = Number(data.watch_min) || 0.9;
  // The frames played so far: the browser's own played ranges (so scrubbing or stepping
  // does not count as watching) united with those of earlier page loads.
  const updateWatched = () => {
    const mine = [];
    for (let i = 0; i < video.played.length; i++) {
      mine.push([Math.round(video.played.start(i) * fps * 100) / 100,
                 Math.round(video.played.end(i) * fps * 100) / 100]);
    }
    state.ranges = unite([...state.ranges, ...mine]);
    const d = video.duration;
    const total = d > 0 && isFinite(d) ? d * fps : n;
    const covered = state.ranges.reduce((a, r) => a + Math.min(r[1], total) - Math.max(r[0], 0), 0);
    state.watched = Math.max(state.watched, Math.min(covered / total, 1));
    root.dataset.watched = state.watched.toFixed(3);
  };
  const canConfirm = () => state.ready && !state.sent
    && performance.now() - t0 >= minAnswerMs
    && (!data.require_watch || state.watched >= watchMin);
  const refreshConfirm = () => {
    updateWatched();
    confirm.disabled = !canConfirm();
    hint.hidden = !(data.require_watch && state.ready && state.watched < watchMin);
  };
  let flushTimer = null;
  const flush = () => {
    flushTimer = null;
    if (state.sent) return;
    const batch = state.events.slice(state.logged);
    if (!batch.length) return;
    state.logged = state.events.length;
    root._api.setTriggerValue("log", { trial: data.trial, events: batch });
  };
  const log = (kind, extra) => {
    if (state.events.length < 500) {
      updateWatched();
      state.events.push({ kind, t: (performance.now() - t0) / 1000, frame: state.frame,
                          watched: state.watched, ranges: state.ranges, tab: tabId(), ...extra });
      // Batched: one round trip per burst of clicks, not per click.
      if (flushTimer === null) flushTimer = setTimeout(flush, 800);
    }
  };
  const clamp = (f) => Math.min(Math.max(Math.round(f), 0), n - 1);
  const show = (f) => {
    state.frame = clamp(f);
    scrub.value = String(state.frame);
    label.textContent = `${L.frame || "Frame"} ${state.frame + 1} / ${n}`;
    // Screen readers hear the frame when it settles (paused), not every frame of a play.
    if (video.paused && !state.seeking) live.textContent = label.textContent;
    root.dataset.frame = String(state.frame);
  };
  const seek = (f) => {
    f = clamp(f);
    show(f);
    if (state.seeking) { state.pendingSeek = f; return; }
    state.seeking = true;
    video.currentTime = (f + 0.5) / fps;
  };
  video.addEventListener("seeked", () => {
    state.seeking = false;
    if (state.pendingSeek !== null) {
      const f = state.pendingSeek;
      state.pendingSeek = null;
      seek(f);
    }
  });

  // The displayed frame, as the compositor reports it.
  if ("requestVideoFrameCallback" in HTMLVideoElement.prototype) {
    const onFrame = (now, meta) => {
      // Only while playing: a paused player shows the frame it was sent to, and a late
      // callback for the first decoded frame must not undo a restored position.
      if (!video.paused && !state.seeking && state.pendingSeek === null) show(meta.mediaTime * fps);
      video.requestVideoFrameCallback(onFrame);
    };
    video.requestVideoFrameCallback(onFrame);
  } else {
    // Older browsers: currentTime during playback (close, and exact once paused on a seek).
    video.addEventListener("timeupdate", () => { if (!state.seeking) show(video.currentTime * fps - 0.5); });
  }

  video.addEventListener("loadeddata", () => {
    if (!state.ready && window.innerHeight <= SHORT_WINDOW_PX) {
      // A short window (200% zoom, a landscape phone): the player to the top, so the
      // video and its controls fill it and the sticky controls cover nothing.
      root.scrollIntoView({ block: "start" });
    }
    state.ready = true;
    root.dataset.ready = "1";
    seek(state.frame);
    refreshConfirm();
    if (state.resume) { state.resume = false; video.play(); }  // loaded again after a stall
  });
  // The stall watchdog: playing, not ended, and the picture has not moved.
  let lastTime = -1, lastMove = performance.now();
  const stallTimer = setInterval(() => {
    if (!root.isConnected) { clearInterval(stallTimer); return; }
    const now = performance.now();
    if (video.paused || video.ended || root.dataset.error || video.currentTime !== lastTime) {
      lastTime = video.currentTime;
      lastMove = now;
      return;
    }
    if (now - lastMove > STALL_MS) {
      lastMove = now;
      root.dataset.stalls = String(Number(root.dataset.stalls || 0) + 1);
      log("watch");
      flush();  // what was watched is stored before the retries (or the slider)
      state.resume = true;
      fail("the video stopped loading");
    }
  }, 500);
  // Re-check what Confirm may do while the clock and the playback run.
  const ticker = setInterval(() => {
    if (!root.isConnected) { clearInterval(ticker); return; }
    refreshConfirm();
  }, 250);
  video.addEventListener("play", () => { play.textContent = L.pause || "Pause"; log("play"); });
  // While playing, the frames watched are stored every 2 s (a reload or a return keeps them).
  const watchTimer = setInterval(() => {
    if (!root.isConnected) { clearInterval(watchTimer); return; }
    if (!video.paused && !state.sent) log("watch");
  }, 2000);
  video.addEventListener("pause", () => { play.textContent = L.play || "Play"; refreshConfirm(); });
  video.addEventListener("ended", () => { show(n - 1); log("ended"); refreshConfirm(); });
  const fail = (msg) => {
    if (root.dataset.error) return;
    // Loaded again first (a dropped request is not a browser that cannot play it).
    if (state.retries < VIDEO_RETRIES) {
      state.retries += 1;
      root.dataset.retries = String(state.retries);
      setTimeout(() => loadSources(`retry=${state.retries}`), 400 * state.retries);
      return;
    }
    errorBox.textContent = `${L.video_error || "The video cannot be played"}: ${msg}`;
    errorBox.hidden = false;
    root.dataset.error = msg;
    root._api.setTriggerValue("error", { trial: data.trial, message: msg });
  };
  video.addEventListener("error", () => {
    fail((video.error && video.error.message) || "this browser cannot play the video");
  });

  play.addEventListener("click", () => {
    if (video.paused) {
      if (state.frame >= n - 1) seek(0);
      video.play();
    } else {
      video.pause();
      // Land exactly on the frame that is showing, so Confirm sends what is seen.
      seek(state.frame);
      log("pause");
    }
  });
  const step = (d) => {
    if (!video.paused) video.pause();
    seek(state.frame + d);
    log("step", { by: d });
  };
  back.addEventListener("click", () => step(-1));
  fwd.addEventListener("click", () => step(1));
  let scrubFrom = null;
  scrub.addEventListener("pointerdown", () => { scrubFrom = state.frame; });
  scrub.addEventListener("input", () => {
    if (!video.paused) video.pause();
    seek(Number(scrub.value));
  });
  scrub.addEventListener("change", () => {
    log("seek", { from: scrubFrom === null ? undefined : scrubFrom });
    scrubFrom = null;
  });
  // Keys anywhere on the page (the instructions promise them without a click into the
  // player). The real target is read through shadow roots: a focused button or the
  // slider keeps its own keys, so Space on Confirm confirms instead of playing.
  root._onKey = (e) => {
    if (!root.isConnected || e.defaultPrevented || e.altKey || e.ctrlKey || e.metaKey) return;
    const target = (e.composedPath && e.composedPath()[0]) || e.target;
    const tag = (target && target.tagName) || "";
    if (/^(INPUT|TEXTAREA|SELECT)$/.test(tag) || (target && target.isContentEditable)) return;
    if (tag === "BUTTON" && (e.key === " " || e.key === "Enter")) return;
    if (e.key === "ArrowLeft") { step(-1); e.preventDefault(); }
    else if (e.key === "ArrowRight") { step(1); e.preventDefault(); }
    else if (e.key === " ") { play.click(); e.preventDefault(); }
  };
  const send = (payload) => root._api.setTriggerValue("confirm", payload);
  confirm.addEventListener("click", (ev) => {
    if (!canConfirm()) return;
    if (!video.paused) { video.pause(); }
    state.sent = true;
    confirm.disabled = true;
    confirm.textContent = L.saving || "Saving…";
    errorBox.hidden = true;
    log("select");
    if (flushTimer !== null) { clearTimeout(flushTimer); flushTimer = null; }
    const payload = { trial: data.trial, frame: state.frame,
                      events: state.events.slice(state.logged), watched: state.watched,
                      ranges: state.ranges, client: clientInfo(ev, pointer, clock) };
    send(payload);
    // Still here after a while: the answer may have been lost with the connection.
    state.resends = 0;
    clearInterval(state.resendTimer);
    state.resendTimer = setInterval(() => {
      if (!root.isConnected) { clearInterval(state.resendTimer); clock.clear(); return; }
      state.resends += 1;
      if (state.resends <= RESENDS) { send({ ...payload, resend: true }); return; }
      clearInterval(state.resendTimer);
      state.sent = false;
      confirm.textContent = L.confirm || "Confirm this frame";
      errorBox.textContent = L.not_saved || "The connection was lost: your answer was not saved. Please press Confirm again.";
      errorBox.hidden = false;
      root.dataset.lost = "1";
      refreshConfirm();
    }, RESEND_MS);
  });

  show(state.frame);
  // Every source the page offers (H.264 MP4 for most browsers, WebM/VP9 for those
  // without H.264, e.g. Debian's Firefox ESR); the browser plays the first it can.
  const sources = data.sources || [{ src: data.src, type: "video/mp4" }];
  const loadSources = (query) => {
    video.querySelectorAll("source").forEach((el) => el.remove());
    sources.forEach((s, i) => {
      const el = document.createElement("source");
      el.src = query ? `${s.src}${s.src.includes("?") ? "&" : "?"}${query}` : s.src;
      if (s.type) el.type = s.type;
      // Errors of <source> children do not reach the video element: the last one
      // failing means none could be played.
      if (i === sources.length - 1) {
        el.addEventListener("error", () => fail("this browser can play none of the video formats"));
      }
      video.appendChild(el);
    });
    video.load();
  };
  loadSources("");
}

// One page-wide key handler, dispatching to the picker on screen now.
if (!window.__snapPickerKeys) {
  window.__snapPickerKeys = true;
  document.addEventListener("keydown", (e) => {
    const root = window.__snapPicker;
    if (root && root.isConnected && root._onKey) root._onKey(e);
  });
}

// Leaving the page (a reload too) keeps the unsent entries of the picker on screen.
if (!window.__snapPickerPagehide) {
  window.__snapPickerPagehide = true;
  window.addEventListener("pagehide", () => {
    const root = window.__snapPicker;
    const s = root && root.isConnected && root._snap;
    if (!s || s.sent || !s.pendingKey) return;
    const rest = s.events.slice(s.logged);
    if (rest.length) sessionStorage.setItem(s.pendingKey, JSON.stringify(rest));
  });
  // Back from the browser's page cache the page is alive and its timer sends them.
  window.addEventListener("pageshow", (e) => {
    const root = window.__snapPicker;
    const s = root && root._snap;
    if (e.persisted && s && s.pendingKey) sessionStorage.removeItem(s.pendingKey);
  });
}

export default function (component) {
  const { parentElement } = component;
  const data = component.data[0];  // sent as [data] (see picker/__init__.py)
  const key = `${data.trial}|${(data.sources || []).map((s) => s.src).join("|")}`;
  let root = parentElement.querySelector(".snap-picker");
  if (!root || root.dataset.key !== key) {
    if (root) root.remove();
    root = document.createElement("div");
    root.className = "snap-picker";
    root.tabIndex = 0;
    root.dataset.key = key;
    root.dataset.testid = "frame-picker";
    parentElement.appendChild(root);
    root._api = component;
    buildPicker(root, data);
  }
  window.__snapPicker = root;
  // Reruns re-invoke this function: keep the mounted player (and its position), but
  // send through the newest callbacks.
  root._api = component;
}
