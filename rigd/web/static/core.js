// rigd console, shared pieces: the page state `rigd` (window.rigd, read by the tests), API
// calls with the token, the message line (messages clear when their cause clears), number
// formatting, channel units and colours, plot layout helpers. docs/web.md.

// what tests (and curious users) can read: window.rigd
export const rigd = window.rigd = {
  updates: 0, renders: 0, orbitRenders: 0, trendRenders: 0, histRenders: 0, lastSeq: null,
  cycle: null, mode: "connecting", filmGap: 25.0, fs: 5000.0, buf: null, lastStatus: null,
  lastT: undefined, epoch: 0, restarts: [], daemon: null, lastGood: 0, stale: false,
  paused: false, trigger: null, drawMs: 0, safeClicks: [], daemonUp: false, access: null,
};

export const $ = (id) => document.getElementById(id);

export function token() { return sessionStorage.getItem("rigd-token") || ""; }

/** One API request: GET without a body, POST with a JSON body; the token goes with both. */
export async function api(path, body) {
  const opts = {method: body === undefined ? "GET" : "POST", headers: {}};
  const tk = token();
  if (tk) opts.headers["Authorization"] = "Bearer " + tk;
  if (body !== undefined) {
    opts.headers["Content-Type"] = "application/json";
    opts.body = JSON.stringify(body);
  }
  let r;
  try {
    r = await fetch(path, opts);
  } catch (e) {
    return {ok: false, status: 0, body: {error: "rigd web not reachable: " + e.message}};
  }
  let data;
  try { data = await r.json(); } catch (e) { data = {error: r.status + " " + r.statusText}; }
  return {ok: r.ok, status: r.status, body: data};
}

// ---------------------------------------------------------------- the message line
// `cause` says when a message goes away by itself: "conn" once the daemon answers again,
// "fault" once no fault is latched; without a cause it stays until the next message.
let msgCause = null;

export function say(text, kind, cause) {
  const m = $("message");
  m.textContent = String(text).split("\n")[0];
  m.className = "message " + (kind || "");
  m.title = m.textContent;
  msgCause = cause || null;
}

/** The cause `cause` has cleared: remove the message it left. */
export function causeCleared(cause) {
  if (msgCause !== cause) return;
  say("", "");
}

export function fmt(v, digits) {
  return (v === null || v === undefined || Number.isNaN(v)) ? "–" : Number(v).toFixed(digits);
}

export function clock(ms) {
  return new Date(ms).toLocaleTimeString([], {hour12: false});
}

// ---------------------------------------------------------------- units and colours
/** The unit of a record/stream channel (docs/ARCHITECTURE.md). */
export function unitOf(c) {
  if (/^e_/.test(c)) return "µm";
  if (/^(u_|r_|k_[xy]|x_[xy]|y_p|r_p|v_)/.test(c)) return "V";
  if (c === "omega_rpm") return "rpm";
  if (c === "p_inj_bar") return "bar";
  if (c === "phi") return "rad";
  if (/^f_/.test(c)) return "N";
  return "";
}

/** The axis group of channel `c` whose unit is `unit` (one unit per group; V split by role,
 * as on the Live tab: the lumped x/y signals of Eq. 1 and the four valves' own): {key, label}.
 * GROUP_ORDER lists the keys top to bottom. */
export const GROUP_ORDER = ["µm", "V lumped", "V valves", "rpm", "bar", "rad", "N", "1"];
export function groupOf(c, unit) {
  if (unit === "V" && /^(y_p|r_p|v_)/.test(c)) return {key: "V valves", label: "valves, V"};
  if (unit === "V" && /^(u_[xy]|r_[xy]|k_[xy]|x_[xy])$/.test(c)) return {key: "V lumped", label: "x/y, V"};
  return {key: unit, label: unit === "1" ? "flags (1)" : unit};
}

