// Scripting: which firmware plugin (on-board script) runs, start/stop, SF_SCRIPT_RUNNING / SF_SCRIPT_FAILURE.
"use strict";
(function () {
  const $ = function (id) { return document.getElementById(id); };
  function flag(id, on) {
    $(id).textContent = on ? "set" : "clear";
    $(id).dataset.on = on ? "true" : "false";
  }
  function show(v) {
    $("script-running").textContent = v.running.length ? v.running.join(", ") : "none";
    flag("flag-script-running", v.script_running);
    flag("flag-script-failure", v.script_failure);
    $("script-startup").textContent = v.startup || "none";
  }
  function fill(v) {
    const sel = $("script-plugin");
    const body = $("script-list").querySelector("tbody");
    sel.textContent = ""; body.textContent = "";
    for (const p of v.available) {
      const o = document.createElement("option");
      o.value = p.name; o.textContent = p.name;
      if (v.running.indexOf(p.name) >= 0) o.selected = true;
      sel.appendChild(o);
      const tr = document.createElement("tr");
      for (const text of [p.name, p.commands.join(" ") || "–", p.description]) {
        const td = document.createElement("td"); td.textContent = text; tr.appendChild(td);
      }
      body.appendChild(tr);
    }
    show(v);
  }
  async function act(url, body) {
    const out = $("script-result");
    out.textContent = "…"; out.className = "result";
    const r = await WSG.api("POST", url, body);
    if (r.data && r.data.running) show(r.data);
    out.textContent = r.ok ? "OK" : "error " + r.status + ": " + (r.data.detail || "");
    out.className = "result " + (r.ok ? "ok" : "bad");
  }
  document.addEventListener("DOMContentLoaded", async function () {
    const r = await WSG.api("GET", "/api/scripting");
    if (r.ok) fill(r.data);
    $("script-form").addEventListener("submit", function (ev) {
      ev.preventDefault();
      act("/api/scripting/start", { plugin: $("script-plugin").value });
    });
    $("script-stop").addEventListener("click", function () { act("/api/scripting/stop"); });
    // live: the snapshot names the running plugins and carries the flags
    WSG.listeners.push(function (msg) {
      const s = msg.state;
      if (!s || !s.flag_names) return;
      $("script-running").textContent = s.plugins && s.plugins.length ? s.plugins.join(", ") : "none";
      flag("flag-script-running", s.flag_names.indexOf("SF_SCRIPT_RUNNING") >= 0);
      flag("flag-script-failure", s.flag_names.indexOf("SF_SCRIPT_FAILURE") >= 0);
    });
  });
})();
