// One JSON request with a timeout and a readable failure, for the web interface (common.js) and the
// Commander (commander.js). No dependencies, no build step.
"use strict";
(function () {
  const TIMEOUT_MS = 8000;  // a request that gets no answer in this time fails with a message

  // {status, ok, data}: status 0 when nothing came back; ``server`` names what did not answer.
  window.wsgRequest = async function (method, url, body, csrf, server) {
    const opts = { method, headers: { "X-CSRF-Token": csrf }, credentials: "same-origin" };
    if (body !== undefined) {
      opts.headers["Content-Type"] = "application/json";
      opts.body = JSON.stringify(body);
    }
    const abort = new AbortController();
    const timer = setTimeout(function () { abort.abort(); }, TIMEOUT_MS);
    opts.signal = abort.signal;
    try {
      const resp = await fetch(url, opts);
      let data = null;
      try { data = await resp.json(); } catch (e) { data = { detail: resp.statusText }; }
      return { status: resp.status, ok: resp.ok, data: data || {} };
    } catch (e) {
      const why = e && e.name === "AbortError" ? "no answer within " + TIMEOUT_MS / 1000 + " s" : "no connection";
      return { status: 0, ok: false, data: { detail: "not sent: " + why + " to " + server } };
    } finally {
      clearTimeout(timer);
    }
  };
})();
