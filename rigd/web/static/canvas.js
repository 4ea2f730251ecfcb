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

/** Draw the traces of figure `el` (its `el.data`: x, y, line colour/width/dash, `mode`
 * lines or markers, `visible`) on its canvas, each clipped to its axes' plot area, in the
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
    const px = (v) => xa._offset + xa.l2p(v), py = (v) => ya._offset + ya.l2p(v);
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
      ctx.fillStyle = mk.color || (tr.line || {}).color || "#000";
      for (let i = 0; i < x.length; i++) {
        if (x[i] === null || y[i] === null) continue;
        ctx.beginPath();
        ctx.arc(px(x[i]), py(y[i]), r, 0, 2 * Math.PI);
        ctx.fill();
      }
    }
    ctx.restore();
  }
  if (extra) extra(ctx, fl);
}

/** Set the traces' data of figure `el` in place (what the next paintLines draws, and what a
 * reader of `el.data` sees) without a Plotly call: `data[i]` {x, y, meta} for trace i. */
export function setLines(el, data) {
  data.forEach((d, i) => {
    const tr = el.data[i];
    tr.x = d.x;
    tr.y = d.y;
    if (d.meta !== undefined) tr.meta = d.meta;
  });
}
