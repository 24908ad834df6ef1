// Pick one of several candidate views (Streamlit components v2, no build step).
//
// data: {trial, views: [{src, method, label}], labels}
// Sends one trigger, "choice": {trial, position, method}. The method echoes the label
// the page was built with, so the server can check it against the participant's
// seeded order (a stale page or an edited label is refused, not miscounted).

export default function (component) {
  const { data, parentElement } = component;
  const key = `${data.trial}|${data.views.map((v) => v.src).join("|")}`;
  let root = parentElement.querySelector(".snap-views");
  if (!root || root.dataset.key !== key) {
    if (root) root.remove();
    root = document.createElement("div");
    root.className = "snap-views";
    root.dataset.key = key;
    const L = data.labels || {};
    data.views.forEach((v, i) => {
      const fig = document.createElement("figure");
      fig.className = "snap-view";
      fig.dataset.position = String(i);
      fig.dataset.method = v.method;
      fig.innerHTML = `<img alt="${v.label}" src="${v.src}" data-testid="view-image-${i}">
        <figcaption>${v.label}</figcaption>
        <button type="button" data-testid="view-choose-${i}">${L.choose || "Choose"} ${v.label}</button>`;
      fig.querySelector("button").addEventListener("click", () => {
        if (root.dataset.sent) return;
        root.dataset.sent = "1";
        root.querySelectorAll("button").forEach((b) => { b.disabled = true; });
        fig.classList.add("snap-chosen");
        root._api.setTriggerValue("choice", {
          trial: data.trial, position: Number(fig.dataset.position), method: fig.dataset.method,
        });
      });
      root.appendChild(fig);
    });
    parentElement.appendChild(root);
  }
  root._api = component;
}
