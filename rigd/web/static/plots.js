// rigd console, the Live tab's plots: the autoscaled orbit with the film-gap circle and the
// time traces (one axis group per unit, pause/trigger views, cursor readout) — their lines on
// a canvas of our own over a Plotly frame (canvas.js) — and the render loop that draws them,
// the header, the trends and the cycle times (slowplots.js): frames only when something is
// due, never while input is pending, and at most DUTY of the wall time.
// docs/web.md.
import {extent, hystRange, line, paintLines, plotFrame, setLines} from "./canvas.js";
import {$, PLOT_CONFIG, band, colours, fmt, layoutBase, rigd, stackedAxes} from "./core.js";
import {HEADER_MS, headerPending, paintHeader} from "./header.js";
import {ORBIT_S, TRACE_S, identity} from "./live.js";
import {drawHistogram, drawTiming, drawTrends} from "./slowplots.js";

// Where the tab's CPU went (bench/console.py, CDP sampling profile of the Live tab on
// SwiftShader, 2026-11-26): ~80 % in Plotly calls — the once-a-second trends, percentiles and
// histogram (each a Plotly.react: a whole new layout, every text re-measured) ~40 %, the orbit
// ~22 %, the traces ~20 %; forced layouts (Plotly measuring text) 13 %. Hence: the orbit at
// 5/s, the slow plots every 2 s (the histogram every 5 s) and redrawn only when what they show
// changed, and the duty cap honoured for long draws too. Since then every plot's lines and
// bars are canvas strokes (canvas.js), Plotly lays out a frame only when an axis re-ranges,
// and without the points (plotFrame): the slow plots' periods stay, each now cheap.
const ORBIT_MS = 200;      // orbit redrawn at most 5 times a second
const TRACES_MS = 200;     // the time traces 5 times (the header too, header.js HEADER_MS)
const TREND_MS = 2000;     // trends every 2 s (canvas strokes)
const TIMING_MS = 5000;    // cycle-time percentiles every 5 s (when changed; canvas bars)
const HIST_MS = 5000;      // the cycle-time histogram (a fetch) every 5 s (when changed; canvas bars)
const SLACK_MS = 60;       // a job due this soon is drawn in the frame of one due now
const DUTY = 0.1;          // drawing takes at most this fraction of the wall time
const MAX_WAIT_MS = 1000;  // ... but the next draw waits no longer than this after a long one

// one axis group per unit (V split by role: the lumped x/y signals, the valves), short titles
// that fit their third of the plot (core.js groupOf: the record view's groups)
const GROUPS = [
  {unit: "µm", label: "e, µm", chans: ["e_x", "e_y"]},
  {unit: "V", label: "x/y, V", chans: ["u_x", "u_y", "r_x", "r_y", "k_x", "k_y"]},
  {unit: "V", label: "valves, V", chans: ["y_p1", "y_p2", "y_p3", "y_p4", "r_p1", "r_p2", "r_p3", "r_p4"]},
];
const NAMES = {k_x: "K∞ k_x", k_y: "K∞ k_y"};
// distinct over the whole plot (its one legend names every trace by colour)
const COLOURS = colours(GROUPS.flatMap((g) => g.chans));

// The lines (orbit, time traces; the slow plots' lines and bars too, slowplots.js) are drawn on
// a canvas of our own (canvas.js): Plotly draws their frame and is called only when it
// changes. The figures' traces are SVG `scatter` (`bar` for the cycle times), their own SVG
// lines and bars hidden.
rigd.traceType = "scatter";


// ---------------------------------------------------------------- orbit
// rigd.orbitScale: "auto" (fits the orbit: a 0.1 µm orbit fills the plot), "gap" (the film
// gap), "user" (the operator zoomed; double-click goes back to auto)
rigd.orbitScale = "auto";
let orbitRange = null;

