// The WSG Commander page (wsg commander): Connect dialog, predefined commands, the Custom Command
// Editor with live decoding, the Communication Log with a byte converter, Stop / FAST STOP / Ack.
// No dependencies, no build step. The server does the parsing and the sending (one parser for the
// CLI and the page: pywsg.protocol.editor); this script only shows what it answers.
"use strict";
(function () {
  const $ = function (id) { return document.getElementById(id); };
  let csrf = document.querySelector('meta[name="csrf-token"]').content;
  const MAX_ROWS = 1000;  // log lines kept on the page (the server keeps more; the saved files have them)
  const AUTO_UPDATE = new Set([0x40, 0x41, 0x43, 0x44, 0x45]);
  let connected = false;

  function announce(text) { const a = $("announce"); if (a.textContent !== text) a.textContent = text; }
  function banner(text, kind) {
    const b = $("banner");
    b.textContent = text || "";
    b.className = "banner " + (kind || "");
    b.hidden = !text;
  }

  function request(method, url, body) {
    return window.wsgRequest(method, url, body, csrf, "the Commander (is wsg commander running?)");
  }
  async function api(method, url, body) {
    let r = await request(method, url, body);
    if (r.status === 403 && /CSRF/.test(r.data.detail || "")) {  // the Commander restarted: a fresh token
      const t = await request("GET", "/api/csrf");
      if (t.ok) { csrf = t.data.token; r = await request(method, url, body); }
    }
    return r;
  }

  function fmt(v, digits, unit) {
    if (v === null || v === undefined || Number.isNaN(v)) return "–";
    return Number(v).toFixed(digits) + " " + unit;
  }
  function setResult(out, r) {
    if (!out) return;
    const bad = !/^E_SUCCESS|^E_CMD_PENDING|^sent/.test(r.status || "");
    let text = r.command + ": " + r.status;
    if (r.values !== undefined && r.values !== null) text += " → " + (typeof r.values === "object" ? JSON.stringify(r.values) : r.values);
    if (r.message) text += " (" + r.message + ")";
    out.textContent = text;
    out.className = "result " + (bad ? "bad" : "ok");
  }
  function failure(out, r) {
    out.textContent = r.data.detail || ("error " + r.status);
    out.className = "result bad";
  }

  // -- connection ------------------------------------------------------------------------------
  function showConnection(c) {
    connected = c.status === "connected";
    $("c-dot").className = "dot " + (connected ? "on" : "off");
    const text = { connected: "connected to ", connecting: "connecting to ", lost: "CONNECTION LOST: ",
      silent: "NO ANSWER from ", disconnected: "not connected" }[c.status] || c.status;
    $("c-conn").textContent = c.status === "disconnected" ? text : text + (c.url || "");
    $("c-url").textContent = c.url ? c.url : "no gripper";
    $("btn-disconnect").disabled = !(connected || c.status === "lost" || c.status === "silent");
    document.body.classList.toggle("offline", !connected);
    if (c.status === "lost") { banner(c.reason || "connection lost", "bad"); announce("Connection lost"); }
    else if (c.status === "silent") { banner(c.reason || "the gripper does not answer", "bad"); announce("No answer from the gripper"); }
    else if (c.status === "disconnected" && c.reason) banner(c.reason, "info");
    else if (c.status === "connected" && c.reason) banner(c.reason, "info");
    else banner("");
  }

  // -- live state --------------------------------------------------------------------------------
  let lastState = "";
  function showState(s) {
    $("s-state").textContent = s.gripper_state || "–";
    $("s-state").className = s.gripper_state ? "state-" + s.gripper_state : "";
    $("s-width").textContent = s.referenced === false ? "[n/a]" : fmt(s.width, 2, "mm");
    $("s-speed").textContent = fmt(s.speed, 1, "mm/s");
    $("s-force").textContent = fmt(s.force, 1, "N");
    const ul = $("s-flags");
    ul.textContent = "";
    for (const f of s.flags || []) {
      const li = document.createElement("li");
      li.className = "on"; li.dataset.flag = f; li.textContent = f;
      ul.appendChild(li);
    }
    const now = (s.fast_stop ? "FAST STOP " : "") + (s.gripper_state || "");
    if (now !== lastState) { lastState = now; if (now) announce("Gripper " + now.trim()); }
  }

  // -- communication log -------------------------------------------------------------------------
  const body = $("log-body");
  function time(t) {
    const d = new Date(t * 1000);
    return d.toTimeString().slice(0, 8) + "." + String(Math.floor((t * 1000) % 1000)).padStart(3, "0");
  }
  function addRow(e) {
    const tr = document.createElement("tr");
    tr.className = e.direction + (e.status && e.status !== "E_SUCCESS" && e.status !== "E_CMD_PENDING" ? " bad" : "");
    tr.tabIndex = 0;
    tr.dataset.hex = e.hex;
    tr.dataset.dir = e.direction;
    if (AUTO_UPDATE.has(e.id)) tr.dataset.auto = "1";
    const cells = [time(e.time), e.direction.toUpperCase(), e.id === null ? "--" : e.id.toString(16).toUpperCase().padStart(2, "0") + "h",
      e.command, e.hex, e.text + (e.meaning && e.status !== "E_SUCCESS" ? " – " + e.meaning : "")];
    cells.forEach(function (c, i) {
      const td = document.createElement("td");
      td.textContent = c;
      if (i === 4) td.className = "hex";
      tr.appendChild(td);
    });
    body.appendChild(tr);
  }
  function addRows(rows) {
    const wrap = body.closest(".log-wrap");
    const atEnd = wrap.scrollTop + wrap.clientHeight >= wrap.scrollHeight - 4;
    rows.forEach(addRow);
    while (body.rows.length > MAX_ROWS) body.deleteRow(0);
    if (atEnd) wrap.scrollTop = wrap.scrollHeight;
  }
  $("log-updates").addEventListener("change", function () {
    body.classList.toggle("hide-auto", !this.checked);
  });
  $("log-clear").addEventListener("click", async function () {
    body.textContent = "";
    await api("POST", "/api/log/clear");
  });

  // -- byte converter --------------------------------------------------------------------------
  function bytesOf(text) {
    const pairs = (text.match(/[0-9a-fA-F]{2}/g) || []).slice(0, 4096);
    return new Uint8Array(pairs.map(function (h) { return parseInt(h, 16); }));
  }
  function convert() {
    const b = bytesOf($("conv-bytes").value);
    const v = new DataView(b.buffer);
    const need = function (n) { return "needs " + n + " byte" + (n > 1 ? "s" : ""); };
    $("cv-8").textContent = b.length >= 1 ? v.getUint8(0) + " / " + v.getInt8(0) : need(1);
    $("cv-16").textContent = b.length >= 2 ? v.getUint16(0, true) + " / " + v.getInt16(0, true) : need(2);
    $("cv-32").textContent = b.length >= 4 ? v.getUint32(0, true) + " / " + v.getInt32(0, true) : need(4);
    $("cv-f").textContent = b.length >= 4 ? String(Number(v.getFloat32(0, true).toPrecision(7))) : need(4);
    let t = "";
    for (const x of b) t += x >= 32 && x < 127 ? String.fromCharCode(x) : "\\x" + x.toString(16).padStart(2, "0");
    $("cv-t").textContent = b.length ? '"' + t + '"' : "–";
  }
  $("conv-bytes").addEventListener("input", convert);
  function showBytes(hex) { $("conv-bytes").value = hex; convert(); }
  document.addEventListener("selectionchange", function () {
    const sel = document.getSelection();
    if (!sel || sel.isCollapsed || !sel.anchorNode) return;
    const el = sel.anchorNode.nodeType === 1 ? sel.anchorNode : sel.anchorNode.parentElement;
    if (!el || !el.closest || !el.closest("#log-body")) return;
    const hex = (sel.toString().match(/\b[0-9A-Fa-f]{2}\b/g) || []).join(" ");
    if (hex) showBytes(hex.toUpperCase());
  });
  body.addEventListener("keydown", function (ev) {
    const tr = ev.target.closest("tr");
    if (ev.key !== "Enter" || !tr) return;
    const all = tr.dataset.hex.split(" ");
    // the parameters: after the 6-byte header (and a reply's 2-byte status), before the CRC
    const start = tr.dataset.dir === "rx" ? 8 : 6;
    showBytes(all.slice(start, all.length - 2).join(" "));
    $("conv-bytes").focus();
  });
  convert();

  // -- live updates ------------------------------------------------------------------------------
  let logSeq = null, resultSeq = null, socket = null, retry = 250;
  const byCommand = {};  // command name -> the output showing its last result
  const latest = {};  // command name -> its newest result seen on the WebSocket
  function live() {
    const q = [];
    if (logSeq !== null) q.push("log=" + logSeq);
    if (resultSeq !== null) q.push("results=" + resultSeq);
    socket = new WebSocket((location.protocol === "https:" ? "wss://" : "ws://") + location.host + "/ws" + (q.length ? "?" + q.join("&") : ""));
    socket.onopen = function () { retry = 250; document.body.classList.remove("stale"); };
    socket.onmessage = function (ev) {
      const m = JSON.parse(ev.data);
      if (m.connection) showConnection(m.connection);
      if (m.state) showState(m.state);
      if (m.log) { addRows(m.log); logSeq = m.log[m.log.length - 1].seq; }
      for (const r of m.results || []) {
        resultSeq = r.seq;
        latest[r.command] = r;
        setResult(byCommand[r.command], r);
        if (r.final && r.status !== "E_SUCCESS") announce(r.command + ": " + r.status);
      }
    };
    socket.onclose = function () {
      document.body.classList.add("stale");
      $("c-dot").className = "dot off";
      $("c-conn").textContent = "the Commander is not reachable (is wsg commander still running?)";
      banner("No connection to the Commander: values are stale; reconnecting…", "bad");
      setTimeout(live, retry);
      retry = Math.min(retry * 2, 4000);
    };
  }

  // -- Stop, FAST STOP, Ack ----------------------------------------------------------------------
  async function command(key, values, out) {
    const r = await api("POST", "/api/command/" + key, values || {});
    if (!r.ok) { failure(out, r); return r; }
    byCommand[r.data.command] = out;
    const seen = latest[r.data.command];  // a final result may have come over the WebSocket first
    setResult(out, seen && seen.seq > r.data.seq ? seen : r.data);
    return r;
  }
  $("c-stop").addEventListener("click", function () { command("stop", {}, $("c-stop-result")); });
  $("c-fast-stop").addEventListener("click", function () { command("fast_stop", {}, $("c-stop-result")); });
  $("c-ack").addEventListener("click", function () { command("ack", {}, $("c-stop-result")); });
  document.addEventListener("keydown", function (ev) {
    if (ev.key !== "Escape") return;
    if ($("connect-dialog").open) return;  // Escape closes the dialog first
    ev.preventDefault();
    command("stop", {}, $("c-stop-result"));
  });

  // -- predefined commands -----------------------------------------------------------------------
  const commands = JSON.parse($("commands-data").dataset.commands);
  const select = $("cmd-select");
  const groups = {};
  for (const c of commands) {
    if (!groups[c.group]) {
      groups[c.group] = document.createElement("optgroup");
      groups[c.group].label = c.group;
      select.appendChild(groups[c.group]);
    }
    const o = document.createElement("option");
    o.value = c.key;
    o.textContent = c.hex + " " + c.title;
    groups[c.group].appendChild(o);
  }
  function paramsFor(key) {
    const c = commands.find(function (x) { return x.key === key; });
    const box = $("cmd-params");
    box.textContent = "";
    for (const p of c.params) {
      const label = document.createElement("label");
      const id = "p-" + p.name;
      let input;
      if (p.kind === "choice") {
        input = document.createElement("select");
        for (const ch of p.choices) { const o = document.createElement("option"); o.value = ch; o.textContent = ch; input.appendChild(o); }
        input.value = p.default;
      } else {
        input = document.createElement("input");
        input.type = p.kind === "bool" ? "checkbox" : p.kind === "number" ? "number" : "text";
        if (p.kind === "number") { input.step = "any"; input.inputMode = "decimal"; }
        if (p.kind === "bool") input.checked = !!p.default; else input.value = p.default === null ? "" : p.default;
      }
      input.id = id; input.name = p.name;
      const err = document.createElement("span");
      err.className = "field-error"; err.id = id + "-error";
      input.setAttribute("aria-describedby", err.id);
      if (p.kind === "bool") { label.className = "check"; label.appendChild(input); label.append(" " + p.label); }
      else { label.append(p.label + (p.unit ? " (" + p.unit + ")" : "") + (p.optional ? ", optional" : "") + " "); label.appendChild(input); }
      label.appendChild(err);
      box.appendChild(label);
    }
  }
  select.addEventListener("change", function () { paramsFor(select.value); $("cmd-result").textContent = ""; });
  paramsFor(select.value);
  $("cmd-form").addEventListener("submit", async function (ev) {
    ev.preventDefault();
    const values = {};
    for (const el of $("cmd-params").querySelectorAll("input, select")) {
      values[el.name] = el.type === "checkbox" ? el.checked : el.value;
      el.classList.remove("invalid"); el.removeAttribute("aria-invalid");
      $(el.id + "-error").textContent = "";
    }
    const out = $("cmd-result");
    out.textContent = "…"; out.className = "result";
    const r = await command(select.value, values, out);
    if (!r.ok && r.data.errors) {
      for (const [name, why] of Object.entries(r.data.errors)) {
        const el = $("p-" + name);
        if (!el) continue;
        el.classList.add("invalid"); el.setAttribute("aria-invalid", "true");
        $(el.id + "-error").textContent = why;
      }
    }
  });

  // -- Custom Command Editor ---------------------------------------------------------------------
  const ids = $("ed-ids");
  for (const c of commands) { const o = document.createElement("option"); o.value = c.hex; o.label = c.title; ids.appendChild(o); }
  let editTimer = null, editSeq = 0;
  function part(text, cls, title) {
    const s = document.createElement("span");
    s.className = "b " + cls; s.textContent = text; s.title = title;
    return s;
  }
  function echo(text, start, end) {
    const e = $("ed-echo");
    e.textContent = "";
    if (start === undefined || start === null) return;
    e.append(text.slice(0, start));
    const m = document.createElement("mark");
    m.textContent = text.slice(start, end) || " ";
    e.appendChild(m);
    e.append(text.slice(end));
  }
  async function decodeNow() {
    const seq = ++editSeq;
    const idText = $("ed-id").value, payload = $("ed-payload").value;
    const r = await request("GET", "/api/editor?id=" + encodeURIComponent(idText) + "&payload=" + encodeURIComponent(payload));
    if (seq !== editSeq) return;  // the user typed on: a newer answer is coming
    const d = r.data, packet = $("ed-packet");
    for (const f of ["ed-id", "ed-payload"]) { $(f).classList.remove("invalid"); $(f).removeAttribute("aria-invalid"); }
    $("ed-error").textContent = ""; $("ed-id-error").textContent = "";
    echo("");
    packet.textContent = "";
    $("ed-send").disabled = !d.ok;
    if (!d.ok) {
      const field = d.field === "id" ? "ed-id" : "ed-payload";
      $(field).classList.add("invalid"); $(field).setAttribute("aria-invalid", "true");
      $(field === "ed-id" ? "ed-id-error" : "ed-error").textContent = d.error || d.detail || "invalid";
      if (field === "ed-payload") echo(payload, d.start, d.end);
      $("ed-decoded").textContent = "";
      return;
    }
    packet.appendChild(part(d.preamble, "pre", "preamble"));
    packet.appendChild(part(d.header.slice(0, 2), "id", "command ID " + d.command));
    packet.appendChild(part(d.header.slice(3), "size", "payload size " + d.size + " bytes"));
    for (const it of d.items) packet.appendChild(part(it.hex, "item", it.text));
    packet.appendChild(part(d.crc, "crc", "CRC (000 §1.2.1)"));
    packet.dataset.wire = d.wire;
    $("ed-decoded").textContent = d.command + (d.decoded ? ": " + d.decoded : "");
  }
  function scheduleDecode() { clearTimeout(editTimer); editTimer = setTimeout(decodeNow, 120); }
  $("ed-id").addEventListener("input", scheduleDecode);
  $("ed-payload").addEventListener("input", scheduleDecode);
  $("editor-form").addEventListener("submit", async function (ev) {
    ev.preventDefault();
    const out = $("ed-result");
    out.textContent = "sending…"; out.className = "result";
    const since = resultSeq || 0;
    const r = await api("POST", "/api/send", { id: $("ed-id").value, payload: $("ed-payload").value });
    if (!r.ok) { failure(out, r); if (r.data.start !== undefined) echo($("ed-payload").value, r.data.start, r.data.end); return; }
    byCommand[r.data.command] = out;
    const seen = latest[r.data.command];  // the reply may have come over the WebSocket before this answer
    if (seen && seen.seq > since) setResult(out, seen);
    else { out.textContent = "sent " + r.data.wire; out.className = "result ok"; }
  });
  decodeNow();

  // -- Connect dialog ----------------------------------------------------------------------------
  const dialog = $("connect-dialog");
  function iface() { return document.querySelector("input[name=iface]:checked").value; }
  function showFields() {
    const k = iface();
    for (const div of dialog.querySelectorAll("[data-if]")) div.hidden = div.dataset.if.split(" ").indexOf(k) < 0;
  }
  function buildUrl() {
    const k = iface();
    let url;
    if (k === "tcp") url = "tcp://" + $("cd-host").value.trim() + ":" + $("cd-port").value;
    else if (k === "udp") url = "udp://" + $("cd-host").value.trim() + ":" + $("cd-port").value + "?reply_port=" + $("cd-reply").value;
    else if (k === "serial") url = "serial://" + $("cd-device").value.trim() + "?baudrate=" + $("cd-baud").value;
    else url = "can://" + $("cd-channel").value.trim() + "?interface=" + encodeURIComponent($("cd-interface").value.trim())
      + ($("cd-bitrate").value !== "0" ? "&bitrate=" + $("cd-bitrate").value : "");
    $("cd-url").value = url;
  }
  function fromUrl(url) {  // fill the fields from a URL given with --url
    const m = /^(tcp|udp|serial|can):\/\/([^?]*)(?:\?(.*))?$/.exec(url || "");
    if (!m) return;
    document.querySelector("input[name=iface][value=" + m[1] + "]").checked = true;
    const q = new URLSearchParams(m[3] || "");
    if (m[1] === "tcp" || m[1] === "udp") {
      const hp = /^(\[[^\]]+\]|[^:]*)(?::(\d+))?$/.exec(m[2]);
      if (hp) { $("cd-host").value = hp[1]; $("cd-port").value = hp[2] || (m[1] === "tcp" ? "1000" : "1500"); }
      if (q.get("reply_port")) $("cd-reply").value = q.get("reply_port");
    } else if (m[1] === "serial") {
      $("cd-device").value = m[2];
      if (q.get("baudrate")) $("cd-baud").value = q.get("baudrate");
    } else {
      $("cd-channel").value = m[2];
      if (q.get("interface")) $("cd-interface").value = q.get("interface");
    }
    showFields();
    $("cd-url").value = url;
  }
  for (const el of dialog.querySelectorAll("input[name=iface]")) el.addEventListener("change", function () { showFields(); buildUrl(); });
  for (const id of ["cd-host", "cd-port", "cd-reply", "cd-device", "cd-baud", "cd-channel", "cd-interface", "cd-bitrate"]) {
    $(id).addEventListener("input", buildUrl);
  }
  $("cd-ports").addEventListener("change", function () { if (this.value) { $("cd-device").value = this.value; buildUrl(); } });
  async function loadPorts() {
    const r = await request("GET", "/api/ports");
    const sel = $("cd-ports");
    while (sel.options.length > 1) sel.remove(1);
    for (const p of (r.data.ports || [])) {
      const o = document.createElement("option");
      o.value = p.device; o.textContent = p.device + (p.description && p.description !== "n/a" ? " – " + p.description : "");
      sel.appendChild(o);
    }
  }
  $("btn-connect").addEventListener("click", function () {
    $("cd-error").textContent = "";
    loadPorts();
    dialog.showModal();
    $("cd-url").focus();
  });
  $("cd-cancel").addEventListener("click", function () { dialog.close(); $("btn-connect").focus(); });
  $("connect-form").addEventListener("submit", async function (ev) {
    ev.preventDefault();
    $("cd-error").textContent = "connecting…";
    const r = await api("POST", "/api/connect", { url: $("cd-url").value });
    if (!r.ok) { $("cd-error").textContent = r.data.detail || "cannot connect"; $("cd-url").focus(); return; }
    $("cd-error").textContent = "";
    showConnection(r.data);
    dialog.close();
    $("c-stop").focus();
  });
  $("btn-disconnect").addEventListener("click", async function () {
    const r = await api("POST", "/api/disconnect");
    if (r.ok) showConnection(r.data);
  });
  const initial = $("cd-url").dataset.initial;
  if (initial) fromUrl(initial); else { showFields(); buildUrl(); }

  live();
})();
