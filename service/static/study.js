// live progress: poll the study (or calibration: data-url) while it is queued or running;
// reload when it ends
// (a file of its own: the page's Content-Security-Policy allows no inline script)
(function () {
  const box = document.getElementById("progress");
  const terminal = new Set(box.dataset.terminal.split(","));
  if (terminal.has(box.dataset.status)) return;
  async function poll() {
    try {
      const url = box.dataset.url || "/studies/" + encodeURIComponent(box.dataset.id);
      const resp = await fetch(url, {headers: {Accept: "application/json"}});
      if (!resp.ok) throw new Error("HTTP " + resp.status);
      const s = await resp.json();
      if (terminal.has(s.status)) { location.reload(); return; }
      const badge = box.querySelector(".status");
      badge.textContent = s.status;
      badge.className = "status status-" + s.status;
      box.querySelector("progress").value = s.progress;
      box.querySelector(".pct").textContent = Math.round(100 * s.progress) + " %";
      box.querySelector(".now").textContent =
        s.current_run ? s.current_run + ": " + (s.current_stage || "") : "";
    } catch (e) {
      console.warn("progress update failed:", e);
    }
    setTimeout(poll, 2000);
  }
  setTimeout(poll, 2000);
})();
