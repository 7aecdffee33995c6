// Control Panel: live width/force plots (last 30 s) and the results of commands sent from here.
"use strict";
(function () {
  const width = new WSGPlot(document.getElementById("plot-width"), { color: "#0a6ebd", min: 0, label: "Width", unit: "mm", digits: 2 });
  const force = new WSGPlot(document.getElementById("plot-force"), { color: "#c0392b", min: 0, label: "Force", unit: "N" });
  let dirty = false;
  const FORMS = { HOMING: "form-home", PREPOSITION: "form-move", GRIP_PART: "form-grip", RELEASE_PART: "form-release" };
  WSG.plots = { width, force };
  const ul = document.getElementById("results");
  function showResult(r) {
    const li = document.createElement("li");
    li.textContent = new Date(r.time * 1000).toLocaleTimeString() + "  " + r.command + "  " + r.status +
      (r.final ? "" : " (pending)");
    li.className = r.status === "E_SUCCESS" || r.status === "E_CMD_PENDING" ? "ok" : "bad";
    ul.insertBefore(li, ul.firstChild);
    while (ul.children.length > 20) ul.removeChild(ul.lastChild);
  }
  // what this tab saw on the pages before (common.js keeps it across page changes)
  for (const p of WSG.history.points) { width.push(p[0], p[1]); force.push(p[0], p[2]); }
  for (const r of WSG.history.results) showResult(r);
  WSG.listeners.push(function (msg) {
    const s = msg.state;
    // no position before homing: the plot shows a gap, not 0.00 mm (the side box says [n/a])
    width.push(msg.t, s.referenced === false ? null : s.width);
    force.push(msg.t, s.force);
    document.getElementById("width-now").textContent = s.referenced === false ? "[n/a]" : WSG.fmt(s.width, 2, "mm");
    document.getElementById("force-now").textContent = WSG.fmt(s.force, 1, "N");
    if (msg.results) {
      for (const r of msg.results) {
        showResult(r);
        // a motion's final reply replaces the E_CMD_PENDING shown beside its form
        // (only a final result newer than the form's own pending reply: not an older motion's)
        const form = r.final && document.getElementById(FORMS[r.command]);
        const out = form && form.querySelector("output.result");
        if (out && out.dataset.seq !== undefined && r.seq > Number(out.dataset.seq)) {
          WSG.showResult(out, r.status === "E_SUCCESS", r.status);
          delete out.dataset.seq;
        }
      }
    }
    dirty = true;
  });
  function frame() {
    if (dirty) { width.draw(); force.draw(); dirty = false; }
    requestAnimationFrame(frame);
  }
  requestAnimationFrame(frame);

  // allowed ranges beside the inputs before a submit (53h system limits)
  WSG.api("GET", "/api/info").then(function (r) {
    // the ranges the server checks (one source: /api/info "ranges"), so hint and refusal agree
    const ranges = r.ok && r.data.ranges;
    if (!ranges) return;
    for (const input of document.querySelectorAll("main form.cmd input[type=number]")) {
      const rg = ranges[input.name];
      if (!rg || rg[0] === undefined || rg[1] === undefined) continue;
      input.min = rg[0]; input.max = rg[1];
      const hint = document.createElement("span");
      hint.className = "range";
      hint.id = input.closest("form").id + "-" + input.name + "-range";
      hint.textContent = "allowed " + rg[0] + " … " + rg[1] + " " + rg[2];
      input.setAttribute("aria-describedby", hint.id);
      input.closest("label").appendChild(hint);
    }
  });
})();