export function setOrbitScale(mode) {
  rigd.orbitScale = mode;
  orbitRange = null;
  for (const b of document.querySelectorAll("[data-orbit]")) b.classList.toggle("active", b.dataset.orbit === mode);
  drawOrbit(true);
}

function orbitLayout(r, maxAbs) {
  const gap = rigd.filmGap;
  const ratio = maxAbs > 0 ? " · orbit " + fmt(maxAbs, maxAbs < 1 ? 3 : 1) + " µm = " +
    fmt(100 * maxAbs / gap, maxAbs / gap < 0.1 ? 2 : 0) + " % of it" : "";
  return layoutBase("orbit e_y vs e_x, µm (last " + ORBIT_S + " s)", {
    xaxis: {range: [-r, r], title: {text: "e_x, µm"}, zeroline: false},
    yaxis: {range: [-r, r], title: {text: "e_y, µm"}, scaleanchor: "x", zeroline: false},
    shapes: [{type: "circle", xref: "x", yref: "y", x0: -gap, y0: -gap, x1: gap, y1: gap,
      line: {color: "#c62828", dash: "dot", width: 1}}],
    annotations: [{xref: "paper", yref: "paper", x: 0, y: 1, xanchor: "left", yanchor: "top",
      showarrow: false, font: {size: 10, color: "#c62828"},
      text: "film gap " + gap + " µm (dotted)" + ratio}],
    // no Plotly hover: its lines are ours (canvas.js), it would search stale points
    showlegend: false, dragmode: "zoom", uirevision: "orbit", hovermode: false,
  });
}

function drawOrbit(force) {
  const b = rigd.buf, x = [], y = [];
  const tmin = (rigd.lastT || 0) - ORBIT_S;
  let m = 0;
  for (let i = 0; i < b.t.length; i++) {
    if (b.t[i] < tmin) continue;
    const ex = (b.e_x.lo[i] + b.e_x.hi[i]) / 2, ey = (b.e_y.lo[i] + b.e_y.hi[i]) / 2;
    x.push(ex); y.push(ey);
    m = Math.max(m, Math.abs(ex), Math.abs(ey));
  }
  const el = $("orbit");
  const data = [line(x, y, "orbit", "#1f77b4", {meta: {daemon: rigd.daemon && rigd.daemon.pid, t: rigd.lastT}}),
    line(x.slice(-1), y.slice(-1), "now", "#c62828", {mode: "markers", marker: {size: 8, color: "#c62828"}})];
  let want = orbitRange;
  if (rigd.orbitScale === "gap") want = rigd.filmGap * 1.05;
  else if (rigd.orbitScale === "auto") {
    const need = Math.max(1.25 * m, 0.01);
    // hysteresis: re-range when the orbit leaves the view or shrinks below 40 % of it
    if (!orbitRange || need > orbitRange || need < 0.4 * orbitRange) want = 1.6 * need;
  }
  if (force || !el.data || want !== orbitRange || rigd.orbitScale === "user" && !el.layout) {
    orbitRange = want;
    const lay = orbitLayout(want || 1, m);
    if (rigd.orbitScale === "user" && el.layout) { lay.xaxis.range = el.layout.xaxis.range; lay.yaxis.range = el.layout.yaxis.range; }
    // double-click is ours (back to auto), not Plotly's reset to the first ranges drawn
    plotFrame(el, data, lay, Object.assign({}, PLOT_CONFIG, {doubleClick: false}));
    if (!el.dataset.wired) {
      el.dataset.wired = "1";
      // a zoom, a resize, a new frame: the lines follow the axes at once
      el.on("plotly_afterplot", () => paintLines(el));
      el.on("plotly_relayout", (ev) => {
        if ("xaxis.range[0]" in ev && !rigd.orbitRelayout) { rigd.orbitScale = "user"; setButtons(); }
        else if (ev["xaxis.autorange"]) setOrbitScale("auto");
        paintLines(el);
      });
      el.on("plotly_doubleclick", () => setOrbitScale("auto"));
      // and the browser's own double-click (its click count, not Plotly's 300 ms timer: a
      // draw between the two presses on a busy machine made Plotly see two single clicks);
      // on the document, as Plotly's drag cover may take the second press
      document.addEventListener("dblclick", (ev) => {
        const r = el.getBoundingClientRect();
        if (ev.clientX >= r.left && ev.clientX <= r.right && ev.clientY >= r.top && ev.clientY <= r.bottom) {
          setOrbitScale("auto");
        }
      });
    }
  }
  setLines(el, data);
  paintLines(el);
  $("orbit-cap").textContent = identity(tmin, rigd.lastT || 0) + " · scale " + rigd.orbitScale;
  rigd.orbitRenders++;
}

