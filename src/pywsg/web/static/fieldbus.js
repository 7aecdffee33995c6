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
  // Bus State (003 §6): station address from Settings → Command Interface, the rest from the server
  function busState(bus) {
    if (!bus) return;
    const el = document.getElementById("fb-state");
    const ago = bus.last_write === null ? "no write yet" :
      "last write " + Math.max(0, bus.now - bus.last_write).toFixed(1) + " s ago";
    const masters = bus.masters + (bus.masters === 1 ? " master" : " masters") + " connected";
    el.textContent = bus.state === "online" ? "Online: " + masters + ", " + ago :
      bus.state === "waiting" ? "Waiting: no Modbus master connected (" + ago + ")" :
      "Offline: no Modbus/TCP server (wsg sim --modbus-port)";
    el.dataset.state = bus.state;
    document.getElementById("fb-interface").textContent = "Modbus/TCP" + (bus.port ? " (port " + bus.port + ")" : "");
  }
  WSG.api("GET", "/api/interface").then(function (r) {
    if (!r.ok) return;
    document.getElementById("fb-station").textContent = r.data.values.profibus_address +
      " (stored under Settings → Command Interface; Modbus/TCP answers any unit id)";
  });
  document.getElementById("fb-bitrate").textContent = "n/a: Modbus/TCP runs over Ethernet (a PROFIBUS WSG detects it)";
  let lastKey = "";
  WSG.listeners.push(function (msg) {
    const fb = msg.fieldbus;
    if (!fb) return;
    busState(fb.bus);
    const key = JSON.stringify([fb.output.hex, fb.input.hex, fb.available]);
    if (key === lastKey) return;  // re-render only on change
    lastKey = key;
    render("fb-output", fb.output);
    render("fb-input", fb.input);
  });
})();
