// rigd console, the Live tab's slow plots: the trends of the last minutes (Ω, P_I, misses/s,
// fault events) and the cycle times (percentiles on a log axis, the histogram with log
// counts) — their lines and bars on a canvas of our own over a Plotly frame (canvas.js) that
// Plotly lays out again only when an axis re-ranges. Called by plots.js's render loop.
// docs/web.md.
import {extent, hystRange, line, paintLines, plotFrame, setLines} from "./canvas.js";
import {$, PLOT_CONFIG, api, fmt, layoutBase, rigd, stackedAxes} from "./core.js";
import {TREND_S, trend} from "./live.js";

// what the cycle-time plots show now (a redraw that would show the same is skipped)
const drawnKey = {timing: null, hist: null};

/** Draw figure `el`: its frame, with `layout` (a new frame, or the first draw), through
 * `Plotly.react` (the traces without their points; the lines and bars painted again after
 * each of Plotly's redraws, a resize too), no Plotly call without; then `data` set in place
 * and its lines and bars on its canvas (canvas.js; `extra` as paintLines'). */
function drawFigure(el, data, layout, extra) {
  if (layout) {
    plotFrame(el, data, layout, PLOT_CONFIG);
    if (!el.dataset.wired) {
      el.dataset.wired = "1";
      el.on("plotly_afterplot", () => paintLines(el, extra));
    }
  }
  setLines(el, data);
  paintLines(el, extra);
}

// ---------------------------------------------------------------- trends
// On the canvas too (canvas.js), over a Plotly frame that does not move: x is the time before
// now (t − now, the last TREND_S s), so the frame is laid out again only when an axis's y range
// re-ranges (hysteresis, as the traces'); a redraw (every 2 s, plots.js TREND_MS) is a few canvas strokes.
// `minSpan`: the narrowest range an axis gets (a flat 0 rpm is not drawn on a ±500 µrpm axis)
const TREND_AXES = [{key: "omega", label: "Ω, rpm", minSpan: 20}, {key: "pinj", label: "P_I, bar", minSpan: 0.1},
  {key: "missRate", label: "misses/s", minSpan: 2}];
let trendRanges = null;

/** The fault events' dotted lines across the trends (canvas.js paintLines' `extra`). */
function faultLines(ctx, fl) {
  const el = $("trends"), f = el.data && el.data[3], xa = fl.xaxis;
  if (!f) return;
  ctx.strokeStyle = "#c62828";
  ctx.lineWidth = 1;
  ctx.setLineDash([2, 2]);
  ctx.beginPath();
  for (const x of f.x) {
    if (x < xa.range[0] || x > xa.range[1]) continue;
    const px = xa._offset + xa.l2p(x);
    ctx.moveTo(px, fl._size.t);
    ctx.lineTo(px, fl._size.t + fl._size.h);
  }
  ctx.stroke();
  ctx.setLineDash([]);
}

export function drawTrends() {
  const now = Date.now(), rel = (w) => (w - now) / 1000;
  const fx = trend.faults.map((f) => rel(f.wall)), fy = trend.faults.map(() => 0);
  const tx = trend.wall.map(rel);
  const data = [
    line(tx, trend.omega, "Ω", "#1f77b4", {yaxis: "y"}),
    line(tx, trend.pinj, "P_I", "#ff7f0e", {yaxis: "y2"}),
    line(tx, trend.missRate, "misses/s", "#7f7f7f", {yaxis: "y3", mode: "lines+markers", marker: {size: 3}}),
    {x: fx, y: fy, yaxis: "y3", name: "fault", type: "scatter", mode: "markers+text", hoverinfo: "none",
      text: trend.faults.map((f) => f.name), textposition: "top left", textfont: {size: 9, color: "#c62828"},
      marker: {symbol: "x", size: 10, color: "#c62828"},
      hovertext: trend.faults.map((f) => f.name + " at " + f.at + ": " + f.text)},
  ];
  // misses/s: 0 is always in view (a rate of nothing is the normal state)
  const yr = TREND_AXES.map((a, i) => hystRange(extent([trend[a.key]], i === 2 ? 0 : undefined),
    trendRanges && trendRanges[i], a.minSpan));
  const el = $("trends");
  let lay = null;
  if (!el.data || yr.some((r, i) => r !== trendRanges[i])) {
    trendRanges = yr;
    const st = stackedAxes(TREND_AXES);
    st.ref.forEach((_, i) => { st.axes[i === 0 ? "yaxis" : "yaxis" + (i + 1)].range = yr[i]; });
    lay = layoutBase("trends, last " + TREND_S / 60 + " min (faults ✕)", Object.assign({
      xaxis: {range: [-TREND_S, 0], title: {text: "t − now, s"}, anchor: "y3", zeroline: false},
      showlegend: false, uirevision: "trends", hovermode: false, dragmode: false,
    }, st.axes));
  }
  drawFigure(el, data, lay, faultLines);
  rigd.trendRenders++;
}

// ---------------------------------------------------------------- cycle times
// Bars on the canvas too, over a Plotly frame on log axes laid out again only when a value
// leaves its range (whole decades, decadeRange): the percentiles change with every update of
// the status and the histogram's counts with every cycle, and a Plotly redraw of either (an
// SVG figure, every text re-measured) cost more than all the canvas strokes of a period.
// What a number is worth reading — the percentiles, the misses, the samples beyond the
// histogram — is in the figure's caption.
const PCT = [["p50", "p50"], ["p99", "p99"], ["p999", "p99.9"], ["max", "max"]];
const SERIES = [["compute", "#1f77b4"], ["lateness", "#ff7f0e"]];
const BAR_W = 0.4;        // a percentile's bar, in category widths (two side by side)
const ranges = {timing: null, histY: null, histX: null};

