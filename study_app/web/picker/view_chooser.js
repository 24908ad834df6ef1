// Pick one of several candidate views (Streamlit components v2, no build step).
//
// data: [{trial, views: [{src, label}], min_answer_s, labels, tab_key}]  (one-item list)
// Triggers:
//   "choice": {trial, position, client, resend}  the picture chosen, and what it was
//             chosen on (viewport, device pixel ratio, input, active time, tab id);
//   "failed": {trial, positions, tab}  pictures that did not load after retries (the
//             server records it; nothing is answered); positions [] once "Try again"
//             brought them all back;
//   "skip":   {trial, client}  "I can't see the pictures": after a picture failed, the
//             way on (the server stores the trial as skipped, never as a choice).
// The page knows positions only: which method made which picture stays on the server
// (it maps the position through the participant's seeded order), so nothing in the DOM
// can reveal or forge a method.
// The Choose buttons stay off until every picture has loaded (a failed one is loaded
// again, IMAGE_RETRIES times) and has been on screen min_answer_s seconds: a double
// click on the previous trial cannot answer this one, and no answer is ever given
// without every picture seen. A picture still failing keeps the buttons off and offers
// "Try again" and "I can't see the pictures" (skip: the trial is stored as skipped and
// the study goes on to its end and its completion code). A choice the connection lost is sent again (RESEND_MS, RESENDS), then
// the buttons open again with a message that nothing was saved.

const RESEND_MS = 4000;
const RESENDS = 3;
const IMAGE_RETRIES = 2;

function withQuery(src, q) {
  return q ? `${src}${src.includes("?") ? "&" : "?"}${q}` : src;
}

