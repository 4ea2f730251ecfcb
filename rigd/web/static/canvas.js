// rigd console, the lines and bars of the Live tab drawn on a canvas of our own over a Plotly
// figure: Plotly draws the frame (axes, titles, ticks, legend, shapes) and handles the zoom,
// and is called again only when the frame changes (a range, the view); the lines and bars
// themselves, redrawn up to 5 times a second, are a few canvas strokes. docs/web.md "Cheap to
// draw".
//
// Why: without a GPU (Chromium's SwiftShader, as on the rig's PC) one Plotly.restyle of the
// 16 time traces (SVG, 800 points each) cost ~160-350 ms of the renderer at load average
// ≈ 17 and the tab ~35 % of a core at 5 redraws/s; the same lines on a canvas cost ~3-5 ms a
// redraw and ~3.5 % (a page drawing only them, same machine, same minutes). Plotly lays out a
// frame for traces without their points (plotFrame): it computes its own SVG paths of what it
// is given even where they are hidden.
//
// The figure's traces (`el.data`) keep what the canvas drew — x, y, meta — set in place
// between Plotly calls, so a reader of the page (the tests) sees the lines' data where Plotly
// keeps it; the figure's own SVG lines and bars are hidden (style.css: `.canvas-lines
// .scatterlayer`, `.barlayer`).

import {rigd} from "./core.js";

/** The overlay canvas of Plotly figure `el`, made once, put back between the figure's two
 * SVG layers (above the axes and grid, under the legend, zoom box and titles) when Plotly
 * rebuilt them, sized to the figure in device pixels. Returns its 2D context (CSS pixels)
 * cleared, or null before the figure's first draw. */
function overlay(el) {
  const fl = el._fullLayout, box = el.querySelector(".svg-container");
  if (!fl || !box) return null;
  let cv = el.rigdCanvas;
  if (!cv) {
    cv = el.rigdCanvas = document.createElement("canvas");
    cv.className = "lines-overlay";
    el.classList.add("canvas-lines");
  }
  if (cv.parentNode !== box) box.insertBefore(cv, box.querySelectorAll(":scope > svg.main-svg")[1] || null);
  const dpr = window.devicePixelRatio || 1, w = fl.width, h = fl.height;
  if (cv.width !== Math.round(w * dpr) || cv.height !== Math.round(h * dpr)) {
    cv.width = Math.round(w * dpr);
    cv.height = Math.round(h * dpr);
    cv.style.width = w + "px";
    cv.style.height = h + "px";
  }
  const ctx = cv.getContext("2d");
  ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
  ctx.clearRect(0, 0, w, h);
  return ctx;
}

function axisOf(fl, ref, letter) {
  return fl[letter + "axis" + (!ref || ref === letter ? "" : ref.slice(1))];
}

/** Data value -> pixel in the figure for axis `ax`: on a linear axis its own scale (Plotly's
 * `_b + _m v`, without the rounding of `l2p`: a call per point of every line), on a log axis
 * the same scale of log10 v (NaN for v <= 0: nothing to draw), else `l2p`. */
function toPixel(ax) {
  const o = ax._offset, m = ax._m, b = ax._b;
  const scaled = Number.isFinite(m) && Number.isFinite(b) && !(ax.rangebreaks || []).length;
  if (ax.type === "linear" && scaled) return (v) => o + b + m * v;
  if (ax.type === "log" && scaled) return (v) => (v > 0 ? o + b + m * Math.log10(v) : NaN);
  return (v) => o + ax.l2p(v);
}

/** The bars of trace `tr` (Plotly's `bar`: each point x[i] spans x[i] + offset … + width, in
 * data units, scalars or arrays) filled from the axis' base — 0 on a linear axis, the plot
 * area's bottom on a log one (a count or a time of 0 has no bar there). */
