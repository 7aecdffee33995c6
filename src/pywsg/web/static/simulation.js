// Simulation: the forms are wired by common.js; "Now" shows the part, block and faults the
// virtual gripper has (GET /api/sim/world), refreshed after each form and every second.
"use strict";
(function () {
  async function load() {
    const r = await WSG.api("GET", "/api/sim/world");
    if (!r.ok) return;
    const w = r.data;
    document.getElementById("world-part").textContent = w.part === null ? "none"
      : WSG.fmt(w.part, 2, "mm") + " wide" + (w.part_inside ? ", a ring gripped from inside" : ", gripped from outside");
    document.getElementById("world-block").textContent = w.blocked_at === null ? "none" : "at " + WSG.fmt(w.blocked_at, 2, "mm");
    document.getElementById("world-faults").textContent = w.faults.length ? w.faults.join(", ") : "none";
    document.getElementById("world-temp").textContent = WSG.fmt(w.temperature, 1, "°C");
  }
  for (const form of document.querySelectorAll("form.cmd")) form.addEventListener("wsg:done", load);
  load();
  setInterval(function () { if (WSG.live) load(); }, 1000);
})();
