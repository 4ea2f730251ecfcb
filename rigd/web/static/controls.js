// rigd console, the controls: SAFE (sent on the press, before anything else), K∞, the
// controller and experiment choosers, the operating-point form (checked here and by the
// server; the applied value confirmed), the scope's pause/trigger/orbit buttons. docs/web.md.
import {$, api, causeCleared, fmt, rigd, say, token} from "./core.js";
import {markEdited} from "./header.js";
import {CHANNELS, armTrigger, pause, refreshStatus} from "./live.js";
import {redrawTraces, setOrbitScale} from "./plots.js";
import {loadRuns} from "./runs.js";

// the Runs tab's listing is re-read this often while it is shown, ms
const RUNS_POLL_MS = 2000;

/** POST /api/<name>; the message says the outcome (errors: the server's one line). */
export async function command(name, body, okText) {
  const r = await api("/api/" + name, body || {});
  if (r.ok) {
    say(typeof okText === "function" ? okText(r.body) : okText || (name + ": ok"), "ok");
  } else {
    const e = String(r.body.error || "failed");
    // a refusal because of a latched fault goes once the fault is reset; "not reachable"
    // (SAFE's too) once the daemon answers again: from then on the header, not an old
    // error, says whether the rig is safe (fault: operator_safe, or none)
    const cause = r.status === 409 && /fault/i.test(e) ? "fault"
      : (r.status === 503 || r.status === 0) ? "conn" : null;
    say((e.startsWith(name + ":") ? e : name + ": " + e) + " (HTTP " + r.status + ")", "error", cause);
  }
  refreshStatus(true);
  return r;
}

// ---------------------------------------------------------------- SAFE
// Sent from `pointerdown` (before the click's own dispatch and before any drawing work the
// page has queued). The `click` that follows a pointer press is the same press and sends
// nothing; a click with `detail` 0 (Enter/Space on the focused button, or a script) had no
// pointerdown, and sends it. Every press sends: no time window that could swallow an
// operator's second press (a 500 ms window did, when the first SAFE failed at once).
function sendSafe() {
  rigd.safeClicks.push({wall_ms: performance.timeOrigin + performance.now(), seq: rigd.lastSeq, wall_ns: rigd.lastWallNs});
  command("safe", {}, "SAFE: safe state latched (reset, then enable, to leave it)");
}