function buildChooser(root, data) {
  const L = data.labels || {};
  const minAnswerMs = 1000 * (Number(data.min_answer_s) || 0);
  const n = data.views.length;
  const status = new Array(n).fill("loading");  // loading | loaded | failed
  const tries = new Array(n).fill(0);
  const buttons = [];
  const imgs = [];
  const clock = activeClock(data.tab_key);
  const pointer = pointerTracker(root);
  const errorBox = document.createElement("div");
  errorBox.className = "snap-views-error";
  errorBox.dataset.testid = "views-error";
  errorBox.hidden = true;
  errorBox.innerHTML = `<span role="alert"></span>`;
  const message = errorBox.querySelector("span");
  const retry = document.createElement("button");
  retry.type = "button";
  retry.dataset.testid = "views-retry";
  retry.textContent = L.retry || "Try again";
  retry.hidden = true;
  errorBox.appendChild(retry);
  const skip = document.createElement("button");
  skip.type = "button";
  skip.dataset.testid = "views-skip";
  skip.textContent = L.skip || "I can't see the pictures: skip this question";
  skip.hidden = true;
  errorBox.appendChild(skip);
  let reportedFailure = false;

  let openTimer = null;
  const update = () => {
    root.dataset.loaded = String(status.filter((s) => s === "loaded").length);
    if (status.every((s) => s === "loaded")) {
      errorBox.hidden = true;
      retry.hidden = true;
      skip.hidden = true;
      delete root.dataset.failed;
      if (reportedFailure) {  // "Try again" brought them back: the server unblocks them
        reportedFailure = false;
        root._api.setTriggerValue("failed", { trial: data.trial, positions: [], tab: tabId() });
      }
      if (openTimer === null && !root.dataset.ready) {
        // Counted from the moment every picture is on screen.
        openTimer = setTimeout(() => {
          if (root.dataset.sent) return;
          buttons.forEach((b) => { b.disabled = false; });
          root.dataset.ready = "1";
        }, minAnswerMs);
      }
    } else if (status.includes("failed") && !status.includes("loading")) {
      message.textContent = L.image_error || "A picture could not be loaded, so this question cannot be answered yet.";
      errorBox.hidden = false;
      retry.hidden = false;
      skip.hidden = false;
      reportedFailure = true;
      root.dataset.failed = status.map((s, i) => (s === "failed" ? i : null)).filter((i) => i !== null).join(",");
      const positions = status.map((s, i) => (s === "failed" ? i : -1)).filter((i) => i >= 0);
      root._api.setTriggerValue("failed", { trial: data.trial, positions, tab: tabId() });
    }
  };
  const load = (i, query) => {
    status[i] = "loading";
    imgs[i].src = withQuery(data.views[i].src, query);
  };
  retry.addEventListener("click", () => {
    retry.hidden = true;
    status.forEach((s, i) => { if (s === "failed") { tries[i] = 0; load(i, `again=${Date.now()}`); } });
  });

  const client = (ev) => clientInfo(ev, pointer, clock);
  skip.addEventListener("click", (ev) => {
    if (root.dataset.sent) return;
    root.dataset.sent = "1";
    skip.disabled = true;
    retry.disabled = true;
    root._api.setTriggerValue("skip", { trial: data.trial, client: client(ev) });
  });

  data.views.forEach((v, i) => {
    const fig = document.createElement("figure");
    fig.className = "snap-view";
    fig.dataset.position = String(i);
    fig.innerHTML = `<img alt="${v.label}" data-testid="view-image-${i}">
      <figcaption>${v.label}</figcaption>
      <button type="button" data-testid="view-choose-${i}" disabled>${L.choose || "Choose"} ${v.label}</button>`;
    const img = fig.querySelector("img");
    imgs.push(img);
    img.addEventListener("load", () => {
      if (img.naturalWidth > 0) { status[i] = "loaded"; update(); }
    });
    img.addEventListener("error", () => {
      // Loaded again first: a dropped request is not a missing picture.
      if (tries[i] < IMAGE_RETRIES) {
        tries[i] += 1;
        setTimeout(() => load(i, `retry=${tries[i]}`), 400 * tries[i]);
        return;
      }
      status[i] = "failed";
      update();
    });
    const button = fig.querySelector("button");
    buttons.push(button);
    button.addEventListener("click", (ev) => {
      if (root.dataset.sent || !root.dataset.ready || !status.every((s) => s === "loaded")) return;
      root.dataset.sent = "1";
      delete root.dataset.lost;
      errorBox.hidden = true;
      buttons.forEach((b) => { b.disabled = true; });
      fig.classList.add("snap-chosen");
      const payload = { trial: data.trial, position: i, client: client(ev) };
      root._api.setTriggerValue("choice", payload);
      let resends = 0;
      clearInterval(root._resend);
      root._resend = setInterval(() => {
        if (!root.isConnected) { clearInterval(root._resend); clock.clear(); return; }
        resends += 1;
        if (resends <= RESENDS) { root._api.setTriggerValue("choice", { ...payload, resend: true }); return; }
        clearInterval(root._resend);
        delete root.dataset.sent;
        root.dataset.lost = "1";
        fig.classList.remove("snap-chosen");
        message.textContent = L.not_saved_choice || "The connection was lost: your choice was not saved. Please choose again.";
        errorBox.hidden = false;
        buttons.forEach((b) => { b.disabled = false; });
      }, RESEND_MS);
    });
    root.appendChild(fig);
  });
  root.appendChild(errorBox);
  data.views.forEach((v, i) => load(i, ""));
}

export default function (component) {
  const { parentElement } = component;
  const data = component.data[0];  // sent as [data] (see picker/__init__.py)
  const key = `${data.trial}|${data.views.map((v) => v.src).join("|")}`;
  let root = parentElement.querySelector(".snap-views");
  if (!root || root.dataset.key !== key) {
    if (root) root.remove();
    root = document.createElement("div");
    root.className = "snap-views";
    root.dataset.key = key;
    root._api = component;
    parentElement.appendChild(root);
    buildChooser(root, data);
  }
  root._api = component;
}
