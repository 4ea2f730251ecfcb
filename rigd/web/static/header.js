// rigd console, state at a glance: the header (cycle, K∞, Ω, P_I, misses, fault), the fault
// banner with its reset button, the "disconnected — values are stale" state that greys the
// header, and the operating-point fields following the daemon's set-point. docs/web.md.
import {$, causeCleared, clock, fmt, rigd} from "./core.js";

/** Without a good status for this long the header's values are stale, ms. */
export const STALE_MS = 3000;

function setText(id, text) {
  const e = $(id);
  if (e.textContent !== text) e.textContent = text;
}

/** The header is repainted at most this often, ms (plots.js paints it, in the frames of the
 * orbit and the traces): the stream brings 10 statuses a second, and each text write costs a
 * style and layout pass; 5 a second is what an eye reads of a changing number. */
export const HEADER_MS = 200;
let pending = null, pendingHook = () => {};

/** `hook()` is called when a status waits to be shown (plots.js wake). */
export function onHeaderPending(hook) { pendingHook = hook; }

/** Take one status (the stream's `status` object, or one built from GET /api/status): kept at
 * once (rigd.lastStatus, the staleness clock), shown in the header by the next paintHeader
 * (the newest status then; a latched fault stays latched in it). */
export function showStatus(s) {
  rigd.lastStatus = s;
  rigd.lastGood = Date.now();
  if (rigd.stale) setStale(false);
  if (s.cycle !== undefined && s.cycle !== null) rigd.cycle = s.cycle;
  if (s.compute_us || s.lateness_us) rigd.timing = {compute_us: s.compute_us, lateness_us: s.lateness_us};
  pending = s;
  pendingHook();
}

export function headerPending() { return pending !== null; }

/** Show the newest status taken in the header (plots.js, in an animation frame). */
export function paintHeader() {
  const s = pending;
  if (s === null) return;
  pending = null;
  if (s.cycle !== undefined && s.cycle !== null) setText("cycle", String(s.cycle));
  setText("kinf", s.k_on ? "on" : (s.k_loaded === false ? "off (none loaded)" : "off"));
  setClass("kinf", "badge " + (s.k_on ? "on" : "off"));
  setText("omega", fmt(s.omega_rpm, 0));
  setText("pinj", fmt(s.p_inj_bar, 2));
  if (s.misses !== undefined && s.misses !== null) setText("misses", String(s.misses));
  showFault(s.fault || {});
  if (s.experiment) showExperiment(s.experiment);
  followSetPoint(s);
  rigd.headerPaints = (rigd.headerPaints || 0) + 1;
}

function setClass(id, cls) {
  const e = $(id);
  if (e.className !== cls) e.className = cls;
}

function showFault(f) {
  const latched = !!f.code;
  // the header names it (the banner below says it whole)
  setText("fault", latched ? f.name + " (cycle " + f.seq + ")" : "none");
  if ($("fault").title !== (latched ? f.text : "")) $("fault").title = latched ? f.text : "";
  setClass("fault", latched ? "faulted" : "");
  const b = $("fault-banner");
  if (latched) {
    setText("fault-text", "FAULT " + f.name + " latched at cycle " + f.seq + ": " + f.text +
      " — the rig is in the safe state (K∞ off, excitation off)");
  }
  if (b.hidden !== !latched) b.hidden = !latched;
  if (!latched) causeCleared("fault");
}

export function showExperiment(exp) {
  const e = typeof exp === "string" ? {state: exp} : exp;
  const prev = rigd.lastExperiment || {};
  // the stream's status carries the state only: keep the rest of the last full answer
  const full = (e.name === undefined && prev.state === e.state) ? prev : e;
  rigd.lastExperiment = full;
  const f = full.fault && full.fault.name ? " (fault " + full.fault.name + ": " + full.fault.text + ")" : "";
  setText("exp-state", "experiment: " + (full.state || "?") + (full.name ? " " + full.name : "") +
    (full.total ? " (" + full.done + "/" + full.total + ")" : "") +
    (full.message ? ": " + full.message : "") + f);
}

/** Grey the header and say since when its values are stale (or undo that). */
export function setStale(stale, reason) {
  rigd.stale = stale;
  document.body.classList.toggle("stale", stale);
  const b = $("stale-banner");
  if (stale) {
    const last = rigd.lastGood ? "last at " + clock(rigd.lastGood) : "never received";
    const text = "disconnected — values are stale (" + last + ")" + (reason ? ": " + reason : "");
    // one line whatever the reason's length (cut with an ellipsis, whole in the tooltip): a
    // banner that wrapped for one reason and not another moved every control below it while
    // the operator (or a test's click) was aiming at one
    setText("stale-text", text);
    if ($("stale-text").title !== text) $("stale-text").title = text;
  } else {
    causeCleared("conn");
  }
  b.hidden = !stale;
}

/** The staleness watchdog: called a few times a second. */
export function checkStale(reason) {
  if (Date.now() - rigd.lastGood > STALE_MS) setStale(true, reason);
}

// ---------------------------------------------------------------- operating point fields
// The fields show the daemon's set-point (status.set_point: what `op` last applied; the
// measured Ω and P_I follow it at the rig's pace) until the operator types into one; after a
// set (or on "revert") they follow the set-point again. Without a known set-point (a rig
// before its first op) they show the measured values, and say so.
function followSetPoint(s) {
  const sp = s.set_point, live = sp && sp.omega_rpm !== undefined && sp.omega_rpm !== null;
  const om = live ? sp.omega_rpm : s.omega_rpm, pi = live ? sp.p_inj_bar : s.p_inj_bar;
  rigd.setPoint = live ? {omega_rpm: om, p_inj_bar: pi, source: sp.source} : null;
  setText("op-now", (live ? "set-point " + fmt(om, 0) + " rpm / " + fmt(pi, 2) + " bar" +
    (sp.source === "config" ? " (configured)" : "") : "no set-point known") +
    " · measured " + fmt(s.omega_rpm, 0) + " rpm / " + fmt(s.p_inj_bar, 2) + " bar");
  // just after a set the fields hold the applied value until a status carries it (the
  // stream's status may be a snapshot from before the daemon's answer)
  const held = rigd.opApplied;
  if (held && (Date.now() > held.until || (live && om === held.omega_rpm && pi === held.p_inj_bar))) {
    rigd.opApplied = null;
  } else if (held) {
    return;
  }
  for (const [id, v, d] of [["op-omega", om, 0], ["op-pinj", pi, 2]]) {
    const el = $(id);
    if (el.dataset.edited || document.activeElement === el || v === null || v === undefined) continue;
    const text = Number(v).toFixed(d);
    if (el.value !== text) el.value = text;
  }
}

export function markEdited(el, edited) {
  if (edited) el.dataset.edited = "1"; else delete el.dataset.edited;
  el.classList.toggle("edited", !!edited);
}
