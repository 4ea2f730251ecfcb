// rigd console, the live data: the stream subscription (GET /api/stream, Server-Sent Events)
// and its fallback (polling GET /api/status), the trace buffers (cleared, visibly, when the
// daemon restarts or the stream has a gap), the daemon's identity, the trends of the last
// minutes and the scope's pause and trigger. docs/web.md.
import {$, api, causeCleared, clock, rigd} from "./core.js";
import {checkStale, showExperiment, showStatus} from "./header.js";

export const TRACE_S = 2.0;   // seconds of history in the time traces
export const ORBIT_S = 1.0;   // seconds of history in the orbit
const KEEP_S = TRACE_S + 0.5; // kept in the buffers (a trigger's window is centred)
const GAP_S = 0.25;           // a jump of loop time this long between updates is a gap
export const TREND_S = 300;   // trends: the last 5 minutes
const TREND_MS = 500;         // one trend sample every 0.5 s
// the subscription (bench/web.py asks for exactly this): 20 min/max buckets per update at 10
// updates/s = 200 buckets/s, 400 over the 2 s traces — about one per pixel column of a plot,
// so the server's decimation leaves nothing for the page to thin out. 10 updates/s: as often
// as the header is repainted (header.js HEADER_MS) and twice the traces' redraws; at 50/s the
// 40 extra messages a second (each a task of the renderer: IPC, event, JSON.parse) were
// drawn by nobody
export const RATE_HZ = 10;
export const POINTS = 20;
// another subscription may be asked in the page's address, ?rate_hz=N (1–50 updates/s) and
// ?points=N (1–200 buckets per update) — e.g. bench/console.py measures SAFE with the page
// taking 50 updates/s; anything else (missing, not a number, out of range) is the default
const QUERY = new URLSearchParams(location.search);
function queryNumber(name, lo, hi, dflt) {
  const raw = QUERY.get(name);
  const v = raw === null || raw.trim() === "" ? NaN : Number(raw);
  return Number.isFinite(v) && v >= lo && v <= hi ? v : dflt;
}
export const STREAM_RATE_HZ = queryNumber("rate_hz", 1, 50, RATE_HZ);
export const STREAM_POINTS = Math.round(queryNumber("points", 1, 200, POINTS));
export const CHANNELS = ["e_x", "e_y", "u_x", "u_y", "r_x", "r_y", "k_x", "k_y",
  "y_p1", "y_p2", "y_p3", "y_p4", "r_p1", "r_p2", "r_p3", "r_p4", "k_on"];

let dirtyHook = () => {};
/** `hook()` is called whenever new data wants drawing. */
export function onDirty(hook) { dirtyHook = hook; }

// ---------------------------------------------------------------- buffers
function newBuffers() {
  const b = {t: []};
  for (const c of CHANNELS) b[c] = {lo: [], hi: []};
  return b;
}
rigd.buf = newBuffers();

/** Start the traces over (a restart or a gap): the old daemon's or the old run's points are
 * never joined to the new ones; the reason is shown above the plots. */
export function restartTraces(reason) {
  rigd.buf = newBuffers();
  rigd.lastT = undefined;
  rigd.epoch++;
  rigd.restarts.push({at: Date.now(), reason});
  // a trigger that fired stays fired: its window is cut from what the new buffers hold
  $("live-note").textContent = "traces restarted at " + clock(Date.now()) + ": " + reason;
  $("live-note").className = "note warn";
}