function setButtons() {
  for (const b of document.querySelectorAll("[data-orbit]")) b.classList.toggle("active", b.dataset.orbit === rigd.orbitScale);
}

// ---------------------------------------------------------------- time traces
let tracesShape = "";
let tracesRanges = null;


/** The y range of each axis group of the traces for buffer `b` (hystRange; `old[gi]`). */
function groupRanges(b, old) {
  return GROUPS.map((g, gi) => hystRange(extent(g.chans.flatMap((c) => [b[c].lo, b[c].hi])),
    old && old[gi]));
}

function tracesLayout(xr, marker, yr) {
  const st = stackedAxes(GROUPS);
  st.ref.forEach((_, i) => { st.axes[i === 0 ? "yaxis" : "yaxis" + (i + 1)].range = yr[i]; });
  const lay = layoutBase("", Object.assign({
    xaxis: {range: xr, title: {text: marker ? "t − t_trigger, s" : "t − now, s"}, anchor: "y3"},
    // no Plotly hover (its lines are ours, canvas.js): the cursor readout is the page's own
    hovermode: false, dragmode: false, showlegend: true, margin: {l: 70, r: 10, t: 12, b: 84},
    legend: {orientation: "h", y: -0.16, font: {size: 10}}, uirevision: "traces",
  }, st.axes));
  lay.shapes = marker ? [{type: "line", xref: "x", yref: "paper", x0: 0, x1: 0, y0: 0, y1: 1,
    line: {color: "#c62828", width: 1, dash: "dash"}}] : [];
  return lay;
}

/** The cursor's vertical line over the traces (canvas.js paintLines' `extra`). */
function cursorLine(ctx, fl) {
  const c = rigd.cursor, xa = fl.xaxis;
  if (!c || c.x < xa.range[0] || c.x > xa.range[1]) return;
  const px = xa._offset + xa.l2p(c.x);
  ctx.strokeStyle = "#444";
  ctx.lineWidth = 1;
  ctx.setLineDash([]);
  ctx.beginPath();
  ctx.moveTo(px, fl._size.t);
  ctx.lineTo(px, fl._size.t + fl._size.h);
  ctx.stroke();
}

function paintTraces() { paintLines($("traces"), cursorLine); }

