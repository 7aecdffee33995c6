// A small time-series plot on <canvas>: the last `span` seconds, auto-scaled with round ticks,
// no dependencies. A null value is a gap (e.g. no position before homing). The canvas carries a
// text alternative (aria-label) with the current value and the range shown.
"use strict";
(function () {
  function Plot(canvas, opts) {
    this.canvas = canvas;
    this.ctx = canvas.getContext("2d");
    this.span = (opts && opts.span) || 30;
    this.color = (opts && opts.color) || "#0a6ebd";
    this.unit = (opts && opts.unit) || "";
    this.label = (opts && opts.label) || "value";
    this.digits = (opts && opts.digits !== undefined) ? opts.digits : 1;
    this.min = (opts && opts.min !== undefined) ? opts.min : null;
    this.points = [];  // [t seconds, value or null]
    canvas.setAttribute("role", "img");
  }
  Plot.prototype.push = function (t, v) {
    if (v === undefined) return;
    this.points.push([t, v]);
    const cut = t - this.span - 1;
    while (this.points.length && this.points[0][0] < cut) this.points.shift();
  };
  function niceStep(range) {
    // 1, 2 or 5 times a power of ten, about a quarter of the range
    const raw = range / 4, mag = Math.pow(10, Math.floor(Math.log10(raw)));
    const f = raw / mag;
    return (f <= 1 ? 1 : f <= 2 ? 2 : f <= 5 ? 5 : 10) * mag;
  }
  Plot.prototype.draw = function () {
    const c = this.ctx, w = this.canvas.width, h = this.canvas.height;
    const left = 44, right = 8, top = 8, bottom = 20;
    c.clearRect(0, 0, w, h);
    c.fillStyle = "#fff"; c.fillRect(0, 0, w, h);
    const pts = this.points;
    const now = pts.length ? pts[pts.length - 1][0] : 0;
    let lo = Infinity, hi = -Infinity;
    for (const p of pts) { if (p[1] !== null) { lo = Math.min(lo, p[1]); hi = Math.max(hi, p[1]); } }
    const seen = isFinite(lo);
    const vmin = lo, vmax = hi;
    if (!seen) { lo = 0; hi = 1; }
    if (this.min !== null) lo = Math.min(lo, this.min);
    if (hi - lo < 1) { hi = lo + 1; }
    const step = niceStep(hi - lo);
    lo = Math.floor(lo / step) * step; hi = Math.ceil(hi / step) * step;
    if (this.min !== null) lo = Math.max(lo, this.min);  // no negative widths or forces on the axis
    const x = function (t) { return left + (w - left - right) * (1 - (now - t) / this.span); }.bind(this);
    const y = function (v) { return top + (h - top - bottom) * (1 - (v - lo) / (hi - lo)); };
    c.strokeStyle = "#ddd"; c.fillStyle = "#374151"; c.font = "11px sans-serif"; c.lineWidth = 1;
    const digits = step < 1 ? 1 : 0;
    this.ticks = [];  // the value axis' labels (read by the tests)
    for (let v = lo; v <= hi + step / 2; v += step) {
      this.ticks.push(Number(v.toFixed(digits)));
      const yy = y(v);
      c.beginPath(); c.moveTo(left, yy); c.lineTo(w - right, yy); c.stroke();
      c.fillText(v.toFixed(digits), 2, yy + 4);
    }
    for (let s = 0; s <= this.span; s += 5) {
      const xx = x(now - s);
      c.beginPath(); c.moveTo(xx, top); c.lineTo(xx, h - bottom); c.stroke();
      c.fillText(s === 0 ? "now" : "-" + s + " s", xx - 12, h - 5);
    }
    const last = pts.length ? pts[pts.length - 1][1] : null;
    this.canvas.setAttribute("aria-label", this.label + " over the last " + this.span + " s: " +
      (last === null ? "no value" : "now " + last.toFixed(this.digits) + " " + this.unit) +
      (seen ? ", between " + vmin.toFixed(this.digits) + " and " + vmax.toFixed(this.digits) + " " + this.unit : ""));
    if (!seen) return;
    c.strokeStyle = this.color; c.lineWidth = 2; c.beginPath();
    let pen = false;
    for (const p of pts) {
      if (p[1] === null) { pen = false; continue; }
      if (pen) c.lineTo(x(p[0]), y(p[1])); else c.moveTo(x(p[0]), y(p[1]));
      pen = true;
    }
    c.stroke();
  };
  window.WSGPlot = Plot;
})();
