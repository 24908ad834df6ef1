// Pick one of several candidate views (Streamlit components v2, no build step).
//
// data: [{trial, views: [{src, label}], min_answer_s, labels}]  (one-item list)
// Sends one trigger, "choice": {trial, position}. The page knows positions only: which
// method made which picture stays on the server (it maps the position through the
// participant's seeded order), so nothing in the DOM can reveal or forge a method.
// The Choose buttons stay off until every picture has loaded and has been on screen
// min_answer_s seconds: a double click on the previous trial cannot answer this one.

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
    const L = data.labels || {};
    const minAnswerMs = 1000 * (Number(data.min_answer_s) || 0);
    let loaded = 0;
    const buttons = [];
    const enableLater = () => {
      // Counted from the moment every picture is on screen.
      setTimeout(() => {
        if (root.dataset.sent) return;
        buttons.forEach((b) => { b.disabled = false; });
        root.dataset.ready = "1";
      }, minAnswerMs);
    };
    data.views.forEach((v, i) => {
      const fig = document.createElement("figure");
      fig.className = "snap-view";
      fig.dataset.position = String(i);
      fig.innerHTML = `<img alt="${v.label}" data-testid="view-image-${i}">
        <figcaption>${v.label}</figcaption>
        <button type="button" data-testid="view-choose-${i}" disabled>${L.choose || "Choose"} ${v.label}</button>`;
      const img = fig.querySelector("img");
      const onLoad = () => { loaded += 1; if (loaded === data.views.length) enableLater(); };
      img.addEventListener("load", onLoad, { once: true });
      img.addEventListener("error", onLoad, { once: true });
      img.src = v.src;
      const button = fig.querySelector("button");
      buttons.push(button);
      button.addEventListener("click", () => {
        if (root.dataset.sent || !root.dataset.ready) return;
        root.dataset.sent = "1";
        buttons.forEach((b) => { b.disabled = true; });
        fig.classList.add("snap-chosen");
        root._api.setTriggerValue("choice", { trial: data.trial, position: i });
      });
      root.appendChild(fig);
    });
    parentElement.appendChild(root);
  }
  root._api = component;
}
