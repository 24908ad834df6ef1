// A button that copies a text (the participant's personal link) to the clipboard
// (Streamlit components v2, no build step). data: [{text, labels: {copy, copied}}].
// Phones show no hover copy icon on code blocks, and the link itself may be cut off.

export default function (component) {
  const { parentElement } = component;
  const data = component.data[0];
  const L = data.labels || {};
  let b = parentElement.querySelector("button.snap-copy");
  if (!b) {
    b = document.createElement("button");
    b.type = "button";
    b.className = "snap-copy";
    b.dataset.testid = "copy-link";
    b.addEventListener("click", async () => {
      const text = b.dataset.text;
      try {
        await navigator.clipboard.writeText(text);
      } catch (e) {
        // No clipboard API (an insecure origin): the old way.
        const ta = document.createElement("textarea");
        ta.value = text;
        document.body.appendChild(ta);
        ta.select();
        document.execCommand("copy");
        ta.remove();
      }
      b.textContent = b.dataset.copied;
      b.dataset.done = "1";
    });
    parentElement.appendChild(b);
  }
  b.dataset.text = data.text;
  b.dataset.copied = L.copied || "Copied";
  if (!b.dataset.done) b.textContent = L.copy || "Copy the link";
}
