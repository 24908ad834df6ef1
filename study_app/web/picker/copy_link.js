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
      let copied = false;
      try {
        await navigator.clipboard.writeText(text);
        copied = true;
      } catch (e) {
        // No clipboard API (an insecure origin) or no permission: the old way, which
        // says whether it copied.
        const ta = document.createElement("textarea");
        ta.value = text;
        document.body.appendChild(ta);
        ta.select();
        try { copied = document.execCommand("copy") === true; } catch (e2) { copied = false; }
        ta.remove();
      }
      // "Copied" only when it was: otherwise the participant is told to copy it by hand.
      b.textContent = copied ? b.dataset.copied : b.dataset.failed;
      if (copied) b.dataset.done = "1"; else b.dataset.done = "failed";
    });
    parentElement.appendChild(b);
  }
  b.dataset.text = data.text;
  b.dataset.copied = L.copied || "Copied";
  b.dataset.failed = L.copy_failed || "Could not copy: please select the link and copy it";
  if (!b.dataset.done) b.textContent = L.copy || "Copy the link";
}
