// live progress: poll the study (or calibration: data-url) while it is queued or running;
// reload when it ends. The same words as demscale job and demscale study: the fraction of
// the planned and added work, runs done of the runs, the run and its stage, the time left
// (a file of its own: the page's Content-Security-Policy allows no inline script)
(function () {
  const box = document.getElementById("progress");
  const terminal = new Set(box.dataset.terminal.split(","));
  if (terminal.has(box.dataset.status)) return;
  // "45 s", "3 min 20 s", "1 h 05 min" (engine.study.run.duration_words)
  function duration(seconds) {
    if (seconds === null || seconds === undefined) return "-";
    const s = Math.max(0, Math.round(seconds));
    const two = (n) => String(n).padStart(2, "0");
    if (s < 60) return s + " s";
    if (s < 3600) return Math.floor(s / 60) + " min " + two(s % 60) + " s";
    return Math.floor(s / 3600) + " h " + two(Math.floor((s % 3600) / 60)) + " min";
  }
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
      box.querySelector(".pct").textContent = (100 * s.progress).toFixed(1) + " %";
      const added = s.runs_added ? " (" + s.runs_added + " added)" : "";
      box.querySelector(".runs").textContent =
        "· " + (s.runs_done ?? 0) + "/" + s.n_runs + " runs done" + added;
      box.querySelector(".now").textContent =
        s.current_run ? "· " + s.current_run + ": " + (s.current_stage || "") : "";
      box.querySelector(".eta").textContent =
        s.status === "running" ? "· ETA " + duration(s.eta) : "";
    } catch (e) {
      console.warn("progress update failed:", e);
    }
    setTimeout(poll, 2000);
  }
  setTimeout(poll, 2000);
})();