/** Append one stream update `u` (t, min, max) to the buffers. */
export function push(u) {
  const t = u.t || [];
  if (!t.length) return;
  if (rigd.lastT !== undefined) {
    if (t[0] < rigd.lastT) {
      restartTraces("loop time went back from " + rigd.lastT.toFixed(3) + " s to " +
        t[0].toFixed(3) + " s (the daemon restarted)");
      fetchIdentity();
    } else if (u.dropped > 0 || t[0] - rigd.lastT > GAP_S) {
      restartTraces("gap in the stream from " + rigd.lastT.toFixed(3) + " s to " +
        t[0].toFixed(3) + " s" + (u.dropped ? " (" + u.dropped + " frames dropped)" : ""));
    }
  }
  const buf = rigd.buf, first = buf.t.length;
  for (const v of t) buf.t.push(v);
  for (const c of CHANNELS) {
    const lo = (u.min || {})[c], hi = (u.max || {})[c], bl = buf[c].lo, bh = buf[c].hi;
    for (let i = 0; i < t.length; i++) {
      bl.push(lo ? lo[i] : null);
      bh.push(hi ? hi[i] : null);
    }
  }
  rigd.lastT = t[t.length - 1];
  const tmin = rigd.lastT - KEEP_S;
  let cut = 0;
  while (cut < buf.t.length && buf.t[cut] < tmin) cut++;
  if (cut > 0) {
    buf.t.splice(0, cut);
    for (const c of CHANNELS) { buf[c].lo.splice(0, cut); buf[c].hi.splice(0, cut); }
  }
  levelTrigger(Math.max(1, first - cut));
  settleTrigger();
}

// ---------------------------------------------------------------- the daemon's identity
export async function fetchIdentity() {
  const r = await api("/api/ping");
  if (!r.ok) return;
  const d = {pid: r.body.pid, version: r.body.version,
    started_ms: Date.now() - 1000 * (r.body.uptime_s || 0)};
  const old = rigd.daemon;
  rigd.daemon = d;
  if (old && old.pid !== d.pid) {
    if (rigd.buf.t.length) restartTraces("the daemon restarted (pid " + old.pid + " → " + d.pid + ")");
    $("live-note").textContent = "daemon restarted at " + clock(d.started_ms) + " (pid " +
      old.pid + " → " + d.pid + "): traces started over";
    $("live-note").className = "note warn";
  }
  $("daemon-id").textContent = "daemon pid " + d.pid + " (up since " + clock(d.started_ms) + ")";
}

/** `daemon pid N · loop t a–b s`: what every live plot carries. */
export function identity(t0, t1) {
  const d = rigd.daemon;
  return (d ? "daemon pid " + d.pid : "daemon ?") + " · loop t " +
    (t0 === undefined ? "–" : t0.toFixed(3) + "–" + t1.toFixed(3) + " s");
}

// ---------------------------------------------------------------- trends
export const trend = {wall: [], omega: [], pinj: [], missRate: [], faults: []};
let lastTrend = {wall: 0, misses: null, faultCode: 0};

function sampleTrend(s) {
  const now = Date.now();
  const f = (s.fault || {}).code || 0;
  if (f && !lastTrend.faultCode) trend.faults.push({wall: now, at: clock(now), name: s.fault.name, text: s.fault.text});
  lastTrend.faultCode = f;
  if (now - lastTrend.wall < TREND_MS) return;
  const dt = (now - lastTrend.wall) / 1000;
  const m = s.misses;
  trend.wall.push(now);
  trend.omega.push(s.omega_rpm);
  trend.pinj.push(s.p_inj_bar);
  trend.missRate.push(lastTrend.misses === null || m === null || m === undefined || m < lastTrend.misses
    ? null : (m - lastTrend.misses) / dt);
  lastTrend.wall = now;
  lastTrend.misses = m === undefined ? null : m;
  const cut = trend.wall.findIndex((w) => w >= now - TREND_S * 1000);
  if (cut > 0) for (const k of ["wall", "omega", "pinj", "missRate"]) trend[k].splice(0, cut);
  while (trend.faults.length && trend.faults[0].wall < now - TREND_S * 1000) trend.faults.shift();
  rigd.trendDirty = true;
}

// ---------------------------------------------------------------- pause and trigger
// rigd.view: what the traces show — null: live (the last TRACE_S s, x = t - now); else a
// frozen copy {buf, t0, label} (pause: x = t - the pause time; trigger: x = t - its time).
rigd.view = null;

function snapshot(ta, tb) {
  const b = rigd.buf, out = {t: []};
  for (const c of CHANNELS) out[c] = {lo: [], hi: []};
  for (let i = 0; i < b.t.length; i++) {
    if (b.t[i] < ta || b.t[i] > tb) continue;
    out.t.push(b.t[i]);
    for (const c of CHANNELS) { out[c].lo.push(b[c].lo[i]); out[c].hi.push(b[c].hi[i]); }
  }
  return out;
}

