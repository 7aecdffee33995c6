// Diagnosis → System Log: history from /api/log, then new entries live from the WebSocket.
"use strict";
(function () {
  const tbody = document.querySelector("#log-table tbody");
  const filter = document.getElementById("log-filter");
  const follow = document.getElementById("log-follow");
  let last = 0;
  function timeText(t) {
    if (typeof t !== "number") return t === null || t === undefined ? "" : String(t);
    return t > 1e9 ? new Date(t * 1000).toLocaleTimeString() : t.toFixed(3) + " s";
  }
  function add(entries) {
    for (const e of entries) {
      if (e.seq <= last) continue;
      last = e.seq;
      const tr = document.createElement("tr");
      tr.className = "lvl-" + String(e.level).toLowerCase();
      for (const v of [e.seq, timeText(e.wall_time !== undefined ? e.wall_time : e.time), e.level, e.message]) {
        const td = document.createElement("td"); td.textContent = v; tr.appendChild(td);
      }
      tbody.appendChild(tr);
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
