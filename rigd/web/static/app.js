// rigd console: live view (GET /api/stream, Server-Sent Events), control (POST /api/<cmd>
// with the Bearer token from sessionStorage), runs (GET /api/runs). docs/web.md.
"use strict";

const TRACE_S = 2.0;          // seconds of history in the time traces
const ORBIT_S = 1.0;          // seconds of history in the orbit
const ORBIT_MS = 100;         // orbit redrawn at most 10 times a second,
const TRACES_MS = 200;        // the time traces 5 times (plotly redraws cost the browser CPU;
const TIMING_MS = 1000;       // the stream still brings every bucket)
const POINTS = 10;            // min/max buckets per stream update (50 updates/s)
const CHANNELS = ["e_x", "e_y", "u_x", "u_y", "r_x", "r_y", "k_x", "k_y",
  "y_p1", "y_p2", "y_p3", "y_p4", "r_p1", "r_p2", "r_p3", "r_p4", "k_on"];

// what tests (and curious users) can read: window.rigd
const rigd = window.rigd = {
  updates: 0, renders: 0, orbitRenders: 0, lastSeq: null, cycle: null, mode: "connecting",
  filmGap: 25.0, buf: null, lastStatus: null, histRenders: 0,
};

const $ = (id) => document.getElementById(id);
const PLOT_CONFIG = {displaylogo: false, responsive: true, displayModeBar: false};
const RECORD_CONFIG = {displaylogo: false, responsive: true};
const layoutBase = (title, extra) => Object.assign({
  title: {text: title, font: {size: 13}}, margin: {l: 48, r: 10, t: 30, b: 30},
  legend: {orientation: "h", y: -0.12, font: {size: 10}}, uirevision: "keep",
}, extra || {});

// ---------------------------------------------------------------- messages and API calls
function say(text, kind) {
  const m = $("message");
  m.textContent = String(text).split("\n")[0];
  m.className = "message " + (kind || "");
  m.title = m.textContent;
}

function token() { return sessionStorage.getItem("rigd-token") || ""; }

// Reads need the token too (docs/web.md, Security): every fetch sends it as the
// Authorization header, and login() exchanges it (POST /api/login) for a read-only session
// cookie (HttpOnly, SameSite=Strict) that the EventSource and the report links carry. Nothing
// is fetched before a login succeeded: the page itself holds no rig data.
async function login() {
  if (!token()) return false;
  try {
    const r = await fetch("/api/login", {method: "POST", headers: {"Authorization": "Bearer " + token()}});
    return r.ok;
  } catch (e) {
    return false;
  }
}

