// A small time-series plot on <canvas>: the last `span` seconds, auto-scaled with round ticks,
// no dependencies. A null value is a gap (e.g. no position before homing). The canvas carries a
// text alternative (aria-label) with the current value and the range shown.
// The canvas takes the size CSS gives it (the width of its panel) and draws at the screen's pixel
// density (devicePixelRatio), so lines and labels are sharp on a 3x phone and fill a wide panel.
"use strict";
(function () {
  const FONT_PX = 12;  // CSS pixels: legible on a phone (the canvas is never scaled down)

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
    this.cssWidth = canvas.width; this.cssHeight = canvas.height; this.dpr = 1;
    canvas.setAttribute("role", "img");
    const self = this;
    if (window.ResizeObserver) {
      new ResizeObserver(function () { if (self.fit()) self.draw(); }).observe(canvas);
    }
    this.fit();
  }
  // match the backing store to the canvas' CSS size times the pixel density; true when it changed
  Plot.prototype.fit = function () {
    const rect = this.canvas.getBoundingClientRect();
    if (!rect.width || !rect.height) return false;
    const dpr = window.devicePixelRatio || 1;
    const w = Math.round(rect.width * dpr), h = Math.round(rect.height * dpr);
    if (w === this.canvas.width && h === this.canvas.height && dpr === this.dpr) return false;
    this.canvas.width = w; this.canvas.height = h;
    this.cssWidth = rect.width; this.cssHeight = rect.height; this.dpr = dpr;
    return true;
  };
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
    this.fit();
    const c = this.ctx, w = this.cssWidth, h = this.cssHeight;
    c.setTransform(this.dpr, 0, 0, this.dpr, 0, 0);  // draw in CSS pixels
    c.font = FONT_PX + "px sans-serif";
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
    const digits = step < 1 ? 1 : 0;
    let widest = 0;
    for (let v = lo; v <= hi + step / 2; v += step) widest = Math.max(widest, c.measureText(v.toFixed(digits)).width);
    const left = Math.ceil(widest) + 8, right = 8, top = 8, bottom = FONT_PX + 10;
    c.clearRect(0, 0, w, h);
    c.fillStyle = "#fff"; c.fillRect(0, 0, w, h);
    const x = function (t) { return left + (w - left - right) * (1 - (now - t) / this.span); }.bind(this);
    const y = function (v) { return top + (h - top - bottom) * (1 - (v - lo) / (hi - lo)); };
    c.strokeStyle = "#ddd"; c.fillStyle = "#374151"; c.lineWidth = 1;
    this.ticks = [];  // the value axis' labels (read by the tests)
    this.labels = [];  // every label drawn: {text, x0, x1} in CSS pixels (read by the tests)
    const label = function (text, xx, yy, align) {
      const tw = c.measureText(text).width;
      const x0 = align === "right" ? xx - tw : align === "center" ? xx - tw / 2 : xx;
      c.textAlign = "left";
      c.fillText(text, x0, yy);
      this.labels.push({ text: text, x0: x0, x1: x0 + tw });
    }.bind(this);
    c.textBaseline = "middle";
    for (let v = lo; v <= hi + step / 2; v += step) {
      this.ticks.push(Number(v.toFixed(digits)));
      const yy = y(v);
      c.beginPath(); c.moveTo(left, yy); c.lineTo(w - right, yy); c.stroke();
      label(v.toFixed(digits), left - 4, Math.min(Math.max(yy, top + FONT_PX / 2), h - bottom), "right");
    }
    c.textBaseline = "alphabetic";
    // time labels every 5 s, fewer when the plot is narrow (a label needs about 44 px)
    const every = (w - left - right) / (this.span / 5) < 44 ? 10 : 5;
    for (let s = 0; s <= this.span; s += 5) {
      const xx = x(now - s);
      c.beginPath(); c.moveTo(xx, top); c.lineTo(xx, h - bottom); c.stroke();
      if (s % every) continue;
      // "now" ends at the right edge, the oldest label starts at the axis: nothing is cut off
      label(s === 0 ? "now" : "-" + s + " s", xx, h - 6, s === 0 ? "right" : s === this.span ? "left" : "center");
    }
    const last = pts.length ? pts[pts.length - 1][1] : null;
    this.canvas.setAttribute("aria-label", this.label + " over the last " + this.span + " s: " +
      (last === null ? "no value" : "now " + last.toFixed(this.digits) + " " + this.unit) +
      (seen ? ", between " + vmin.toFixed(this.digits) + " and " + vmax.toFixed(this.digits) + " " + this.unit : ""));
    if (!seen) return;
    c.save();
    c.beginPath(); c.rect(left, 0, w - left - right, h); c.clip();  // points older than the span stay off the axis
    c.strokeStyle = this.color; c.lineWidth = 2; c.beginPath();
    let pen = false;
    for (const p of pts) {
      if (p[1] === null) { pen = false; continue; }
      if (pen) c.lineTo(x(p[0]), y(p[1])); else c.moveTo(x(p[0]), y(p[1]));
      pen = true;
    }
    c.stroke();
    c.restore();
  };
  window.WSGPlot = Plot;
})();
