// rigd console, the Live tab's slow plots: the trends of the last minutes (Ω, P_I, misses/s,
// fault events; lines on a canvas of our own over a Plotly frame, canvas.js) and the cycle
// times (percentiles on a log axis, the histogram: Plotly's SVG, redrawn only when what they
// show changed). Called by plots.js's render loop. docs/web.md.
import {extent, hystRange, line, paintLines, setLines} from "./canvas.js";
import {$, PLOT_CONFIG, api, layoutBase, rigd, stackedAxes} from "./core.js";
import {TREND_S, trend} from "./live.js";

// what the cycle-time plots show now (a redraw that would show the same is skipped)
const drawnKey = {timing: null, hist: null};

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
  if (!el.data || yr.some((r, i) => r !== trendRanges[i])) {
    trendRanges = yr;
    const st = stackedAxes(TREND_AXES);
    st.ref.forEach((_, i) => { st.axes[i === 0 ? "yaxis" : "yaxis" + (i + 1)].range = yr[i]; });
    const lay = layoutBase("trends, last " + TREND_S / 60 + " min (faults ✕)", Object.assign({
      xaxis: {range: [-TREND_S, 0], title: {text: "t − now, s"}, anchor: "y3", zeroline: false},
      showlegend: false, uirevision: "trends", hovermode: false, dragmode: false,
    }, st.axes));
    Plotly.react(el, data, lay, PLOT_CONFIG);
    if (!el.dataset.wired) {
      el.dataset.wired = "1";
      el.on("plotly_afterplot", () => paintLines(el, faultLines));
    }
  } else {
    setLines(el, data);
  }
  paintLines(el, faultLines);
  rigd.trendRenders++;
}

// ---------------------------------------------------------------- cycle times
export function drawTiming() {
  const t = rigd.timing || {}, keys = ["p50", "p99", "p999", "max"];
  const bars = [];
  for (const [name, d, col] of [["compute", t.compute_us, "#1f77b4"], ["lateness", t.lateness_us, "#ff7f0e"]]) {
    if (!d) continue;
    bars.push({x: ["p50", "p99", "p99.9", "max"], y: keys.map((k) => d[k]), type: "bar",
      name: name + " µs", marker: {color: col}});
  }
  const misses = rigd.lastStatus && rigd.lastStatus.misses;
  // percentiles as shown (3 significant digits) and the title: unchanged, nothing is redrawn
  const key = JSON.stringify([misses, bars.map((b) => [b.name, b.y.map((v) => (v === null || v === undefined) ? v : Number(v).toPrecision(3))])]);
  if (key === drawnKey.timing) return;
  drawnKey.timing = key;
  Plotly.react("timing", bars, layoutBase("cycle time percentiles (misses: " +
    (misses === undefined || misses === null ? "–" : misses) + ")", {barmode: "group",
    yaxis: {type: "log", title: {text: "µs (log)"}}, xaxis: {title: {text: "percentile"}}}), PLOT_CONFIG);
}

// the cycle-time histogram: `timing`'s coarse histograms (the daemon's 100 ns bins summed to
// at most 32 bars), fetched with the same period as the percentiles
export async function drawHistogram() {
  const r = await api("/api/timing");
  const h = r.ok && r.body && r.body.histogram_us;
  if (!h) return;
  const bars = [];
  for (const [name, d, col] of [["compute", h.compute, "#1f77b4"], ["lateness", h.lateness, "#ff7f0e"]]) {
    if (!d || !d.counts.length) continue;
    const mid = d.counts.map((_, i) => 0.5 * (d.edges_us[i] + d.edges_us[i + 1]));
    bars.push({x: mid, y: d.counts, type: "bar", name: name + (d.overflow ? " (+" +
      d.overflow + " beyond)" : ""), opacity: 0.7, marker: {color: col}});
  }
  const key = JSON.stringify(bars.map((b) => [b.name, b.y]));
  if (key === drawnKey.hist) return;
  drawnKey.hist = key;
  Plotly.react("timing-hist", bars, layoutBase("cycle-time histogram",
    {barmode: "overlay", yaxis: {type: "log", title: {text: "cycles (log)"}},
      xaxis: {title: {text: "µs"}}, legend: {orientation: "h", x: 0.99, xanchor: "right", y: 0.99,
        yanchor: "top", bgcolor: "rgba(255,255,255,0.75)", font: {size: 10}}}), PLOT_CONFIG);
  rigd.histRenders++;
}

