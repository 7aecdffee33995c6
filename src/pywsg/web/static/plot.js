// A small time-series plot on <canvas>: the last `span` seconds, auto-scaled, no dependencies.
"use strict";
(function () {
  function Plot(canvas, opts) {
    this.canvas = canvas;
    this.ctx = canvas.getContext("2d");
    this.span = (opts && opts.span) || 30;
    this.color = (opts && opts.color) || "#0a6ebd";
    this.unit = (opts && opts.unit) || "";
    this.min = (opts && opts.min !== undefined) ? opts.min : null;
    this.points = [];  // [t seconds, value]
  }
  Plot.prototype.push = function (t, v) {
    if (v === null || v === undefined) return;
    this.points.push([t, v]);
    const cut = t - this.span - 1;
    while (this.points.length && this.points[0][0] < cut) this.points.shift();
  };
  Plot.prototype.draw = function () {
    const c = this.ctx, w = this.canvas.width, h = this.canvas.height;
    const left = 44, right = 8, top = 8, bottom = 20;
    c.clearRect(0, 0, w, h);
    c.fillStyle = "#fff"; c.fillRect(0, 0, w, h);
    const pts = this.points;
    const now = pts.length ? pts[pts.length - 1][0] : 0;
    let lo = Infinity, hi = -Infinity;
    for (const p of pts) { lo = Math.min(lo, p[1]); hi = Math.max(hi, p[1]); }
    if (this.min !== null) lo = Math.min(lo, this.min);
    if (!isFinite(lo)) { lo = 0; hi = 1; }
    if (hi - lo < 1) { hi = lo + 1; }
    const pad = (hi - lo) * 0.08; lo -= pad; hi += pad;
    const x = function (t) { return left + (w - left - right) * (1 - (now - t) / this.span); }.bind(this);
    const y = function (v) { return top + (h - top - bottom) * (1 - (v - lo) / (hi - lo)); };
    c.strokeStyle = "#ddd"; c.fillStyle = "#666"; c.font = "11px sans-serif"; c.lineWidth = 1;
    for (let i = 0; i <= 4; i++) {
      const v = lo + (hi - lo) * i / 4, yy = y(v);
      c.beginPath(); c.moveTo(left, yy); c.lineTo(w - right, yy); c.stroke();
      c.fillText(v.toFixed(1), 2, yy + 4);
    }
    for (let s = 0; s <= this.span; s += 5) {
      const xx = x(now - s);
      c.beginPath(); c.moveTo(xx, top); c.lineTo(xx, h - bottom); c.stroke();
      c.fillText(s === 0 ? "now" : "-" + s + " s", xx - 12, h - 5);
    }
    if (!pts.length) return;
    c.strokeStyle = this.color; c.lineWidth = 2; c.beginPath();
    pts.forEach(function (p, i) { if (i) c.lineTo(x(p[0]), y(p[1])); else c.moveTo(x(p[0]), y(p[1])); });
    c.stroke();
  };
  window.WSGPlot = Plot;
})();
