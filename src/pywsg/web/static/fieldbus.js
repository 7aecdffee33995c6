// Diagnosis → Fieldbus Monitor: the register images byte by byte, decoded, live (manual 003 §6).
"use strict";
(function () {
  WSG.liveParams = { fieldbus: "1" };
  function valueCell(reg) {
    const td = document.createElement("td");
    if (reg.kind === "flags") {
      for (const b of reg.bits) {
        const lab = document.createElement("label"); lab.className = "bit" + (b.on ? " on" : "");
        const cb = document.createElement("input"); cb.type = "checkbox"; cb.checked = b.on; cb.disabled = true;
        lab.appendChild(cb); lab.appendChild(document.createTextNode(" " + b.name));
        td.appendChild(lab);
      }
    } else {
      td.textContent = reg.text;
      if (reg.flags && reg.flags.length) {
        const d = document.createElement("div"); d.className = "small muted"; d.textContent = reg.flags.join(" ");
        td.appendChild(d);
      }
    }
    return td;
  }
  function render(id, image) {
    const tbody = document.querySelector("#" + id + " tbody");
    tbody.textContent = "";
    if (!image.available) {
      const tr = document.createElement("tr"); const td = document.createElement("td");
      td.colSpan = 4; td.className = "muted"; td.textContent = "no fieldbus controller attached";
      tr.appendChild(td); tbody.appendChild(tr); return;
    }
    const starts = {};
    for (const r of image.registers) starts[r.offset] = r;
    image.bytes.forEach(function (b) {
      const tr = document.createElement("tr");
      tr.dataset.index = b.index;
      const idx = document.createElement("td"); idx.textContent = b.index;
      const hex = document.createElement("td"); hex.textContent = b.hex; hex.className = "hex";
      tr.appendChild(idx); tr.appendChild(hex);
      const reg = starts[b.index];
      if (reg) {
        const name = document.createElement("td"); name.textContent = reg.name; name.rowSpan = reg.size;
        const val = valueCell(reg); val.rowSpan = reg.size; val.className = (val.className + " value").trim();
        val.dataset.register = reg.name;
        tr.appendChild(name); tr.appendChild(val);
      }
      tbody.appendChild(tr);
    });
    tbody.parentElement.dataset.hex = image.hex;
  }
  // Bus State (003 §6): the rows each attached bus gives (its bus_state()), under the bus's name
  function busState(buses) {
    const tbody = document.querySelector("#fb-bus tbody");
    tbody.textContent = "";
    if (!buses || !buses.length) {
      const tr = document.createElement("tr"); const td = document.createElement("td");
      td.className = "muted"; td.dataset.row = "Interface state";
      td.textContent = "Offline: no fieldbus (wsg sim --modbus-port N)";
      tr.appendChild(td); tbody.appendChild(tr); return;
    }
    for (const bus of buses) {
      if (buses.length > 1) {
        const tr = document.createElement("tr"); const th = document.createElement("th");
        th.colSpan = 2; th.textContent = bus.name; tr.appendChild(th); tbody.appendChild(tr);
      }
      for (const row of bus.rows) {
        const tr = document.createElement("tr"); tr.dataset.bus = bus.name;
        const th = document.createElement("th"); th.textContent = row.label;
        const td = document.createElement("td"); td.textContent = row.text; td.dataset.row = row.label;
        tr.appendChild(th); tr.appendChild(td); tbody.appendChild(tr);
      }
    }
  }
  let lastKey = "";
  WSG.listeners.push(function (msg) {
    const fb = msg.fieldbus;
    if (!fb) return;
    busState(fb.buses);
    const key = JSON.stringify([fb.output.hex, fb.input.hex, fb.available]);
    if (key === lastKey) return;  // re-render only on change
    lastKey = key;
    render("fb-output", fb.output);
    render("fb-input", fb.input);
  });
})();