function paintBars(ctx, tr, xa, ya, px, py) {
  const x = tr.x, y = tr.y || [], at = (v, i) => (Array.isArray(v) ? v[i] : v);
  const bottom = ya._offset + ya._length;
  const base = ya.type === "log" ? bottom : Math.min(Math.max(py(0), ya._offset), bottom);
  ctx.fillStyle = (tr.marker || {}).color || "#000";
  ctx.globalAlpha = tr.opacity === undefined ? 1 : tr.opacity;
  for (let i = 0; i < x.length; i++) {
    const top = y[i] === null || y[i] === undefined ? NaN : py(y[i]);
    if (!Number.isFinite(top) || x[i] === null) continue;
    const x0 = x[i] + (at(tr.offset, i) || 0), w = at(tr.width, i) || 0;
    const a = px(x0), b = px(x0 + w);
    ctx.fillRect(Math.min(a, b), Math.min(top, base), Math.max(Math.abs(b - a), 1), Math.abs(base - top));
  }
  ctx.globalAlpha = 1;
}

/** Draw the traces of figure `el` (its `el.data`: x, y, line colour/width/dash, `mode`
 * lines, markers (circles, or crosses for symbol "x") or text, `visible`; a `bar` trace's bars)
 * on its canvas, each clipped to its axes' plot area, in the figure's current axis ranges;
 * `extra(ctx, fullLayout)` draws more on top (a cursor). */
export function paintLines(el, extra) {
  const ctx = overlay(el);
  if (!ctx) return;
  const fl = el._fullLayout;
  for (const tr of el.data || []) {
    if (tr.visible === false || tr.visible === "legendonly") continue;
    const xa = axisOf(fl, tr.xaxis, "x"), ya = axisOf(fl, tr.yaxis, "y");
    const x = tr.x || [], y = tr.y || [];
    if (!xa || !ya || !x.length) continue;
    ctx.save();
    ctx.beginPath();
    ctx.rect(xa._offset, ya._offset, xa._length, ya._length);
    ctx.clip();
    const px = toPixel(xa), py = toPixel(ya);
    if (tr.type === "bar") {
      paintBars(ctx, tr, xa, ya, px, py);
    } else if (/lines/.test(tr.mode || "lines")) {
      const ln = tr.line || {};
      ctx.strokeStyle = ln.color || "#000";
      ctx.lineWidth = ln.width || 1;
      ctx.setLineDash(ln.dash === "dot" ? [2, 2] : ln.dash === "dash" ? [5, 3] : []);
      ctx.beginPath();
      let pen = false;
      for (let i = 0; i < x.length; i++) {
        // a missing value breaks the line (as Plotly does without connectgaps)
        if (x[i] === null || y[i] === null || x[i] === undefined || y[i] === undefined) { pen = false; continue; }
        if (pen) ctx.lineTo(px(x[i]), py(y[i])); else ctx.moveTo(px(x[i]), py(y[i]));
        pen = true;
      }
      ctx.stroke();
    }
    if (/markers/.test(tr.mode || "")) {
      const mk = tr.marker || {}, r = (mk.size || 6) / 2;
      ctx.fillStyle = ctx.strokeStyle = mk.color || (tr.line || {}).color || "#000";
      ctx.lineWidth = 2;
      ctx.setLineDash([]);
      for (let i = 0; i < x.length; i++) {
        if (x[i] === null || y[i] === null) continue;
        const cx = px(x[i]), cy = py(y[i]);
        ctx.beginPath();
        if (mk.symbol === "x") {       // a cross (the trends' fault events)
          ctx.moveTo(cx - r, cy - r); ctx.lineTo(cx + r, cy + r);
          ctx.moveTo(cx - r, cy + r); ctx.lineTo(cx + r, cy - r);
          ctx.stroke();
        } else {
          ctx.arc(cx, cy, r, 0, 2 * Math.PI);
          ctx.fill();
        }
      }
    }
    if (/text/.test(tr.mode || "") && tr.text) {
      // each point's text above it, to its left (Plotly's textposition "top left")
      const tf = tr.textfont || {};
      ctx.fillStyle = tf.color || "#000";
      ctx.font = (tf.size || 10) + "px sans-serif";
      ctx.textAlign = "right";
      ctx.textBaseline = "bottom";
      for (let i = 0; i < x.length; i++) {
        if (x[i] === null || y[i] === null || !tr.text[i]) continue;
        ctx.fillText(tr.text[i], px(x[i]) - 2, py(y[i]) - 4);
      }
    }
    ctx.restore();
  }
  if (extra) extra(ctx, fl);
}