function drawTraces() {
  const v = rigd.view, b = v ? v.buf : rigd.buf;
  const t0 = v ? v.t0 : rigd.lastT || 0;
  const trig = v && rigd.trigger && rigd.trigger.state === "done";
  const st = stackedAxes(GROUPS);
  const data = [];
  // live, the buffers keep KEEP_S (a trigger's window) but the plot shows TRACE_S: the
  // buckets before it (a fifth of them) are not handed to the canvas, from the last one
  // before the left edge on (the line enters the plot from it)
  let from = 0;
  if (!v) {
    while (from < b.t.length && b.t[from] < t0 - TRACE_S) from++;
    from = Math.max(0, from - 1);
  }
  GROUPS.forEach((g, gi) => {
    for (const c of g.chans) {
      const e = band(b.t, b[c].lo, b[c].hi, t0, from);
      data.push(line(e.x, e.y, NAMES[c] || c, COLOURS[c], {yaxis: st.ref[gi], xaxis: "x",
        meta: {daemon: rigd.daemon && rigd.daemon.pid, t0: t0, epoch: rigd.epoch},
        line: {width: 1, color: COLOURS[c], dash: /^(r_p|k_)/.test(c) ? "dot" : "solid"}}));
    }
  });
  const shape = v ? (trig ? "trig" : "pause") : "live";
  const yr = groupRanges(b, shape === tracesShape ? tracesRanges : null);
  const el = $("traces");
  if (shape !== tracesShape || !el.data || yr.some((r, i) => r !== tracesRanges[i])) {
    tracesShape = shape;
    tracesRanges = yr;
    const xr = trig ? [-TRACE_S / 2, TRACE_S / 2] : [-TRACE_S, 0];
    plotFrame(el, data, tracesLayout(xr, trig, yr), PLOT_CONFIG);
    if (!el.dataset.wired) {
      el.dataset.wired = "1";
      el.on("plotly_afterplot", paintTraces);
      // the legend shows/hides a channel: the canvas follows
      el.on("plotly_restyle", paintTraces);
      el.addEventListener("mousemove", (ev) => {
        const fl = el._fullLayout, xa = fl && fl.xaxis;
        if (!xa) return;
        const r = el.getBoundingClientRect(), px = ev.clientX - r.left - xa._offset;
        if (px < 0 || px > xa._length) return;
        cursorAt(xa.p2l(px));
        paintTraces();
      });
    }
  }
  setLines(el, data);
  paintTraces();
  const t1 = b.t.length ? b.t[b.t.length - 1] : undefined;
  $("traces-cap").textContent = identity(b.t.length ? b.t[0] : undefined, t1) +
    (v ? " · " + v.label : " · live");
  rigd.renders++;
}

/** The cursor readout: loop time and every channel's bucket (min…max, unit) at x. */
export function cursorAt(x) {
  const v = rigd.view, b = v ? v.buf : rigd.buf, t0 = v ? v.t0 : rigd.lastT || 0;
  if (!b.t.length) return;
  const t = x + t0;
  let k = 0;
  while (k + 1 < b.t.length && b.t[k + 1] <= t) k++;
  const parts = [];
  for (const g of GROUPS) {
    for (const c of g.chans) {
      const lo = b[c].lo[k], hi = b[c].hi[k];
      if (lo === null || lo === undefined) continue;
      const d = g.unit === "µm" ? 3 : 3;
      parts.push((NAMES[c] || c) + " " + (lo === hi ? fmt(lo, d) : fmt(lo, d) + "…" + fmt(hi, d)) + " " + g.unit);
    }
  }
  rigd.cursor = {x, t};
  $("cursor").textContent = "cursor: loop t " + b.t[k].toFixed(4) + " s (x " + x.toFixed(4) + " s): " + parts.join(", ");
}

// ---------------------------------------------------------------- the render loop
// One timer, one frame: no animation frame is asked for unless something is due — the header
// (a new status), a plot with new data, the slow plots' period — and a frame draws everything
// due then or within SLACK_MS of it (the header, the orbit and the traces share their frames:
// 5 a second). Why: each frame runs Chromium's whole frame pipeline (style, layout, paint of
// the changed regions, layerizing a page of five SVG figures, compositing: "(program)" in the
// tab's profile); a frame asked for at every vsync (60/s) to look at the clock, and the
// header and each plot in frames of their own, cost more than the drawing itself.
const dirty = {orbit: false, traces: false};
const last = {header: 0, orbit: 0, traces: 0, trends: 0, timing: 0, hist: 0};
let nextDraw = 0, timer = null, timerAt = 0, frameAsked = false;
export function markDirty() {
  dirty.orbit = dirty.traces = true;
  wake();
}

function pendingInput() {
  const s = navigator.scheduling;
  return !!(s && s.isInputPending && s.isInputPending());
}

const liveShown = () => $("live").classList.contains("active");

