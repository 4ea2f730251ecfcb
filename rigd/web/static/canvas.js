// rigd console, the fast lines of the Live tab drawn on a canvas of our own over a Plotly
// figure: Plotly draws the frame (axes, titles, ticks, legend, shapes) and handles the zoom,
// and is called again only when the frame changes (a range, the view); the lines themselves,
// redrawn 5 times a second, are a few canvas strokes. docs/web.md "Cheap to draw".
//
// Why: without a GPU (Chromium's SwiftShader, as on the rig's PC) one Plotly.restyle of the
// 16 time traces (SVG, 800 points each) cost ~160-350 ms of the renderer at load average
// ≈ 17 and the tab ~35 % of a core at 5 redraws/s; the same lines on a canvas cost ~3-5 ms a
// redraw and ~3.5 % (a page drawing only them, same machine, same minutes).
//
// The figure's traces (`el.data`) keep what the canvas drew — x, y, meta — set in place
// between Plotly calls, so a reader of the page (the tests) sees the lines' data where Plotly
// keeps it; the figure's own SVG lines are hidden (style.css: `.canvas-lines .scatterlayer`).

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
 * `_b + _m v`, without the rounding of `l2p`: a call per point of every line), else `l2p`. */
function toPixel(ax) {
  const o = ax._offset, m = ax._m, b = ax._b;
  if (ax.type === "linear" && Number.isFinite(m) && Number.isFinite(b) && !(ax.rangebreaks || []).length) {
    return (v) => o + b + m * v;
  }
  return (v) => o + ax.l2p(v);
}

/** Draw the traces of figure `el` (its `el.data`: x, y, line colour/width/dash, `mode`
 * lines, markers (circles, or crosses for symbol "x") or text, `visible`) on its canvas, each clipped to its axes' plot area, in the
 * figure's current axis ranges; `extra(ctx, fullLayout)` draws more on top (a cursor). */
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
    if (/lines/.test(tr.mode || "lines")) {
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
 * reader of `el.data` sees) without a Plotly call: `data[i]` {x, y, meta, text, hovertext}
 * for trace i. */
export function setLines(el, data) {
  data.forEach((d, i) => {
    const tr = el.data[i];
    tr.x = d.x;
    tr.y = d.y;
    for (const k of ["meta", "text", "hovertext"]) if (d[k] !== undefined) tr[k] = d[k];
  });
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
