// Diagnosis → System Log: history from /api/log, then new entries live from the WebSocket.
// Times in ISO 8601 UTC with the date; a line repeating the one before it (numbers aside, e.g.
// "disconnect announced by 127.0.0.1:50312") is folded into it with a count.
"use strict";
(function () {
  const tbody = document.querySelector("#log-table tbody");
  const filter = document.getElementById("log-filter");
  const follow = document.getElementById("log-follow");
  let last = 0;
  let prev = null;  // {key, tr, count}
  function timeText(t) {
    if (typeof t !== "number") return t === null || t === undefined ? "" : String(t);
    return t > 1e9 ? new Date(t * 1000).toISOString().replace("T", " ").replace("Z", "") : t.toFixed(3) + " s";
  }
  function foldKey(e) { return String(e.level) + "|" + String(e.message).replace(/\d+/g, "#"); }
  function add(entries) {
    for (const e of entries) {
      if (e.seq <= last) continue;
      last = e.seq;
      const when = timeText(e.wall_time !== undefined ? e.wall_time : e.time);
      const key = foldKey(e);
      if (prev && prev.key === key) {
        prev.count += 1;
        const cells = prev.tr.children;
        cells[0].textContent = e.seq;
        cells[1].textContent = when;
        cells[3].textContent = e.message + "  (×" + prev.count + ")";
        prev.tr.dataset.count = prev.count;
        continue;
      }
      const tr = document.createElement("tr");
      tr.className = "lvl-" + String(e.level).toLowerCase();
      for (const v of [e.seq, when, e.level, e.message]) {
        const td = document.createElement("td"); td.textContent = v; tr.appendChild(td);
      }
      tbody.appendChild(tr);
      prev = { key, tr, count: 1 };
      applyFilter(tr);
    }
    while (tbody.children.length > 2000) tbody.removeChild(tbody.firstChild);
    if (follow.checked && entries.length) window.scrollTo(0, document.body.scrollHeight);
  }
  function applyFilter(tr) {
    const q = filter.value.trim().toLowerCase();
    tr.hidden = q !== "" && !tr.textContent.toLowerCase().includes(q);
  }
  filter.addEventListener("input", function () { for (const tr of tbody.children) applyFilter(tr); });
  WSG.listeners.push(function (msg) { if (msg.log) add(msg.log); });
  WSG.liveParams = { log: "0" };
})();