/** Set the traces' data of figure `el` in place (what the next paintLines draws, and what a
 * reader of `el.data` sees) without a Plotly call: `data[i]` {x, y, meta, text, hovertext;
 * a bar's width and offset} for trace i. */
export function setLines(el, data) {
  data.forEach((d, i) => {
    const tr = el.data[i];
    tr.x = d.x;
    tr.y = d.y;
    for (const k of ["meta", "text", "hovertext", "width", "offset"]) if (d[k] !== undefined) tr[k] = d[k];
  });
}

/** The traces `data` without their points, for a Plotly call that lays out their frame and
 * legend (the points are set in place after it, setLines, and drawn on the canvas): Plotly
 * computes its own paths of what it is given even where they are hidden — for the 16 time
 * traces' 800 points each, most of a re-range's cost. One null point each: a trace without a
 * point drops out of Plotly's legend. A later Plotly redraw of its own (a resize, a legend
 * click) works on the points set in place. */
function withoutPoints(data) {
  return data.map((d) => Object.assign({}, d, {x: [null], y: [null]}));
}

/** Lay out figure `el`'s frame (axes, titles, legend, shapes) for the traces `data` through
 * `Plotly.react`, the traces without their points (withoutPoints); the caller sets the points
 * in place after it (setLines: what paintLines draws and `el.data` shows). Counted per figure
 * in `window.rigd.frameLayouts` (bench/console.py: how often a window laid out a frame). */
export function plotFrame(el, data, layout, config) {
  Plotly.react(el, withoutPoints(data), layout, config);
  const n = rigd.frameLayouts || (rigd.frameLayouts = {});
  n[el.id] = (n[el.id] || 0) + 1;
}

/** A line trace (SVG `scatter`: its own line hidden, canvas.js draws it) for a figure. */
export function line(x, y, name, colour, extra) {
  return Object.assign({x, y, name, type: "scatter", mode: "lines", hoverinfo: "none",
    line: {width: 1, color: colour}}, extra || {});
}

/** [lo, hi] over the non-null values of the arrays `arrs` (`with`: a value always inside),
 * or null when there is none. */
export function extent(arrs, withValue) {
  let lo = Infinity, hi = -Infinity;
  for (const a of arrs) {
    for (let i = 0; i < a.length; i++) {
      const v = a[i];
      if (v === null || v === undefined) continue;
      if (v < lo) lo = v;
      if (v > hi) hi = v;
    }
  }
  if (withValue !== undefined && hi >= lo) { lo = Math.min(lo, withValue); hi = Math.max(hi, withValue); }
  return hi >= lo ? [lo, hi] : null;
}

/** A y range for lines spanning `ext` ([lo, hi] or null) with hysteresis: the range `old` is
 * kept while the lines stay inside it and span at least 40 % of it, else they get their
 * extent with 10 % either side (a flat line: a span of 2 % of its value, at least `minSpan`,
 * default 0.001).
 * Plotly's own autorange would redo the whole frame at every redraw. */
export function hystRange(ext, old, minSpan) {
  if (!ext) return old || [-1, 1];
  const [lo, hi] = ext;
  const mid = (lo + hi) / 2, span = Math.max(hi - lo, 0.02 * Math.abs(mid), minSpan || 1e-3);
  if (old && lo >= old[0] && hi <= old[1] && span >= 0.4 * (old[1] - old[0])) return old;
  return [mid - 0.6 * span, mid + 0.6 * span];
}
