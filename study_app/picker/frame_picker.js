// Frame-accurate video frame picker (Streamlit components v2, no build step).
//
// data: {src, fps, n_frames, trial, start_frame, labels}
// Sends one trigger, "confirm": {trial, frame, events}, where frame is the 0-based
// video frame on screen when the participant pressed Confirm and events is the log of
// plays, pauses, seeks and steps ({kind, t: seconds since shown, frame}).
// Sends "error": {trial, message} if the browser cannot play the video.
//
// Frame accuracy: the frame on screen is read from requestVideoFrameCallback's
// mediaTime (the presentation time of the composited frame), frame = round(t * fps);
// seeking to frame f targets the middle of its display interval, (f + 0.5) / fps, so
// rounding can never land on a neighbour.

function buildPicker(root, data) {
  const n = data.n_frames;
  const fps = data.fps;
  const L = data.labels || {};
  root.innerHTML = `
    <div class="snap-stage">
      <video class="snap-video" data-testid="picker-video" preload="auto" muted playsinline
             disablepictureinpicture></video>
      <div class="snap-error" data-testid="picker-error" hidden></div>
    </div>
    <input class="snap-scrub" data-testid="picker-scrub" type="range" min="0" max="${n - 1}"
           step="1" value="0" aria-label="${L.scrub || "Position in the animation"}">
    <div class="snap-controls">
      <button type="button" data-testid="picker-back" title="${L.back || "Previous frame"} (←)">◀ 1</button>
      <button type="button" data-testid="picker-play" class="snap-play">${L.play || "Play"}</button>
      <button type="button" data-testid="picker-forward" title="${L.forward || "Next frame"} (→)">1 ▶</button>
      <span class="snap-frame" data-testid="picker-frame" aria-live="polite"></span>
      <button type="button" data-testid="picker-confirm" class="snap-confirm" disabled>
        ${L.confirm || "Confirm this frame"}</button>
    </div>`;
  const video = root.querySelector("video");
  const scrub = root.querySelector(".snap-scrub");
  const label = root.querySelector(".snap-frame");
  const play = root.querySelector("[data-testid=picker-play]");
  const back = root.querySelector("[data-testid=picker-back]");
  const fwd = root.querySelector("[data-testid=picker-forward]");
  const confirm = root.querySelector("[data-testid=picker-confirm]");
  const errorBox = root.querySelector(".snap-error");

  const t0 = performance.now();
  const state = { frame: Math.min(Math.max(data.start_frame || 0, 0), n - 1), events: [],
                  sent: false, ready: false, seeking: false, pendingSeek: null };
  root._snap = state;
  const log = (kind, extra) => {
    if (state.events.length < 500) {
      state.events.push({ kind, t: (performance.now() - t0) / 1000, frame: state.frame, ...extra });
    }
  };
  const clamp = (f) => Math.min(Math.max(Math.round(f), 0), n - 1);
  const show = (f) => {
    state.frame = clamp(f);
    scrub.value = String(state.frame);
    label.textContent = `${L.frame || "Frame"} ${state.frame + 1} / ${n}`;
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
      if (!state.seeking && state.pendingSeek === null) show(meta.mediaTime * fps);
      video.requestVideoFrameCallback(onFrame);
    };
    video.requestVideoFrameCallback(onFrame);
  } else {
    // Older browsers: currentTime during playback (close, and exact once paused on a seek).
    video.addEventListener("timeupdate", () => { if (!state.seeking) show(video.currentTime * fps - 0.5); });
  }

  video.addEventListener("loadeddata", () => {
    state.ready = true;
    confirm.disabled = false;
    root.dataset.ready = "1";
    seek(state.frame);
  });
  video.addEventListener("play", () => { play.textContent = L.pause || "Pause"; log("play"); });
  video.addEventListener("pause", () => { play.textContent = L.play || "Play"; });
  video.addEventListener("ended", () => { show(n - 1); log("ended"); });
  video.addEventListener("error", () => {
    const msg = (video.error && video.error.message) || "this browser cannot play the video";
    errorBox.textContent = `${L.video_error || "The video cannot be played"}: ${msg}`;
    errorBox.hidden = false;
    root.dataset.error = msg;
    root._api.setTriggerValue("error", { trial: data.trial, message: msg });
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
  root.addEventListener("keydown", (e) => {
    if (e.target === scrub) return; // the range input handles its own arrows
    if (e.key === "ArrowLeft") { step(-1); e.preventDefault(); }
    else if (e.key === "ArrowRight") { step(1); e.preventDefault(); }
    else if (e.key === " ") { play.click(); e.preventDefault(); }
  });
  confirm.addEventListener("click", () => {
    if (state.sent || !state.ready) return;
    if (!video.paused) { video.pause(); }
    state.sent = true;
    confirm.disabled = true;
    confirm.textContent = L.saving || "Saving…";
    log("select");
    root._api.setTriggerValue("confirm", { trial: data.trial, frame: state.frame, events: state.events });
  });

  show(state.frame);
  video.src = data.src;
}

export default function (component) {
  const { data, parentElement } = component;
  const key = `${data.trial}|${data.src}`;
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
  // Reruns re-invoke this function: keep the mounted player (and its position), but
  // send through the newest callbacks.
  root._api = component;
}
