// live progress: poll the JSON lists while some study or calibration is queued or running
// (a file of its own: the page's Content-Security-Policy allows no inline script)
(function () {
  for (const table of document.querySelectorAll("table[data-url]")) {
    const terminal = new Set(table.dataset.terminal.split(","));
    const rows = () => Array.from(table.querySelectorAll("tbody tr"));
    async function poll() {
      if (!rows().some(r => !terminal.has(r.dataset.status))) return;
      try {
        const resp = await fetch(table.dataset.url + "?limit=200", {headers: {Accept: "application/json"}});
        if (!resp.ok) throw new Error("HTTP " + resp.status);
        const byId = new Map((await resp.json()).data.map(s => [s.id, s]));
        for (const row of rows()) {
          const s = byId.get(row.dataset.id);
          if (!s) continue;
          row.dataset.status = s.status;
          const badge = row.querySelector(".status");
          badge.textContent = s.status;
          badge.className = "status status-" + s.status;
          row.querySelector("progress").value = s.progress;
          row.querySelector(".pct").textContent = Math.round(100 * s.progress) + " %";
          row.querySelector(".now").textContent = s.status === "running" && s.current_run
            ? s.current_run + ": " + (s.current_stage || "") : (s.error || "").slice(0, 80);
          row.querySelector(".runtime").textContent =
            s.run_time === null ? "-" : Math.round(s.run_time) + " s";
        }
      } catch (e) {
        console.warn("progress update failed:", e);
      }
      setTimeout(poll, 2000);
    }
    setTimeout(poll, 2000);
  }
})();
