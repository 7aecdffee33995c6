// Settings → Command Interface / Motion Configuration: a form built from /api/settings.
"use strict";
(function () {
  const form = document.getElementById("settings-form");
  const group = form.dataset.group;
  const tbody = document.querySelector("#settings-table tbody");
  let fields = [];
  let values = {};
  const POWER_CYCLE = ["model", "serial_number", "finger1", "finger2"];  // like a real device: a restart

  function input(f, value) {
    const kind = f.kind.replace("?", "");
    let el;
    if (kind === "bool") {
      el = document.createElement("input"); el.type = "checkbox"; el.checked = !!value;
    } else if (f.choices.length) {
      el = document.createElement("select");
      el.dataset.json = "1";
      const opts = f.kind.endsWith("?") ? [[null, "(none)"]].concat(f.choices) : f.choices;
      for (const c of opts) {
        const o = document.createElement("option"); o.value = JSON.stringify(c[0]); o.textContent = c[1];
        el.appendChild(o);
      }
      el.value = JSON.stringify(value === undefined ? null : value);
    } else {
      el = document.createElement("input");
      el.type = (kind === "int" || kind === "float") ? "number" : "text";
      if (kind === "float") el.step = "any";
      el.value = kind === "json" ? JSON.stringify(value) : (value === null ? "" : value);
    }
    el.name = f.name; el.id = "set-" + f.name; el.dataset.kind = f.kind;
    return el;
  }

  function render() {
    tbody.textContent = "";
    for (const f of fields) {
      if (f.group !== group) continue;
      const tr = document.createElement("tr");
      const th = document.createElement("th");
      const el = input(f, values[f.name]);
      const td = document.createElement("td");
      if (el.type === "checkbox") {
        // the hit area is a label around the box (>= 40 px); the row header names it
        const caption = document.createElement("span"); caption.id = "set-" + f.name + "-label"; caption.textContent = f.label;
        th.appendChild(caption);
        el.setAttribute("aria-labelledby", caption.id);
        const hit = document.createElement("label"); hit.className = "check"; hit.appendChild(el);
        td.appendChild(hit);
      } else {
        const label = document.createElement("label"); label.htmlFor = "set-" + f.name; label.textContent = f.label;
        th.appendChild(label);
        td.appendChild(el);
      }
      if (f.unit) { const u = document.createElement("span"); u.className = "muted"; u.textContent = " " + f.unit; td.appendChild(u); }
      const err = document.createElement("span"); err.className = "field-error"; err.dataset.for = f.name;
      td.appendChild(err);
      if (f.help) { const h = document.createElement("div"); h.className = "muted small"; h.textContent = f.help; td.appendChild(h); }
      tr.appendChild(th); tr.appendChild(td); tbody.appendChild(tr);
    }
  }

  function readValue(el) {
    const kind = el.dataset.kind.replace("?", "");
    if (el.dataset.json) return JSON.parse(el.value);
    if (kind === "bool") return el.checked;
    if (kind === "int") return el.value === "" ? null : (Number.isInteger(Number(el.value)) ? Number(el.value) : el.value);
    if (kind === "str" && el.value === "" && el.dataset.kind.endsWith("?")) return null;
    if (kind === "float") return el.value === "" ? null : Number(el.value);
    if (kind === "json") { try { return JSON.parse(el.value); } catch (e) { return el.value; } }
    return el.value;
  }

  function showInterfaces(info) {
    const panel = document.getElementById("interfaces-panel");
    if (group !== "interface" || !info) return;
    const tb = document.querySelector("#interfaces tbody");
    tb.textContent = "";
    const rows = Array.isArray(info) ? info.map(function (v, i) { return [String(i), v]; }) : Object.entries(info);
    for (const [k, v] of rows) {
      const tr = document.createElement("tr");
      const th = document.createElement("th"); th.textContent = k;
      const td = document.createElement("td"); td.textContent = typeof v === "object" ? JSON.stringify(v) : String(v);
      tr.appendChild(th); tr.appendChild(td); tb.appendChild(tr);
    }
    panel.hidden = false;
  }

  async function load() {
    const r = await WSG.api("GET", "/api/settings");
    fields = r.data.fields; values = r.data.values;
    document.getElementById("settings-file").textContent = r.data.settings_file ?
      "Saved to " + r.data.settings_file + "." : "No settings file: changes last until the simulator stops.";
    render();
    showInterfaces(r.data.interfaces);
    form.dataset.loaded = "1";
  }

  form.addEventListener("submit", async function (ev) {
    ev.preventDefault();
    const changes = {};
    for (const el of form.querySelectorAll("[name]")) {
      const v = readValue(el);
      if (JSON.stringify(v) !== JSON.stringify(values[el.name])) changes[el.name] = v;
    }
    const out = document.getElementById("settings-result");
    if (!Object.keys(changes).length) { out.textContent = "nothing changed"; out.className = "result"; return; }
    const cycling = Object.keys(changes).filter(function (k) { return POWER_CYCLE.indexOf(k) >= 0; });
    if (cycling.length && !window.confirm("Changing " + cycling.join(", ") + " power-cycles the virtual gripper: " +
        "a running motion stops and homing is lost (the fingers must be referenced again). Apply?")) {
      out.textContent = "not applied"; out.className = "result"; return;
    }
    const r = await WSG.api("POST", "/api/settings", changes);
    WSG.showErrors(form, r.data && r.data.errors);
    if (r.ok) {
      values = r.data.values;
      out.textContent = "Applied: " + r.data.changed.join(", ") + (r.data.saved ? " (saved)" : "");
      out.className = "result ok";
    } else {
      out.textContent = "Not applied: " + (r.data.detail || r.status);
      out.className = "result bad";
    }
  });
  load();

  // -- Motion Configuration: statistics, soft limits, jog (Command Interface: the device tag) -----
  async function loadMotion() {
    const st = await WSG.api("GET", "/api/statistics");
    if (st.ok) {
      document.getElementById("stat-total").textContent = st.data.total;
      document.getElementById("stat-no-part").textContent = st.data.no_part;
      document.getElementById("stat-lost").textContent = st.data.lost_part;
    }
    const sl = await WSG.api("GET", "/api/soft-limits");
    if (sl.ok) {
      document.getElementById("soft-now").textContent = sl.data.minus === null ? "none set" :
        WSG.fmt(sl.data.minus, 2, "mm") + " … " + WSG.fmt(sl.data.plus, 2, "mm");
    }
  }
  if (document.getElementById("motion-panels")) {
    loadMotion();
    for (const id of ["form-stats", "form-soft-limits"]) {
      // when the common handler has the answer: show what the device has now
      document.getElementById(id).addEventListener("wsg:done", loadMotion);
    }
    // the Overdrive selector shows what the device has (SF_OVERDRIVE_MODE) until someone changes it
    const ovr = document.querySelector("#form-overdrive select[name=on]");
    ovr.addEventListener("change", function () { ovr.dataset.edited = "1"; });
    document.getElementById("form-overdrive").addEventListener("wsg:done", function () { delete ovr.dataset.edited; });
    WSG.listeners.push(function (msg) {
      if (!msg.state || ovr.dataset.edited) return;
      const on = msg.state.flag_names.indexOf("SF_OVERDRIVE_MODE") >= 0 ? "true" : "false";
      if (ovr.value !== on) ovr.value = on;
    });
    const jogForm = document.getElementById("form-jog");
    jogForm.addEventListener("submit", function (ev) { ev.stopImmediatePropagation(); ev.preventDefault(); });
    const out = jogForm.querySelector("output.result");
    let jogging = false;
    async function jog(direction) {
      const speed = Number(jogForm.querySelector("[name=speed]").value || 0);
      const r = await WSG.api("POST", "/api/jog", direction === "stop" ? { direction } : { direction, speed });
      WSG.showErrors(jogForm, r.data && r.data.errors);
      WSG.showResult(out, r.ok, r.ok ? (direction === "stop" ? "stopped" : "jogging " + direction) :
        (r.data.status || "error") + ": " + (r.data.detail || ""));
    }
    for (const btn of jogForm.querySelectorAll("button.jog")) {
      const start = function (ev) { ev.preventDefault(); if (!jogging) { jogging = true; jog(btn.dataset.direction); } };
      const end = function () { if (jogging) { jogging = false; jog("stop"); } };
      btn.addEventListener("pointerdown", start);
      btn.addEventListener("pointerup", end);
      btn.addEventListener("pointerleave", end);
      btn.addEventListener("blur", end);
      btn.addEventListener("keydown", function (ev) { if ((ev.key === " " || ev.key === "Enter") && !ev.repeat) start(ev); });
      btn.addEventListener("keyup", function (ev) { if (ev.key === " " || ev.key === "Enter") end(); });
    }
  }
  const tagInput = document.getElementById("tag-input");
  if (tagInput) {
    WSG.api("GET", "/api/identity").then(function (r) { if (r.ok && r.data.tag !== null) tagInput.value = r.data.tag; });
    document.getElementById("form-tag").addEventListener("wsg:done", WSG.loadIdentity);
  }
})();
