// Scripting: which on-board script runs, start/stop it; the two script flags live.
"use strict";
(function () {
  const select = document.getElementById("script-name");
  function show(d) {
    document.getElementById("script-running").textContent = d.running.length ? d.running.join(", ") : "none";
    document.getElementById("script-startup").textContent = d.startup || "none";
    if (!select.options.length) {
      for (const name of d.available) {
        const o = document.createElement("option"); o.value = name; o.textContent = name; select.appendChild(o);
      }
    }
  }
  async function load() { const r = await WSG.api("GET", "/api/script"); if (r.ok) show(r.data); }
  const form = document.getElementById("form-script");
  form.addEventListener("wsg:done", function (ev) { if (ev.detail.ok) show(ev.detail.data); });
  document.getElementById("script-stop").addEventListener("click", async function () {
    const r = await WSG.api("POST", "/api/script/stop");
    WSG.showResult(form.querySelector("output.result"), r.ok, r.ok ? "stopped" : "error: " + (r.data.detail || r.status));
    if (r.ok) show(r.data);
  });
  WSG.listeners.push(function (msg) {
    const names = msg.state.flag_names;
    document.getElementById("script-flag-running").textContent = names.indexOf("SF_SCRIPT_RUNNING") >= 0 ? "on" : "off";
    document.getElementById("script-flag-failure").textContent = names.indexOf("SF_SCRIPT_FAILURE") >= 0 ? "on" : "off";
    if (Array.isArray(msg.state.plugins)) {
      document.getElementById("script-running").textContent = msg.state.plugins.length ? msg.state.plugins.join(", ") : "none";
    }
  });
  load();
})();
