// Settings → Command Interface: the stored interface and network values (/api/interface).
// Loaded with defer beside settings.js, which runs the protocol options form of the same page.
"use strict";
(function () {
  const form = document.getElementById("iface-form");
  const $ = function (id) { return document.getElementById(id); };
  let values = {};

  function show(data) {
    values = data.values;
    const sel = $("if-interface");
    if (!sel.options.length) {
      for (const [key, label] of Object.entries(data.interfaces)) {
        const o = document.createElement("option"); o.value = key; o.textContent = label; sel.appendChild(o);
      }
    }
    for (const [name, v] of Object.entries(values)) {
      const el = form.querySelector('[name="' + name + '"]');
      if (!el) continue;
      if (el.type === "checkbox") el.checked = !!v; else el.value = v;
    }
    for (const div of form.querySelectorAll(".not-applied")) div.textContent = data.notes[div.dataset.note] || "";
    $("iface-stored").textContent = data.problem ? data.problem :
      (data.stored_in ? "Stored in " + data.stored_in + "." : "No settings file: stored until the simulator stops.");
    form.dataset.loaded = "1";
  }

  function read() {
    const changes = {};
    for (const el of form.querySelectorAll("[name]")) {
      let v = el.type === "checkbox" ? el.checked : el.value.trim();
      if (el.dataset.type === "int") v = /^-?\d+$/.test(v) ? parseInt(v, 10) : v;
      if (JSON.stringify(v) !== JSON.stringify(values[el.name])) changes[el.name] = v;
    }
    return changes;
  }

  form.addEventListener("submit", async function (ev) {
    ev.preventDefault();
    const out = $("iface-result");
    const changes = read();
    if (!Object.keys(changes).length) { out.textContent = "nothing changed"; out.className = "result"; return; }
    out.textContent = "…"; out.className = "result";
    const r = await WSG.api("POST", "/api/interface", changes);
    WSG.showErrors(form, r.data && r.data.errors);
    if (r.ok) {
      show(r.data);
      out.textContent = "Stored: " + r.data.changed.join(", ") + " (not applied: virtual gripper)";
      out.className = "result ok";
    } else {
      out.textContent = "Not stored: " + (r.data.detail || r.status);
      out.className = "result bad";
    }
  });

  document.addEventListener("DOMContentLoaded", async function () {
    const r = await WSG.api("GET", "/api/interface");
    if (r.ok) show(r.data);
  });
})();
