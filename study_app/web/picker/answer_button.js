// A button whose press is an answer (Streamlit components v2, no build step): the slider
// fallback's "Confirm this frame" and the attention check's "Continue". Like the pickers,
// it reports what the answer was given on (client.js).
//
// data: [{label, tab_key, testid}]  (one-item list; tab_key names the participant's
//        trial, so the page's active time is the one the trial's pickers counted)
// Trigger "press": {client}  viewport, device pixel ratio, input, active time, tab id.

export default function (component) {
  const { parentElement } = component;
  const data = component.data[0];
  let root = parentElement.querySelector(".snap-answer");
  if (!root || root.dataset.key !== data.tab_key) {
    if (root) root.remove();
    root = document.createElement("div");
    root.className = "snap-answer";
    root.dataset.key = data.tab_key;
    const clock = activeClock(data.tab_key);
    const pointer = pointerTracker(root);
    const button = document.createElement("button");
    button.type = "button";
    button.className = "snap-answer-button";
    button.dataset.testid = data.testid || "answer-button";
    button.addEventListener("click", (ev) => {
      root._api.setTriggerValue("press", { client: clientInfo(ev, pointer, clock) });
    });
    root.appendChild(button);
    parentElement.appendChild(root);
  }
  root._api = component;
  root.querySelector("button").textContent = data.label;
}