/** The range of a log axis (log10 units) for the positive values `vals`: whole decades, the
 * smallest value's bar at least 0.1 decade tall; `old` is kept while every value is inside it
 * and it is at most one decade wider than they need (hysteresis: bars that change a little do
 * not move the frame). */
function decadeRange(vals, old) {
  let lo = Infinity, hi = -Infinity;
  for (const v of vals) if (v > 0 && Number.isFinite(v)) { lo = Math.min(lo, v); hi = Math.max(hi, v); }
  if (hi < lo) return old || [0, 1];
  const a = Math.log10(lo), b = Math.log10(hi);
  const want = [Math.floor(a - 0.1), Math.max(Math.ceil(b + 0.05), Math.floor(a - 0.1) + 1)];
  if (old && a - 0.1 >= old[0] && b + 0.05 <= old[1] && old[1] - old[0] <= want[1] - want[0] + 1) return old;
  return want;
}

const num = (v) => (v === null || v === undefined || Number.isNaN(Number(v)) ? null : Number(v));
const usText = (v) => (v === null ? "–" : Number(v.toPrecision(3)).toString());

/** A bar chart's layout on these figures: log y axis of range `yr` (decades), the rest given. */
function barsLayout(title, yTitle, yr, xaxis, legendRight) {
  return layoutBase(title, {
    barmode: "overlay", hovermode: false, dragmode: false, uirevision: title,
    yaxis: {type: "log", range: yr, title: {text: yTitle}}, xaxis,
    legend: {orientation: "h", x: legendRight ? 0.99 : 0.01, xanchor: legendRight ? "right" : "left",
      y: 0.99, yanchor: "top", bgcolor: "rgba(255,255,255,0.75)", font: {size: 10}},
  });
}

export function drawTiming() {
  const t = rigd.timing || {};
  const vals = SERIES.map(([name]) => PCT.map(([k]) => num((t[name + "_us"] || {})[k])));
  const misses = num(rigd.lastStatus && rigd.lastStatus.misses);
  // as shown (3 significant digits): unchanged, nothing is drawn
  const shown = vals.map((v) => v.map(usText));
  const key = JSON.stringify([misses, shown]);
  if (key === drawnKey.timing) return;
  drawnKey.timing = key;
  const data = SERIES.map(([name, col], s) => ({x: [0, 1, 2, 3], y: vals[s], type: "bar",
    name: name + " µs", offset: (s - 1) * BAR_W, width: BAR_W, marker: {color: col}, hoverinfo: "none"}));
  const yr = decadeRange(vals.flat(), ranges.timing), el = $("timing");
  const lay = !el.data || yr !== ranges.timing ? barsLayout("cycle time percentiles, µs", "µs (log)", yr,
    {range: [-0.5, 3.5], tickmode: "array", tickvals: [0, 1, 2, 3], ticktext: PCT.map((p) => p[1]),
      title: {text: "percentile"}, zeroline: false}, false) : null;
  ranges.timing = yr;
  drawFigure(el, data, lay);
  $("timing-cap").textContent = SERIES.map(([name], s) => name + " " + PCT.map(([, label], i) =>
    label + " " + shown[s][i]).join(" / ") + " µs").join(" · ") + " · misses " + (misses === null ? "–" : misses);
  rigd.timingRenders = (rigd.timingRenders || 0) + 1;
}

// the cycle-time histogram: `timing`'s coarse histograms (the daemon's 100 ns bins summed to
// at most 32 bars; counts since the loop started), fetched with the same period as the
// percentiles
export async function drawHistogram() {
  const r = await api("/api/timing");
  const h = r.ok && r.body && r.body.histogram_us;
  if (!h) return;
  const a = performance.now();
  const data = [], caption = [];
  let top = 0;
  for (const [name, col] of SERIES) {
    const d = h[name];
    if (!d || !d.counts.length) continue;
    const w = d.edges_us[1] - d.edges_us[0];
    top = Math.max(top, d.edges_us[d.edges_us.length - 1]);
    data.push({x: d.counts.map((_, i) => d.edges_us[i]), y: d.counts, type: "bar", name,
      offset: 0, width: w, opacity: 0.7, marker: {color: col}, hoverinfo: "none"});
    caption.push(name + ": " + d.counts.reduce((x, y) => x + y, 0) + " cycles in bars of " +
      fmt(w, w < 1 ? 2 : 1) + " µs" + (d.overflow ? ", " + d.overflow + " beyond them" : ""));
  }
  const key = JSON.stringify(data.map((b) => [b.name, b.y, b.width]));
  if (!data.length || key === drawnKey.hist) return;
  drawnKey.hist = key;
  const el = $("timing-hist");
  const yr = decadeRange(data.flatMap((b) => b.y), ranges.histY);
  // x from 0 to the last bar's edge, re-ranged when a bar leaves it or fills less than half
  const old = ranges.histX, xr = old && top <= old[1] && top >= 0.5 * old[1] ? old : [0, 1.1 * top];
  // the same traces as drawn (a series without samples yet: a new frame)
  const same = el.data && el.data.length === data.length && el.data.every((tr, i) => tr.name === data[i].name);
  const lay = !same || yr !== ranges.histY || xr !== old ? barsLayout("cycle-time histogram", "cycles (log)", yr,
    {range: xr, title: {text: "µs"}, zeroline: false}, true) : null;
  ranges.histY = yr;
  ranges.histX = xr;
  drawFigure(el, data, lay);
  $("timing-hist-cap").textContent = caption.join(" · ");
  rigd.histRenders++;
  // its drawing, after the fetch (plots.js counts a job's time until its first await)
  const jm = rigd.jobMs || (rigd.jobMs = {});
  jm.hist = (jm.hist || 0) + performance.now() - a;
}