// 20 distinct colours (no repeats within a plot): Tableau 10 then its darker/lighter mates
const PALETTE = ["#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2",
  "#17becf", "#bcbd22", "#7f7f7f", "#0b3d91", "#a50f15", "#00441b", "#b35806", "#3f007d",
  "#543005", "#ae017e", "#006d77", "#6b6b00", "#252525"];
const FIXED = {e_x: 0, e_y: 1, u_x: 2, u_y: 3, r_x: 4, r_y: 5, k_x: 6, k_y: 7,
  y_p1: 0, y_p2: 1, y_p3: 2, y_p4: 3, r_p1: 10, r_p2: 11, r_p3: 12, r_p4: 13};

/** Distinct colours for `names` (one plot): the fixed colour of a live channel when free,
 * else the next unused palette entry. */
export function colours(names) {
  const used = new Set(), out = {};
  for (const n of names) {
    if (n in FIXED && !used.has(FIXED[n])) { out[n] = PALETTE[FIXED[n]]; used.add(FIXED[n]); }
  }
  let k = 0, extra = 0;
  for (const n of names) {
    if (n in out) continue;
    while (k < PALETTE.length && used.has(k)) k++;
    if (k < PALETTE.length) { out[n] = PALETTE[k]; used.add(k); continue; }
    // beyond the palette: hues a golden angle apart, darker on odd steps
    out[n] = "hsl(" + ((extra * 137.508 + 20) % 360).toFixed(1) + ", 70%, " + (extra % 2 ? 30 : 45) + "%)";
    extra++;
  }
  return out;
}

// ---------------------------------------------------------------- plot helpers
export const PLOT_CONFIG = {displaylogo: false, responsive: true, displayModeBar: false};
export const RECORD_CONFIG = {displaylogo: false, responsive: true};

export function layoutBase(title, extra) {
  return Object.assign({
    title: {text: title, font: {size: 13}}, margin: {l: 58, r: 10, t: 30, b: 40},
    // inside the plot's top-left corner: below it, it would sit on the x axis's title
    legend: {orientation: "h", x: 0.01, xanchor: "left", y: 0.99, yanchor: "top",
      bgcolor: "rgba(255,255,255,0.75)", font: {size: 10}}, uirevision: "keep",
  }, extra || {});
}

/** `groups` (list of {unit, label}) as y-axes stacked top to bottom, one per unit, sharing
 * the x axis: returns {axes: layout fields, ref: [yaxis names "y", "y2", ...]}. */
export function stackedAxes(groups, gap) {
  const n = groups.length, g = gap === undefined ? 0.06 : gap;
  const h = (1 - g * (n - 1)) / n, axes = {}, ref = [];
  groups.forEach((grp, i) => {
    const top = 1 - i * (h + g), key = i === 0 ? "yaxis" : "yaxis" + (i + 1);
    axes[key] = {domain: [Math.max(0, top - h), top], title: {text: grp.label, font: {size: 11}},
      zeroline: false, automargin: true};
    if (grp.type) axes[key].type = grp.type;
    ref.push(i === 0 ? "y" : "y" + (i + 1));
  });
  return {axes, ref};
}

// min/max buckets drawn as a band: t0 min, t0 max, t1 max, t1 min, t2 min, t2 max, ...
// (each bucket a vertical stroke from its min to its max, joined end to end: no peak lost,
// no saw-tooth from joining one bucket's max to the next one's min); the buckets from index
// `from` on (default 0), x relative to `t0`
export function band(t, lo, hi, t0, from) {
  const f = from || 0, n = t.length - f, x = new Array(2 * n), y = new Array(2 * n), z = t0 || 0;
  for (let i = 0; i < n; i++) {
    const k = i + f;
    x[2 * i] = x[2 * i + 1] = t[k] - z;
    if (i % 2 === 0) { y[2 * i] = lo[k]; y[2 * i + 1] = hi[k]; } else { y[2 * i] = hi[k]; y[2 * i + 1] = lo[k]; }
  }
  return {x, y};
}