// `live`: drawn only while the Live tab is shown (the header always)
const JOBS = [
  {key: "header", every: HEADER_MS, due: headerPending, run: paintHeader},
  {key: "orbit", every: ORBIT_MS, live: true, due: () => dirty.orbit, run: () => { dirty.orbit = false; drawOrbit(false); }},
  {key: "traces", every: TRACES_MS, live: true, due: () => dirty.traces, run: () => { dirty.traces = false; drawTraces(); }},
  {key: "trends", every: TREND_MS, live: true, due: () => true, run: () => { drawTrends(); }},
  // once the stream has brought percentiles (before, an empty frame would stand for 5 s)
  {key: "timing", every: TIMING_MS, live: true, due: () => !!rigd.timing, run: () => { drawTiming(); }},
  // a fetch of /api/timing: not while the daemon does not answer (live.js startWatch)
  {key: "hist", every: HIST_MS, live: true, due: () => rigd.daemonUp, run: () => { drawHistogram(); }},
];

/** The jobs that may run now (the Live tab's only while it is shown) and are due. */
function dueJobs(shown) { return JOBS.filter((j) => (shown || !j.live) && j.due()); }

/** Run every job due at `now` (or within SLACK_MS of it); returns the ms it took. */
function drawDue(now, shown) {
  const a = performance.now(), jm = rigd.jobMs || (rigd.jobMs = {});
  let ran = false;
  for (const j of dueJobs(shown)) {
    if (now - last[j.key] < j.every - SLACK_MS) continue;
    // an operator's press (SAFE) waits for no more than the job under way: the rest of the
    // frame's jobs stay due for the next frame
    if (ran && pendingInput()) break;
    last[j.key] = now;
    const b = performance.now();
    try {
      j.run();
    } finally {
      // per plot, ms (bench/console.py reports where the drawing goes)
      jm[j.key] = (jm[j.key] || 0) + performance.now() - b;
      jm[j.key + "_n"] = (jm[j.key + "_n"] || 0) + 1;
    }
    ran = true;
  }
  if (ran) rigd.frames = (rigd.frames || 0) + 1;
  return performance.now() - a;
}

/** Ask for a frame when the next job is due (a timer until then); nothing due, nothing asked:
 * new data (markDirty, markHeader) wakes it again. */
export function wake() {
  if (frameAsked) return;
  let at = Infinity;
  for (const j of dueJobs(liveShown())) at = Math.min(at, last[j.key] + j.every);
  if (at === Infinity) return;
  at = Math.max(at, nextDraw);
  if (timer !== null && timerAt <= at) return;    // already waiting for that one (or sooner)
  if (timer !== null) clearTimeout(timer);
  timer = null;
  const wait = at - performance.now();
  if (wait <= 0) { frameAsked = true; requestAnimationFrame(renderFrame); return; }
  timerAt = at;
  timer = setTimeout(() => { timer = null; wake(); }, wait);
}

function renderFrame() {
  // the clock of the timers (the frame's own timestamp is its start, earlier: a job due now
  // would not be, and wait for another frame)
  const now = performance.now();
  frameAsked = false;
  try {
    if (pendingInput()) {
      nextDraw = now + 16;                 // the operator's input first
    } else if (now >= nextDraw) {
      const shown = liveShown(), d = drawDue(now, shown);
      if (shown) rigd.drawMs += d;
      // at most DUTY of the time drawing (a plot's first draw may take a second on a busy
      // machine: that one-off holds the others back MAX_WAIT_MS at most)
      nextDraw = now + Math.min(d / DUTY, MAX_WAIT_MS);
    }
  } finally {
    // a draw that throws must not end the drawing for good
    wake();
  }
}

export function startRendering() {
  // the Live tab shown again: its plots are due at once
  document.querySelector("nav").addEventListener("click", () => setTimeout(wake, 0));
  wake();
}

/** Redraw the traces now (pause, trigger, resume: the operator sees the change at once). */
export function redrawTraces() {
  dirty.traces = true;
  last.traces = 0;
  wake();
}
