// Shared by every page: CSRF-aware JSON requests, the live WebSocket, the Gripper side box,
// command forms with errors shown beside their fields. No dependencies, no build step.
"use strict";
(function () {
  const csrf = document.querySelector('meta[name="csrf-token"]').content;
  const canWrite = document.querySelector('meta[name="can-write"]').content === "true";
  const listeners = [];
  const WSG = { csrf, canWrite, listeners, last: null, updates: 0 };
  window.WSG = WSG;

  WSG.api = async function (method, url, body) {
    const opts = { method, headers: { "X-CSRF-Token": csrf }, credentials: "same-origin" };
    if (body !== undefined) {
      opts.headers["Content-Type"] = "application/json";
      opts.body = JSON.stringify(body);
    }
    const resp = await fetch(url, opts);
    let data = null;
    try { data = await resp.json(); } catch (e) { data = { detail: resp.statusText }; }
    return { status: resp.status, ok: resp.ok, data };
  };

  WSG.fmt = function (v, digits, unit) {
    if (v === null || v === undefined || Number.isNaN(v)) return "n/a";
    return Number(v).toFixed(digits) + (unit ? " " + unit : "");
  };

  function banner(text, kind) {
    const b = document.getElementById("banner");
    if (!b) return;
    b.textContent = text;
    b.className = "banner " + (kind || "");
    b.hidden = !text;
  }
  WSG.banner = banner;

  // -- live connection -------------------------------------------------------------------------
  WSG.connect = function (params) {
    const proto = location.protocol === "https:" ? "wss:" : "ws:";
    const query = new URLSearchParams(params || {}).toString();
    const url = proto + "//" + location.host + "/ws" + (query ? "?" + query : "");
    const dot = document.getElementById("ws-status");
    const text = document.getElementById("ws-text");
    let ws;
    function open() {
      ws = new WebSocket(url);
      ws.onopen = function () { dot.className = "dot on"; text.textContent = "live"; };
      ws.onclose = function () {
        dot.className = "dot off"; text.textContent = "disconnected – retrying";
        setTimeout(open, 1000);
      };
      ws.onmessage = function (ev) {
        const msg = JSON.parse(ev.data);
        WSG.last = msg;
        WSG.updates += 1;
        if (msg.state) updateBox(msg.state);
        for (const fn of listeners) fn(msg);
      };
    }
    open();
  };

  function updateBox(s) {
    document.getElementById("g-state").textContent = s.state;
    document.getElementById("g-state").className = "state-" + s.state;
    // like the real panel: no position until the fingers are referenced (homing)
    document.getElementById("g-width").textContent = s.referenced === false ? "[n/a]" : WSG.fmt(s.width, 2, "mm");
    document.getElementById("g-speed").textContent = WSG.fmt(s.speed, 1, "mm/s");
    document.getElementById("g-force").textContent = WSG.fmt(s.force, 1, "N");
    document.getElementById("g-temp").textContent = WSG.fmt(s.temperature, 1, "°C");
    const list = document.getElementById("flag-list");
    if (list.children.length !== s.flag_list.length) {
      list.textContent = "";
      for (const f of s.flag_list) {
        const li = document.createElement("li");
        li.dataset.flag = f.name;
        li.textContent = f.label;
        list.appendChild(li);
      }
    }
    s.flag_list.forEach(function (f, i) {
      const li = list.children[i];
      li.className = f.on ? "on" : "";
    });
    document.body.dataset.state = s.state;
  }

  // -- forms -----------------------------------------------------------------------------------
  function formBody(form) {
    const body = {};
    for (const el of form.querySelectorAll("input[name], select[name]")) {
      const raw = el.type === "checkbox" ? el.checked : el.value;
      if (el.type === "checkbox") { body[el.name] = raw; continue; }
      if (raw === "") continue;  // optional field left empty
      if (el.type === "number") body[el.name] = Number(raw);
      else if (el.dataset.type === "int") body[el.name] = parseInt(raw, 10);
      else if (el.dataset.type === "bool") body[el.name] = raw === "true";
      else body[el.name] = raw;
    }
    return body;
  }

  WSG.showErrors = function (form, errors) {
    for (const span of form.querySelectorAll(".field-error")) span.textContent = "";
    for (const el of form.querySelectorAll(".invalid")) el.classList.remove("invalid");
    if (!errors) return;
    for (const [name, msg] of Object.entries(errors)) {
      const span = form.querySelector('.field-error[data-for="' + CSS.escape(name) + '"]');
      if (span) {
        span.textContent = msg;
        const input = form.querySelector('[name="' + CSS.escape(name) + '"]');
        if (input) input.classList.add("invalid");
      }
    }
  };

  async function submit(form, method, endpoint) {
    const out = form.querySelector("output.result");
    const body = method === "DELETE" ? undefined : formBody(form);
    if (out) { out.textContent = "…"; out.className = "result"; }
    const r = await WSG.api(method, endpoint, body);
    WSG.showErrors(form, r.data && r.data.errors);
    if (out) {
      const d = r.data || {};
      out.textContent = r.ok ? (d.status || d.action || "OK") : (d.status || ("error " + r.status)) + ": " + (d.detail || "");
      out.className = "result " + (r.ok ? "ok" : "bad");
    }
    return r;
  }
  WSG.submit = submit;

  document.addEventListener("DOMContentLoaded", function () {
    for (const form of document.querySelectorAll("form.cmd")) {
      form.addEventListener("submit", function (ev) {
        ev.preventDefault();
        submit(form, "POST", form.dataset.endpoint);
      });
      for (const btn of form.querySelectorAll("button.delete")) {
        btn.addEventListener("click", function () { submit(form, "DELETE", btn.dataset.endpoint); });
      }
    }
    const stop = document.getElementById("btn-stop");
    const ack = document.getElementById("btn-ack");
    stop.addEventListener("click", async function () {
      const r = await WSG.api("POST", "/api/stop");
      banner(r.ok ? "" : "Stop: " + (r.data.detail || r.status), r.ok ? "" : "bad");
    });
    ack.addEventListener("click", async function () {
      const r = await WSG.api("POST", "/api/ack");
      banner(r.ok ? "" : "Ack: " + (r.data.detail || r.status), r.ok ? "" : "bad");
    });
    if (!canWrite) {
      for (const b of document.querySelectorAll("main button, #gripper-box button")) b.disabled = true;
      banner("Read-only: log in to move the fingers or change settings.", "info");
    }
    if (!document.body.dataset.noLive) WSG.connect(WSG.liveParams || {});
  });
})();