export function pause(on) {
  rigd.paused = on;
  if (on && rigd.lastT !== undefined) {
    rigd.view = {buf: snapshot(rigd.lastT - TRACE_S, rigd.lastT), t0: rigd.lastT,
      label: "PAUSED at loop t " + rigd.lastT.toFixed(3) + " s"};
  } else if (!on) {
    rigd.view = null;
    if (rigd.trigger) rigd.trigger.state = rigd.trigger.mode === "free" ? "off" : "armed";
  }
  $("pause").textContent = on ? "resume" : "pause";
  $("scope-state").textContent = on ? rigd.view && rigd.view.label || "paused" : scopeIdle();
  dirtyHook();
}

function scopeIdle() {
  const tr = rigd.trigger;
  return !tr || tr.mode === "free" ? "live (free running)" : "armed: " + describe(tr);
}

function describe(tr) {
  if (tr.mode === "level") return tr.chan + " " + tr.edge + " through " + tr.level;
  if (tr.mode === "fault") return "a fault latching";
  return "an experiment starting";
}

/** Arm the trigger from the page's fields (mode free disarms). Returns an error text or "". */
export function armTrigger() {
  const mode = $("trig-mode").value;
  const tr = {mode, chan: $("trig-chan").value, edge: $("trig-edge").value, state: "armed"};
  if (mode === "level") {
    const v = $("trig-level").value.trim();
    if (!/^[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$/.test(v)) return "trigger level: a number is required, got '" + v + "'";
    tr.level = Number(v);
  }
  if (mode === "free") tr.state = "off";
  rigd.trigger = tr;
  if (rigd.paused) pause(false);
  $("scope-state").textContent = scopeIdle();
  return "";
}

function fire(t, why) {
  const tr = rigd.trigger;
  tr.state = "waiting";
  tr.t = t;
  tr.why = why;
  $("scope-state").textContent = "triggered at loop t " + t.toFixed(4) + " s (" + why + "): filling…";
}

function levelTrigger(from) {
  const tr = rigd.trigger;
  if (!tr || tr.state !== "armed" || tr.mode !== "level") return;
  const b = rigd.buf, c = b[tr.chan];
  if (!c) return;
  for (let i = from; i < b.t.length; i++) {
    const rising = tr.edge === "rising";
    const hit = rising ? (c.hi[i - 1] < tr.level && c.hi[i] >= tr.level)
      : (c.lo[i - 1] > tr.level && c.lo[i] <= tr.level);
    if (hit) { fire(b.t[i], tr.chan + " " + tr.edge + " through " + tr.level); return; }
  }
}

function eventTrigger(s, seqNow) {
  const tr = rigd.trigger;
  if (!tr || tr.state !== "armed") return;
  const f = s.fault || {}, prev = rigd.prevStatus || {};
  if (tr.mode === "fault" && f.code && !(prev.fault || {}).code) {
    fire((f.seq || seqNow) / rigd.fs, "fault " + f.name);
  }
  const exp = typeof s.experiment === "string" ? s.experiment : (s.experiment || {}).state;
  const pexp = typeof prev.experiment === "string" ? prev.experiment : (prev.experiment || {}).state;
  if (tr.mode === "experiment" && exp === "running" && pexp !== "running") {
    fire(seqNow / rigd.fs, "experiment started");
  }
}

function settleTrigger() {
  const tr = rigd.trigger;
  if (!tr || tr.state !== "waiting" || rigd.lastT < tr.t + TRACE_S / 2) return;
  tr.state = "done";
  rigd.paused = true;
  rigd.view = {buf: snapshot(tr.t - TRACE_S / 2, tr.t + TRACE_S / 2), t0: tr.t,
    label: "TRIGGERED at loop t " + tr.t.toFixed(4) + " s: " + tr.why + " (x = 0; resume re-arms)"};
  $("pause").textContent = "resume";
  $("scope-state").textContent = rigd.view.label;
  dirtyHook();
}

// ---------------------------------------------------------------- stream / fallback polling
function statusFromCtl(st) {
  const c = st.controller || {}, lf = st.last_frame || {};
  return {cycle: st.seq, k_on: !!c.enabled, k_loaded: !!c.loaded, fault: st.fault,
    omega_rpm: lf.omega_rpm, p_inj_bar: lf.p_inj_bar, set_point: st.set_point, misses: st.overruns};
}

function takeStatus(s, seqNow) {
  showStatus(s);
  eventTrigger(s, seqNow);
  sampleTrend(s);
  rigd.prevStatus = s;
}

/** GET /api/status into the header (when the stream is not live); returns its body or null.
 * An answer clears a "not reachable" message (cause "conn") unless `keepConn` (a command's
 * own follow-up: its error is shown at least until the next read). */
export async function refreshStatus(keepConn) {
  const r = await api("/api/status");
  rigd.daemonUp = r.ok;
  if (r.ok) {
    if (rigd.mode !== "stream") takeStatus(statusFromCtl(r.body), r.body.seq);
    if (keepConn !== true) causeCleared("conn");
    return r.body;
  }
  // the stale banner's reason: this read's (the stream's own reason, worded otherwise, is in
  // the header's tooltip: two sources taking turns made the banner's text flap)
  rigd.lastError = r.status ? r.status + ": " + (r.body.error || "") : (r.body.error || "");
  return null;
}

let poller = null, es = null, retryMs = 1000;
function startPolling(reason) {
  rigd.mode = "polling";
  rigd.streamError = reason;
  // short in the header (it must not wrap the SAFE button away); the reason in its tooltip
  // and, once the status is stale too, in the stale banner
  $("stream-state").textContent = "no live stream: polling status, traces stopped";
  $("stream-state").title = "live stream unavailable: " + reason;
  if (poller) return;
  poller = setInterval(() => refreshStatus(), 500);
}

export function connectStream() {
  es = new EventSource("/api/stream?rate_hz=" + STREAM_RATE_HZ + "&points=" + STREAM_POINTS +
    "&channels=" + CHANNELS.join(","));
  es.addEventListener("subscribed", (e) => {
    rigd.mode = "stream";
    rigd.daemonUp = true;
    rigd.subscription = JSON.parse(e.data);
    if (rigd.subscription.fs_hz) rigd.fs = rigd.subscription.fs_hz;
    $("stream-state").textContent = "live " + rigd.subscription.rate_hz + " Hz";
    $("stream-state").title = "";
    retryMs = 1000;
    causeCleared("conn");     // the daemon streams again: a "not reachable" message is over
    if (poller) { clearInterval(poller); poller = null; }
    fetchIdentity();
  });
  es.onmessage = (e) => {
    const u = JSON.parse(e.data);
    rigd.updates++;
    // the server decimates: at most STREAM_POINTS min/max buckets per update, whatever the frames
    rigd.maxBuckets = Math.max(rigd.maxBuckets || 0, (u.t || []).length);
    rigd.lastSeq = u.seq;
    rigd.lastWallNs = u.wall_ns;
    if (u.status) takeStatus(Object.assign({cycle: u.seq}, u.status), u.seq);
    push(u);
    dirtyHook();
  };
  es.addEventListener("error", (e) => {
    rigd.daemonUp = false;  // until a status read or a subscription answers again
    if (e.data) {           // the relay's one-line reason: the stream has ended
      es.close();
      startPolling(JSON.parse(e.data).error);
      setTimeout(connectStream, retryMs);
      retryMs = Math.min(2 * retryMs, 5000);
    } else if (es.readyState === EventSource.CLOSED) {
      startPolling("rigd web not reachable");
      setTimeout(connectStream, 5000);
    } else {
      startPolling("rigd web not reachable");   // the browser reconnects by itself
    }
  });
}

/** The slow things not in the stream's status, and the staleness watchdog. While the daemon
 * does not answer (rigd.daemonUp false) only the status is polled — what the stale state
 * needs, its reason and the way back — not the experiment, nor the timing (plots.js). */
export function startWatch() {
  setInterval(async () => {
    if (!rigd.daemonUp) return;
    const e = await api("/api/experiment");
    if (e.ok) showExperiment(e.body);
  }, 2000);
  setInterval(() => checkStale(rigd.lastError || rigd.streamError), 250);
}