// ---------------------------------------------------------------- operating point
const NUMBER = /^[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$/;

/** The number in field `id`, or throws a one-line reason naming the field. */
function numberField(id, label, unit) {
  const el = $(id), v = el.value.trim();
  if (!NUMBER.test(v)) {
    el.classList.add("invalid");
    throw new Error("op: " + label + ": a number in " + unit + " is required, got " + (v ? "'" + v + "'" : "an empty field"));
  }
  el.classList.remove("invalid");
  return Number(v);
}

async function setOperatingPoint() {
  let omega, pinj;
  try {
    omega = numberField("op-omega", "Ω", "rpm");
    pinj = numberField("op-pinj", "P_I", "bar");
  } catch (e) {
    say(e.message + " (nothing sent)", "error");
    return;
  }
  const r = await command("op", {omega_rpm: omega, p_inj_bar: pinj}, (res) =>
    "op: applied Ω = " + fmt(res.omega_rpm, 0) + " rpm, P_I = " + fmt(res.p_inj_bar, 2) +
    " bar (the rig follows at its own pace)");
  if (!r.ok) return;
  // the daemon answered once the loop applied it: its reply is the set-point now
  rigd.opApplied = {omega_rpm: r.body.omega_rpm, p_inj_bar: r.body.p_inj_bar, until: Date.now() + 3000};
  for (const [id, v, d] of [["op-omega", r.body.omega_rpm, 0], ["op-pinj", r.body.p_inj_bar, 2]]) {
    markEdited($(id), false);
    $(id).value = fmt(v, d);
  }
}

// ---------------------------------------------------------------- wiring
async function fileText(input) {
  const f = input.files && input.files[0];
  return f ? {name: f.name, text: await f.text()} : null;
}

function fillSelect(sel, items, placeholder) {
  sel.innerHTML = "";
  if (placeholder !== null) {
    const o = document.createElement("option");
    o.value = ""; o.textContent = placeholder; sel.appendChild(o);
  }
  for (const it of items) {
    const e = document.createElement("option");
    e.value = it; e.textContent = it; sel.appendChild(e);
  }
}

export async function loadFiles() {
  const r = await api("/api/files");
  if (!r.ok) return;
  const cfg = r.body.config || [];
  const exps = cfg.filter((p) => p.includes("/experiments/")).concat(cfg.filter((p) => !p.includes("/experiments/")));
  fillSelect($("exp-select"), exps, "— experiment YAML (config folder) —");
  const ctrls = cfg.filter((p) => /controller|\/k_/i.test(p)).concat(r.body.runs || []);
  fillSelect($("controller-select"), ctrls.length ? ctrls : cfg, "— controller YAML —");
}

export function wireControls() {
  $("token").value = token();
  // the token button (login, then start) is wired by app.js
  $("token").addEventListener("keydown", (e) => { if (e.key === "Enter") $("token-save").click(); });
  $("safe").addEventListener("pointerdown", (e) => { if (e.button === 0) sendSafe(); });
  $("safe").addEventListener("click", (e) => { if (e.detail === 0) sendSafe(); });
  $("enable").onclick = () => command("enable", {}, "K∞ enabled");
  $("disable").onclick = () => command("disable", {}, "K∞ disabled");
  const reset = async () => { const r = await command("reset", {}, "fault reset"); if (r.ok) causeCleared("fault"); };
  $("reset").onclick = reset;
  $("banner-reset").onclick = reset;
  $("stop").onclick = () => command("stop", {}, "experiment stop requested");
  for (const id of ["op-omega", "op-pinj"]) {
    // typing, or a clear() that fires only "change": the field is the operator's now
    for (const ev of ["input", "change"]) $(id).addEventListener(ev, () => markEdited($(id), true));
    $(id).addEventListener("keydown", (e) => { if (e.key === "Enter") setOperatingPoint(); });
  }
  $("op-set").onclick = setOperatingPoint;
  $("op-revert").onclick = () => { for (const id of ["op-omega", "op-pinj"]) { markEdited($(id), false); $(id).classList.remove("invalid"); } };
  $("load").onclick = async () => {
    const up = await fileText($("controller-file"));
    const sel = $("controller-select").value;
    if (!up && !sel) { say("load: choose a controller file or upload one", "error"); return; }
    command("load", up ? {upload: up} : {path: sel}, (res) => "controller loaded: " + (res && res.path || sel || up.name));
  };
  $("start").onclick = async () => {
    const up = await fileText($("exp-file"));
    const sel = $("exp-select").value;
    if (!up && !sel) { say("start: choose an experiment or upload one", "error"); return; }
    command("start", up ? {upload: up} : {path: sel}, "experiment started");
  };
  // scope
  fillSelect($("trig-chan"), CHANNELS.filter((c) => c !== "k_on"), null);
  $("pause").onclick = () => { pause(!rigd.paused); redrawTraces(); };
  $("trig-arm").onclick = () => {
    const err = armTrigger();
    if (err) say(err, "error"); else redrawTraces();
  };
  for (const b of document.querySelectorAll("[data-orbit]")) b.onclick = () => setOrbitScale(b.dataset.orbit);
  for (const b of document.querySelectorAll("nav .tab")) {
    b.onclick = () => {
      for (const t of document.querySelectorAll("nav .tab")) t.classList.toggle("active", t === b);
      for (const p of document.querySelectorAll(".panel")) p.classList.toggle("active", p.id === b.dataset.tab);
      if (b.dataset.tab === "runs") loadRuns(); else window.dispatchEvent(new Event("resize"));
    };
  }
  $("runs-refresh").onclick = () => loadRuns();
  // while the Runs tab is shown its list follows the runs folder (a run that ends, fails or
  // appears shows up without a click; an unchanged listing is not redrawn)
  setInterval(() => { if ($("runs").classList.contains("active")) loadRuns(true); }, RUNS_POLL_MS);
}