async function api(path, body) {
  const opts = {method: body === undefined ? "GET" : "POST", headers: {}};
  if (token()) opts.headers["Authorization"] = "Bearer " + token();
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

async function command(name, body, okText) {
  const r = await api("/api/" + name, body || {});
  if (r.ok) {
    say(okText || (name + ": ok " + JSON.stringify(r.body)), "ok");
  } else {
    const e = String(r.body.error || "failed");
    say((e.startsWith(name + ":") ? e : name + ": " + e) + " (HTTP " + r.status + ")", "error");
  }
  refreshStatus();
  return r;
}

async function fileText(input) {
  const f = input.files && input.files[0];
  return f ? {name: f.name, text: await f.text()} : null;
}

// ---------------------------------------------------------------- controls
function wireControls() {
  $("token").value = token();
  $("token-save").onclick = async () => {
    sessionStorage.setItem("rigd-token", $("token").value.trim());
    if (await login()) {
      say("token kept for this tab (sessionStorage); sent as Authorization: Bearer", "ok");
      start();
    } else {
      say("login: token refused (HTTP 401): use the token rigd web printed at start", "error");
    }
  };
  $("token").addEventListener("keydown", (e) => { if (e.key === "Enter") $("token-save").click(); });
  $("safe").onclick = () => command("safe", {}, "SAFE: safe state latched (reset, then enable, to leave it)");
  $("enable").onclick = () => command("enable", {}, "K∞ enable requested");
  $("disable").onclick = () => command("disable", {}, "K∞ disable requested");
  $("reset").onclick = () => command("reset", {}, "fault reset");
  $("stop").onclick = () => command("stop", {}, "experiment stop requested");
  $("op-set").onclick = () => command("op", {
    omega_rpm: Number($("op-omega").value), p_inj_bar: Number($("op-pinj").value)});
  $("load").onclick = async () => {
    const up = await fileText($("controller-file"));
    const sel = $("controller-select").value;
    if (!up && !sel) { say("load: choose a controller file or upload one", "error"); return; }
    command("load", up ? {upload: up} : {path: sel});
  };
  $("start").onclick = async () => {
    const up = await fileText($("exp-file"));
    const sel = $("exp-select").value;
    if (!up && !sel) { say("start: choose an experiment or upload one", "error"); return; }
    command("start", up ? {upload: up} : {path: sel});
  };
  for (const b of document.querySelectorAll("nav .tab")) {
    b.onclick = () => {
      for (const t of document.querySelectorAll("nav .tab")) t.classList.toggle("active", t === b);
      for (const p of document.querySelectorAll(".panel")) p.classList.toggle("active", p.id === b.dataset.tab);
      if (b.dataset.tab === "runs") loadRuns(); else window.dispatchEvent(new Event("resize"));
    };
  }
  $("runs-refresh").onclick = loadRuns;
}

function fillSelect(sel, items, placeholder) {
  sel.innerHTML = "";
  const o = document.createElement("option");
  o.value = ""; o.textContent = placeholder; sel.appendChild(o);
  for (const it of items) {
    const e = document.createElement("option");
    e.value = it; e.textContent = it; sel.appendChild(e);
  }
}

async function loadFiles() {
  const r = await api("/api/files");
  if (!r.ok) return;
  const cfg = r.body.config || [];
  const exps = cfg.filter((p) => p.includes("/experiments/")).concat(cfg.filter((p) => !p.includes("/experiments/")));
  fillSelect($("exp-select"), exps, "— experiment YAML (config folder) —");
  const ctrls = cfg.filter((p) => /controller|\/k_/i.test(p)).concat(r.body.runs || []);
  fillSelect($("controller-select"), ctrls.length ? ctrls : cfg, "— controller YAML —");
}

// ---------------------------------------------------------------- status line
function fmt(v, digits) {
  return (v === null || v === undefined || Number.isNaN(v)) ? "–" : Number(v).toFixed(digits);
}

function showStatus(s) {
  // s: the stream's status object, or one built from /api/status
  rigd.lastStatus = s;
  if (s.cycle !== undefined && s.cycle !== null) {
    rigd.cycle = s.cycle;
    $("cycle").textContent = String(s.cycle);
  }
  const k = $("kinf");
  k.textContent = s.k_on ? "on" : (s.k_loaded === false ? "off (none loaded)" : "off");
  k.className = "badge " + (s.k_on ? "on" : "off");
  $("omega").textContent = fmt(s.omega_rpm, 0);
  $("pinj").textContent = fmt(s.p_inj_bar, 2);
  if (s.misses !== undefined) $("misses").textContent = String(s.misses);
  const f = s.fault || {};
  const fe = $("fault");
  fe.textContent = f.code ? (f.name + ": " + f.text + " (cycle " + f.seq + ")") : "none";
  fe.className = f.code ? "faulted" : "";
  if (s.experiment) {
    const e = typeof s.experiment === "string" ? {state: s.experiment} : s.experiment;
    $("exp-state").textContent = "experiment: " + (e.state || "?") +
      (e.name ? " " + e.name : "") + (e.total ? " (" + e.done + "/" + e.total + ")" : "") +
      (e.message ? ": " + e.message : "");
  }
  if (s.compute_us || s.lateness_us) rigd.timing = {compute_us: s.compute_us, lateness_us: s.lateness_us};
}

function statusFromCtl(st) {
  const c = st.controller || {}, lf = st.last_frame || {};
  return {cycle: st.seq, k_on: !!c.enabled, k_loaded: !!c.loaded, fault: st.fault,
    omega_rpm: lf.omega_rpm, p_inj_bar: lf.p_inj_bar, misses: st.overruns};
}

async function refreshStatus() {
  const r = await api("/api/status");
  if (r.ok) {
    if (rigd.mode !== "stream") showStatus(statusFromCtl(r.body));
    return r.body;
  }
  if (rigd.mode !== "stream") say("status: " + r.status + ": " + (r.body.error || ""), "error");
  return null;
}

// ---------------------------------------------------------------- live buffers
function newBuffers() {
  const b = {t: []};
  for (const c of CHANNELS) b[c] = {lo: [], hi: []};
  return b;
}

function push(u) {
  const buf = rigd.buf || (rigd.buf = newBuffers());
  const t = u.t || [];
  if (!t.length) return;
  if (rigd.lastT !== undefined && t[0] < rigd.lastT) {   // the loop restarted: start over
    rigd.buf = newBuffers();
    return push(u);
  }
  rigd.lastT = t[t.length - 1];
  for (const v of t) buf.t.push(v);
  for (const c of CHANNELS) {
    const lo = (u.min || {})[c], hi = (u.max || {})[c];
    for (let i = 0; i < t.length; i++) {
      buf[c].lo.push(lo ? lo[i] : null);
      buf[c].hi.push(hi ? hi[i] : null);
    }
  }
  const tmin = rigd.lastT - TRACE_S;
  let cut = 0;
  while (cut < buf.t.length && buf.t[cut] < tmin) cut++;
  if (cut > 0) {
    buf.t.splice(0, cut);
    for (const c of CHANNELS) { buf[c].lo.splice(0, cut); buf[c].hi.splice(0, cut); }
  }
}

// min/max buckets drawn as a band: t0 min, t0 max, t1 max, t1 min, t2 min, t2 max, ...
// (each bucket a vertical stroke from its min to its max, joined end to end: no peak lost,
// no saw-tooth from joining one bucket's max to the next one's min)
function band(t, lo, hi) {
  const x = [], y = [];
  for (let i = 0; i < t.length; i++) {
    x.push(t[i], t[i]);
    if (i % 2 === 0) y.push(lo[i], hi[i]); else y.push(hi[i], lo[i]);
  }
  return {x, y};
}

function envelope(c) {
  const b = rigd.buf;
  return band(b.t, b[c].lo, b[c].hi);
}

function line(c, name, extra) {
  const e = envelope(c);
  return Object.assign({x: e.x, y: e.y, name: name || c, type: "scatter", mode: "lines",
    line: {width: 1}}, extra || {});
}

// ---------------------------------------------------------------- plots
function gapCircle(r) {
  return {type: "circle", xref: "x", yref: "y", x0: -r, y0: -r, x1: r, y1: r,
    line: {color: "#c62828", dash: "dot", width: 1}};
}

function drawOrbit() {
  const b = rigd.buf, x = [], y = [];
  const tmin = (rigd.lastT || 0) - ORBIT_S;
  for (let i = 0; i < b.t.length; i++) {
    if (b.t[i] < tmin) continue;
    const ex = (b.e_x.lo[i] + b.e_x.hi[i]) / 2, ey = (b.e_y.lo[i] + b.e_y.hi[i]) / 2;
    x.push(ex); y.push(ey);
  }
  const g = rigd.filmGap * 1.05;
  Plotly.react("orbit", [
    {x, y, type: "scatter", mode: "lines", name: "orbit (last " + ORBIT_S + " s)", line: {width: 1}},
    {x: x.slice(-1), y: y.slice(-1), type: "scatter", mode: "markers", name: "now",
      marker: {size: 8, color: "#c62828"}},
  ], layoutBase("orbit e_y vs e_x, µm (film gap " + rigd.filmGap + " µm dotted)", {
    xaxis: {range: [-g, g], title: {text: "e_x, µm"}, zeroline: false},
    yaxis: {range: [-g, g], title: {text: "e_y, µm"}, scaleanchor: "x", zeroline: false},
    shapes: [gapCircle(rigd.filmGap)], showlegend: false,
  }), PLOT_CONFIG);
  rigd.orbitRenders++;
}

function drawTraces() {
  const tl = {title: {text: ""}};        // time in the titles: the legend sits below
  Plotly.react("trace-p", [line("e_x", "e_x"), line("e_y", "e_y")],
    layoutBase("shaft displacement p = (e_x, e_y), µm vs t, s", {xaxis: tl}), PLOT_CONFIG);
  Plotly.react("trace-u", [line("u_x", "u_x"), line("u_y", "u_y"), line("r_x", "r_x"),
    line("r_y", "r_y"), line("k_x", "K∞ k_x", {line: {width: 1, dash: "dot"}}),
    line("k_y", "K∞ k_y", {line: {width: 1, dash: "dot"}})],
  layoutBase("lumped u, references r, K∞ output k, V vs t, s", {xaxis: tl}), PLOT_CONFIG);
  const v = [];
  for (let i = 1; i <= 4; i++) v.push(line("y_p" + i, "y_p" + i));
  for (let i = 1; i <= 4; i++) v.push(line("r_p" + i, "r_p" + i, {line: {width: 1, dash: "dot"}}));
  Plotly.react("trace-valves", v, layoutBase("valve positions y_p,i, references r_p,i, V vs t, s",
    {xaxis: tl}), PLOT_CONFIG);
}

function drawTiming() {
  const t = rigd.timing || {}, keys = ["p50", "p99", "p999", "max"];
  const bars = [];
  for (const [name, d] of [["compute", t.compute_us], ["lateness", t.lateness_us]]) {
    if (!d) continue;
    bars.push({x: keys, y: keys.map((k) => d[k]), type: "bar", name: name + " µs"});
  }
  const misses = rigd.lastStatus && rigd.lastStatus.misses;
  Plotly.react("timing", bars, layoutBase("cycle time percentiles, µs (misses: " +
    (misses === undefined ? "–" : misses) + ")", {barmode: "group"}), PLOT_CONFIG);
}

// the cycle-time histogram: `timing`'s coarse histograms (the daemon's 100 ns bins summed to
// at most 32 bars), fetched with the same period as the percentiles
async function drawHistogram() {
  const r = await api("/api/timing");
  const h = r.ok && r.body && r.body.histogram_us;
  if (!h) return;
  const bars = [];
  for (const [name, d] of [["compute", h.compute], ["lateness", h.lateness]]) {
    if (!d || !d.counts.length) continue;
    const mid = d.counts.map((_, i) => 0.5 * (d.edges_us[i] + d.edges_us[i + 1]));
    bars.push({x: mid, y: d.counts, type: "bar", name: name + (d.overflow ? " (+" +
      d.overflow + " beyond)" : ""), opacity: 0.7});
  }
  Plotly.react("timing-hist", bars, layoutBase("cycle-time histogram, cycles vs µs",
    {barmode: "overlay", yaxis: {type: "log"}}), PLOT_CONFIG);
  rigd.histRenders++;
}

let dirty = {orbit: false, traces: false}, lastOrbit = 0, lastTraces = 0, lastTiming = 0;
function markDirty() { dirty.orbit = dirty.traces = true; }
function renderLoop(now) {
  if (rigd.buf && $("live").classList.contains("active")) {
    if (dirty.orbit && now - lastOrbit >= ORBIT_MS) {
      dirty.orbit = false; lastOrbit = now; drawOrbit();
    } else if (dirty.traces && now - lastTraces >= TRACES_MS) {
      dirty.traces = false; lastTraces = now; drawTraces(); rigd.renders++;
    } else if (now - lastTiming >= TIMING_MS) {
      lastTiming = now; drawTiming(); drawHistogram();
    }
  }
  requestAnimationFrame(renderLoop);
}

// ---------------------------------------------------------------- stream / fallback polling
let poller = null;
function startPolling(reason) {
  rigd.mode = "polling";
  $("stream-state").textContent = "live stream unavailable (" + reason + "): polling status";
  if (poller) return;
  poller = setInterval(async () => {
    const st = await refreshStatus();
    if (!st || !st.last_frame) return;
    const lf = st.last_frame, tt = st.t_s;
    const u = {t: [tt], min: {}, max: {}};
    for (const c of CHANNELS) { if (c in lf) { u.min[c] = [lf[c]]; u.max[c] = [lf[c]]; } }
    push(u);
    markDirty();
  }, 250);
}

function connectStream() {
  const es = new EventSource("/api/stream?rate_hz=50&points=" + POINTS + "&channels=" + CHANNELS.join(","));
  es.addEventListener("subscribed", (e) => {
    rigd.mode = "stream";
    rigd.subscription = JSON.parse(e.data);
    $("stream-state").textContent = "live " + rigd.subscription.rate_hz + " Hz";
    if (poller) { clearInterval(poller); poller = null; }
  });
  es.onmessage = (e) => {
    const u = JSON.parse(e.data);
    rigd.updates++;
    rigd.lastSeq = u.seq;
    if (u.status) showStatus(Object.assign({cycle: u.seq}, u.status));
    push(u);
    markDirty();
  };
  es.addEventListener("error", (e) => {
    if (e.data) {           // the relay's one-line reason: the stream has ended
      es.close();
      startPolling(JSON.parse(e.data).error);
      setTimeout(connectStream, 5000);
    } else if (es.readyState === EventSource.CLOSED) {
      startPolling("rigd web not reachable");
    }
  });
}

// ---------------------------------------------------------------- runs
function cell(tr, text) {
  const td = document.createElement("td");
  if (text instanceof Node) td.appendChild(text); else td.textContent = text;
  tr.appendChild(td);
  return td;
}

async function loadRuns() {
  const r = await api("/api/runs");
  const tb = document.querySelector("#runs-table tbody");
  tb.innerHTML = "";
  if (!r.ok) { say("runs: " + (r.body.error || r.status), "error"); return; }
  for (const run of r.body) {
    const tr = document.createElement("tr");
    tr.dataset.run = run.name;
    cell(tr, run.name);
    cell(tr, run.error ? "(" + run.error + ")" : (run.kind || "–"));
    const op = run.operating_point;
    cell(tr, op ? fmt(op.omega_rpm, 0) + " rpm / " + fmt(op.p_inj_bar, 2) + " bar" : "–");
    cell(tr, run.source || "–");
    cell(tr, run.duration_s === null || run.duration_s === undefined ? "–" : fmt(run.duration_s, 1) + " s");
    cell(tr, run.status || "–");
    const recs = document.createElement("span");
    for (const f of run.records || []) {
      const b = document.createElement("button");
      b.textContent = f; b.className = "open-record";
      b.onclick = () => openRecord(run.name, f);
      recs.appendChild(b);
    }
    cell(tr, recs);
    const pages = document.createElement("span");
    for (const p of run.pages || []) {
      const a = document.createElement("a");
      a.href = "/runs/" + encodeURIComponent(run.name) + "/" + p.split("/").map(encodeURIComponent).join("/");
      a.textContent = p; a.target = "_blank"; a.rel = "noopener";
      pages.appendChild(a);
    }
    cell(tr, pages);
    tb.appendChild(tr);
  }
}

let currentRecord = null;
async function openRecord(run, file, t0, t1) {
  currentRecord = {run, file};
  let q = "?points=2000";
  if (t0 !== undefined) q += "&t0=" + t0 + "&t1=" + t1;
  const path = "/api/runs/" + encodeURIComponent(run) + "/" + file.split("/").map(encodeURIComponent).join("/");
  const r = await api(path + q);
  if (!r.ok) { say("record: " + (r.body.error || r.status), "error"); return; }
  const v = r.body, traces = [];
  for (const [c, d] of Object.entries(v.channels)) {
    if (c === "seq") continue;
    const {x, y} = band(v.t_s, d.min, d.max);
    traces.push({x, y, name: c + (v.units[c] ? " [" + v.units[c] + "]" : ""), type: "scatter",
      mode: "lines", line: {width: 1}, visible: /^(e_|u_|r_x|r_y)/.test(c) ? true : "legendonly"});
  }
  $("record-title").textContent = run + "/" + file + ": " + v.n + " samples at " + v.fs_hz +
    " Hz" + (v.decimated ? ", min/max decimated to " + v.t_s.length + " buckets (zoom for detail)" : "");
  const layout = layoutBase(run + "/" + file, {xaxis: {title: {text: "t, s"}}, uirevision: file});
  if (t0 !== undefined) layout.xaxis.range = [t0, t1];
  await Plotly.react("record-plot", traces, layout, RECORD_CONFIG);
  const el = $("record-plot");
  if (!el.dataset.wired) {
    el.dataset.wired = "1";
    el.on("plotly_relayout", (ev) => {
      if (!currentRecord) return;
      if ("xaxis.range[0]" in ev) {
        openRecord(currentRecord.run, currentRecord.file, ev["xaxis.range[0]"], ev["xaxis.range[1]"]);
      } else if (ev["xaxis.autorange"]) {
        openRecord(currentRecord.run, currentRecord.file);
      }
    });
  }
}

// ---------------------------------------------------------------- start
let started = false;
async function main() {
  wireControls();
  if (await login()) start();
  else say("enter the token printed by rigd web (or its read-only token) and press Keep", "error");
}

async function start() {
  if (started) return;
  started = true;
  const c = await api("/api/console");
  if (c.ok && c.body.film_gap_um) rigd.filmGap = c.body.film_gap_um;
  rigd.buf = newBuffers();
  loadFiles();
  await refreshStatus();
  setInterval(async () => {          // slow things not in the stream's status
    const e = await api("/api/experiment");
    if (e.ok) showStatus(Object.assign({}, rigd.lastStatus || {}, {experiment: e.body}));
  }, 2000);
  connectStream();
  requestAnimationFrame(renderLoop);
}

main();
