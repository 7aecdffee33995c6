// Settings → Command Interface / Motion Configuration: a form built from /api/settings.
"use strict";
(function () {
  const form = document.getElementById("settings-form");
  const group = form.dataset.group;
  const tbody = document.querySelector("#settings-table tbody");
  let fields = [];
  let values = {};

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
      const label = document.createElement("label"); label.htmlFor = "set-" + f.name; label.textContent = f.label;
      th.appendChild(label);
      const td = document.createElement("td");
      td.appendChild(input(f, values[f.name]));
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
})();
