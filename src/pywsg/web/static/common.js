// Shared by every page: CSRF-aware JSON requests, the live WebSocket, the Gripper side box,
// the menus, command forms with errors shown beside their fields. No dependencies, no build step.
"use strict";
(function () {
  const canWrite = document.querySelector('meta[name="can-write"]').content === "true";
  const listeners = [];
  const WSG = {
    csrf: document.querySelector('meta[name="csrf-token"]').content,
    canWrite, listeners, last: null, updates: 0, live: false, lastUpdate: null,
    finals: {},  // command name -> newest final result {seq, status} seen on the WebSocket
  };
  window.WSG = WSG;

  // -- history across page changes: the last 30 s of width/force and the last command results ---------
  // Every page records them from the live updates; sessionStorage carries them to the next page (per
  // tab, per server), so the Control Panel's plots and results list survive a visit to another page.
  const HISTORY_KEY = "pywsg.history";
  const HISTORY_S = 31, HISTORY_RESULTS = 20;
  function loadHistory() {
    try {
      const h = JSON.parse(sessionStorage.getItem(HISTORY_KEY) || "null");
      if (h && Array.isArray(h.points) && Array.isArray(h.results)) return h;
    } catch (e) { /* no storage or a bad entry: start empty */ }
    return { points: [], results: [], seq: null };
  }
  const history = loadHistory();
  WSG.history = history;
  function record(msg) {
    const s = msg.state;
    if (s) {
      history.points.push([msg.t, s.referenced === false ? null : s.width, s.force]);
      const cut = msg.t - HISTORY_S;
      while (history.points.length && history.points[0][0] < cut) history.points.shift();
    }
    for (const r of msg.results || []) {
      history.results.push(r);
      history.seq = r.seq;
    }
    if (history.results.length > HISTORY_RESULTS) history.results.splice(0, history.results.length - HISTORY_RESULTS);
  }
  function saveHistory() {
    try { sessionStorage.setItem(HISTORY_KEY, JSON.stringify(history)); } catch (e) { /* storage full or off */ }
  }
  window.addEventListener("pagehide", saveHistory);
  WSG.saveHistory = saveHistory;

  async function renewToken() {
    // after a restart of the gripper the old session is gone: /api/csrf hands out a new one
    // (its answer sets the new session cookie); on a non-loopback bind that means logging in again
    const resp = await fetch("/api/csrf", { credentials: "same-origin", cache: "no-store" });
    if (!resp.ok) return false;
    const data = await resp.json();
    WSG.csrf = data.token;
    return data.can_write;
  }
  WSG.renewToken = renewToken;

  function request(method, url, body) {
    return window.wsgRequest(method, url, body, WSG.csrf, "the gripper (is the simulator running?)");
  }

  // Every request of the page: a refused CSRF token is renewed once and the request repeated, so
  // Stop works right after a restart of the gripper even before the WebSocket is back.
  WSG.api = async function (method, url, body) {
    let r = await request(method, url, body);
    if (r.status === 403 && /CSRF/.test(r.data.detail || "")) {
      try { await renewToken(); } catch (e) { /* answered below */ }
      r = await request(method, url, body);
      if (r.status === 403 && /CSRF/.test(r.data.detail || "")) {
        r.data.detail = "this page's session has expired: reload the page";
      }
    }
    if (r.status === 401) r.data.detail = "login required: log in again (the gripper may have restarted)";
    return r;
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

  function announce(text) {
    const a = document.getElementById("announce");
    if (a && a.textContent !== text) a.textContent = text;
  }

  // -- live connection -------------------------------------------------------------------------
  function setStale(stale) {
    document.body.classList.toggle("stale", stale);
    const text = document.getElementById("ws-text");
    if (stale) {
      const since = WSG.lastUpdate ? " since " + WSG.lastUpdate.toLocaleTimeString() : "";
      text.textContent = "disconnected" + since + " – values are stale, retrying";
    } else {
      text.textContent = "live";
    }
  }

  WSG.connect = function (params) {
    const proto = location.protocol === "https:" ? "wss:" : "ws:";
    function url() {
      // results newer than the last one this tab saw: none are lost while the next page loads
      const p = Object.assign({}, params || {});
      if (history.seq !== null && history.seq !== undefined) p.results = String(history.seq);
      const query = new URLSearchParams(p).toString();
      return proto + "//" + location.host + "/ws" + (query ? "?" + query : "");
    }
    const dot = document.getElementById("ws-status");
    let ws;
    let wasLive = false;
    async function open() {
      if (wasLive) {
        // reconnecting (the gripper may have restarted): a fresh session and CSRF token first
        try {
          const writable = await renewToken();
          if (canWrite && !writable) banner("The session ended (the gripper restarted?): log in again.", "bad");
        } catch (e) { setTimeout(open, 1000); return; }
      }
      ws = new WebSocket(url());
      ws.onopen = function () {
        wasLive = true; WSG.live = true;
        dot.className = "dot on"; setStale(false);
        const b = document.getElementById("banner");
        if (b && b.dataset.conn) { banner(""); delete b.dataset.conn; }
        // "not sent: no connection" beside a form is no longer true once the gripper is back
        for (const out of document.querySelectorAll("output.result[data-conn]")) {
          out.textContent = ""; out.className = "result"; delete out.dataset.conn;
        }
      };
      ws.onclose = function () {
        WSG.live = false;
        dot.className = "dot off"; setStale(true);
        if (wasLive) {
          banner("No connection to the gripper: the values shown are stale. Commands will fail until it is back.", "bad");
          document.getElementById("banner").dataset.conn = "1";
          announce("Connection to the gripper lost");
        }
        setTimeout(open, 1000);
      };
      ws.onmessage = function (ev) {
        const msg = JSON.parse(ev.data);
        WSG.last = msg;
        WSG.updates += 1;
        WSG.lastUpdate = new Date();
        if (msg.results) {
          for (const r of msg.results) {
            const f = WSG.finals[r.command];
            if (r.final && (!f || r.seq > f.seq)) WSG.finals[r.command] = { seq: r.seq, status: r.status };
          }
        }
        if (msg.state) updateBox(msg.state);
        record(msg);
        for (const fn of listeners) fn(msg);
      };
    }
    open();
  };

  function updateBox(s) {
    const st = document.getElementById("g-state");
    st.textContent = s.state;
    st.className = "state-" + s.state;
    // like the real panel: no position until the fingers are referenced (homing)
    const width = s.referenced === false ? "[n/a]" : WSG.fmt(s.width, 2, "mm");
    document.getElementById("g-width").textContent = width;
    const qs = document.getElementById("q-state");
    if (qs) { qs.textContent = s.state; qs.className = "state-" + s.state; document.getElementById("q-width").textContent = width; }
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
    // screen readers hear state changes and FAST STOP (aria-live region), not every number
    const fast = s.flag_names.indexOf("SF_FAST_STOP") >= 0;
    // 001 §41h: ERROR "remains until the next motion command is received" (after an acknowledge if
    // FAST STOP is active) — say so, or an ERROR with no flag set looks like a fault nobody can clear
    const note = document.getElementById("g-state-note");
    if (note) {
      note.textContent = s.state !== "ERROR" ? "" : fast
        ? "FAST STOP: acknowledge (Ack), then any motion command clears ERROR."
        : "Kept until the next motion command (grip state, 001 §41h).";
      document.getElementById("g-state-note-row").hidden = s.state !== "ERROR";
    }
    announce("Gripper state " + s.state + (fast ? ", FAST STOP active" : ""));
  }

  // -- identity header: model, firmware, serial, hardware revision, device tag (50h/52h) ----------
  WSG.loadIdentity = async function () {
    const r = await WSG.api("GET", "/api/identity");
    if (!r.ok) return;
    const d = r.data;
    const set = function (id, v) { const el = document.getElementById(id); if (el) el.textContent = v === null || v === undefined || v === "" ? "–" : String(v); };
    set("id-tag", d.tag); set("id-serial", d.serial); set("id-fw", d.firmware); set("id-hw", d.hw_revision);
    // 003 §6, figure 1: "Location: n/a, Contact: n/a" under the title
    for (const k of ["location", "contact"]) {
      const el = document.getElementById("id-" + k);
      if (el) el.textContent = d[k] ? String(d[k]) : "n/a";
    }
    const title = document.getElementById("model-title");
    if (title && d.model) title.textContent = d.model + " Control Panel";
  };

  // -- menus (WAI-ARIA disclosure: a button per menu; arrow keys move within it, Escape or leaving
  //    it with Tab closes it; near the right edge it opens leftwards) -------------------------------
  function setupMenus() {
    const buttons = Array.from(document.querySelectorAll("ul.nav button[aria-controls]"));
    const listOf = function (b) { return document.getElementById(b.getAttribute("aria-controls")); };
    const linksOf = function (b) { return Array.from(listOf(b).querySelectorAll("a")); };
    function fit(list) {
      // open leftwards when the menu would run past the window's right edge (a phone)
      list.classList.remove("menu-end");
      const r = list.getBoundingClientRect();
      if (r.width && r.right > document.documentElement.clientWidth) list.classList.add("menu-end");
    }
    function setOpen(b, open) {
      b.setAttribute("aria-expanded", String(open));
      const list = listOf(b);
      list.hidden = !open;
      if (open) fit(list);
    }
    function close(except) {
      for (const b of buttons) if (b !== except && b.getAttribute("aria-expanded") === "true") setOpen(b, false);
    }
    for (const b of buttons) {
      const li = b.parentElement;
      b.addEventListener("click", function () {
        const open = b.getAttribute("aria-expanded") !== "true";
        close(b);
        setOpen(b, open);
      });
      // hover opens a menu without a click: keep it inside the window too
      li.addEventListener("mouseenter", function () { fit(listOf(b)); });
      li.addEventListener("focusout", function (ev) {
        if (!ev.relatedTarget || !li.contains(ev.relatedTarget)) setOpen(b, false);
      });
      li.addEventListener("keydown", function (ev) {
        const links = linksOf(b);
        const i = links.indexOf(document.activeElement);
        let to = null;
        if (ev.key === "ArrowDown") to = i < 0 ? 0 : (i + 1) % links.length;
        else if (ev.key === "ArrowUp") to = i < 0 ? links.length - 1 : (i - 1 + links.length) % links.length;
        else if (ev.key === "Home" && i >= 0) to = 0;
        else if (ev.key === "End" && i >= 0) to = links.length - 1;
        if (to === null || !links.length) return;
        ev.preventDefault();
        if (b.getAttribute("aria-expanded") !== "true") { close(b); setOpen(b, true); }
        links[to].focus();
      });
    }
    document.addEventListener("click", function (ev) {
      if (!ev.target.closest || !ev.target.closest("ul.nav")) close(null);
    });
    return {
      // Escape: close the open menu (focus back on its button); true when there was one
      escape: function () {
        const open = buttons.find(function (b) { return b.getAttribute("aria-expanded") === "true"; });
        if (!open) return false;
        close(null);
        open.focus();
        return true;
      },
    };
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
    for (const el of form.querySelectorAll(".invalid")) { el.classList.remove("invalid"); el.removeAttribute("aria-invalid"); }
    if (!errors) return;
    for (const [name, msg] of Object.entries(errors)) {
      const span = form.querySelector('.field-error[data-for="' + CSS.escape(name) + '"]');
      if (span) {
        span.textContent = msg;
        const input = form.querySelector('[name="' + CSS.escape(name) + '"]');
        if (input) { input.classList.add("invalid"); input.setAttribute("aria-invalid", "true"); }
      }
    }
  };

  function showResult(out, ok, text) {
    out.textContent = text;
    out.className = "result " + (ok ? "ok" : "bad");
  }
  WSG.showResult = showResult;

  async function submit(form, method, endpoint) {
    const out = form.querySelector("output.result");
    const body = method === "DELETE" ? undefined : formBody(form);
    if (out) { out.textContent = "…"; out.className = "result"; delete out.dataset.seq; }
    const r = await WSG.api(method, endpoint, body);
    WSG.showErrors(form, r.data && r.data.errors);
    if (out) {
      const d = r.data || {};
      const final = d.seq !== undefined && d.seq !== null && WSG.finals[d.command];
      if (r.status === 202 && final && final.seq > d.seq) {
        // the WebSocket brought the final result before this reply: show it, not E_CMD_PENDING
        showResult(out, final.status === "E_SUCCESS", final.status);
      } else if (r.ok) {
        showResult(out, true, d.status || d.action || "OK");
        if (r.status === 202) out.dataset.seq = d.seq;
      } else {
        showResult(out, false, (d.status || (r.status ? "error " + r.status : "failed")) + ": " + (d.detail || ""));
        if (r.status === 0) out.dataset.conn = "1";  // cleared when the live connection is back
      }
    }
    form.dispatchEvent(new CustomEvent("wsg:done", { detail: r }));  // pages refresh what it changed
    return r;
  }
  WSG.submit = submit;

  async function stopOrAck(path, what) {
    const r = await WSG.api("POST", path);
    banner(r.ok ? "" : what + " failed: " + (r.data.detail || r.status), r.ok ? "" : "bad");
    if (r.ok) announce(what + " sent");
  }

  // a table wider than a phone scrolls sideways: keyboard users must be able to focus it to scroll
  function markScrollable() {
    for (const t of document.querySelectorAll("main table")) {
      if (t.scrollWidth > t.clientWidth + 1) t.tabIndex = 0; else t.removeAttribute("tabindex");
    }
  }
  WSG.markScrollable = markScrollable;
  let markPending = false;
  function markSoon() {
    // tables filled later (the Fieldbus Monitor's registers) are checked when they change
    if (markPending) return;
    markPending = true;
    requestAnimationFrame(function () { markPending = false; markScrollable(); });
  }

  // the quick Stop bar: shown while the Gripper box's Stop button is scrolled out of sight (a phone)
  function setupQuickbar() {
    const bar = document.getElementById("quickbar");
    const stop = document.getElementById("btn-stop");
    if (!bar || !stop || !window.IntersectionObserver) return;
    new IntersectionObserver(function (entries) {
      for (const e of entries) bar.hidden = e.isIntersecting;
    }).observe(stop);
  }

  document.addEventListener("DOMContentLoaded", function () {
    const menus = setupMenus();
    markScrollable();
    window.addEventListener("resize", markScrollable);
    const main = document.querySelector("main");
    if (main && window.MutationObserver) new MutationObserver(markSoon).observe(main, { childList: true, subtree: true });
    setupQuickbar();
    for (const form of document.querySelectorAll("form.cmd")) {
      form.noValidate = true;  // one error style: the server's reason beside the field, not a browser bubble
      form.addEventListener("submit", function (ev) {
        ev.preventDefault();
        submit(form, "POST", form.dataset.endpoint);
      });
      for (const btn of form.querySelectorAll("button.delete")) {
        btn.addEventListener("click", function () { submit(form, "DELETE", btn.dataset.endpoint); });
      }
    }
    const stop = document.getElementById("btn-stop");
    stop.addEventListener("click", function () { stopOrAck("/api/stop", "Stop"); });
    const quickStop = document.getElementById("btn-stop-quick");
    if (quickStop) quickStop.addEventListener("click", function () { stopOrAck("/api/stop", "Stop"); });
    // Escape stops the fingers from anywhere on the page (first it closes an open menu)
    document.addEventListener("keydown", function (ev) {
      if (ev.key !== "Escape" || ev.defaultPrevented || menus.escape()) return;
      if (canWrite) stopOrAck("/api/stop", "Stop");
    });
    document.getElementById("btn-ack").addEventListener("click", function () { stopOrAck("/api/ack", "Ack"); });
    const skip = document.getElementById("skip-stop");
    if (skip) skip.addEventListener("click", function (ev) { ev.preventDefault(); stop.focus(); });
    if (!canWrite) {
      for (const b of document.querySelectorAll("main button, #gripper-box button")) b.disabled = true;
      banner("Read-only: log in to move the fingers or change settings.", "info");
    }
    if (!document.body.dataset.noLive) WSG.connect(WSG.liveParams || {});
    WSG.loadIdentity();
    // the tag can change from any client (51h): refresh while the connection is live
    setInterval(function () { if (WSG.live) WSG.loadIdentity(); }, 5000);
  });
})();
