// Control Panel: live width/force plots (last 30 s) and the results of commands sent from here.
"use strict";
(function () {
  const width = new WSGPlot(document.getElementById("plot-width"), { color: "#0a6ebd", min: 0 });
  const force = new WSGPlot(document.getElementById("plot-force"), { color: "#c0392b", min: 0 });
  let dirty = false;
  const FORMS = { HOMING: "form-home", PREPOSITION: "form-move", GRIP_PART: "form-grip", RELEASE_PART: "form-release" };
  WSG.plots = { width, force };
  WSG.listeners.push(function (msg) {
    const s = msg.state;
    width.push(msg.t, s.width);
    force.push(msg.t, s.force);
    document.getElementById("width-now").textContent = WSG.fmt(s.width, 2, "mm");
    document.getElementById("force-now").textContent = WSG.fmt(s.force, 1, "N");
    if (msg.results) {
      const ul = document.getElementById("results");
      for (const r of msg.results) {
        const li = document.createElement("li");
        li.textContent = new Date(r.time * 1000).toLocaleTimeString() + "  " + r.command + "  " + r.status +
          (r.final ? "" : " (pending)");
        li.className = r.status === "E_SUCCESS" || r.status === "E_CMD_PENDING" ? "ok" : "bad";
        ul.insertBefore(li, ul.firstChild);
        // a motion's final reply replaces the E_CMD_PENDING shown beside its form
        const form = r.final && document.getElementById(FORMS[r.command]);
        const out = form && form.querySelector("output.result");
        if (out) {
          out.textContent = r.status;
          out.className = "result " + (r.status === "E_SUCCESS" ? "ok" : "bad");
        }
        while (ul.children.length > 20) ul.removeChild(ul.lastChild);
      }
    }
    dirty = true;
  });
  function frame() {
    if (dirty) { width.draw(); force.draw(); dirty = false; }
    requestAnimationFrame(frame);
  }
  requestAnimationFrame(frame);
})();
