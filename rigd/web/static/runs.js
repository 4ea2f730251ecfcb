// rigd console, the Runs tab: the runs folder (status with its reason), a record opened as
// zoomable traces — one axis group per unit, distinct colours, min/max decimated server-side
// and fetched again for the zoomed window — and the HTML pages of each run. docs/web.md.
import {$, GROUP_ORDER, RECORD_CONFIG, api, band, colours, fmt, groupOf, layoutBase, say, stackedAxes,
  unitOf} from "./core.js";

function cell(tr, text) {
  const td = document.createElement("td");
  if (text instanceof Node) td.appendChild(text); else td.textContent = text;
  tr.appendChild(td);
  return td;
}

let lastRuns = null;

/** Fill the Runs table from GET /api/runs. ``onlyIfChanged``: leave the table (and the rows a
 * user may be about to click) untouched when the listing is the same as last time — the tab
 * polls with it while it is shown, so a run's status and reason follow the manifest. */
export async function loadRuns(onlyIfChanged = false) {
  const r = await api("/api/runs");
  const tb = document.querySelector("#runs-table tbody");
  if (!r.ok) { if (!onlyIfChanged) say("runs: " + (r.body.error || r.status), "error"); return; }
  const key = JSON.stringify(r.body);
  if (onlyIfChanged === true && key === lastRuns) return;
  lastRuns = key;
  tb.innerHTML = "";
  for (const run of r.body) {
    const tr = document.createElement("tr");
    tr.dataset.run = run.name;
    cell(tr, run.name);
    cell(tr, run.error ? "(" + run.error + ")" : (run.kind || "–"));
    const op = run.operating_point;
    cell(tr, op ? fmt(op.omega_rpm, 0) + " rpm / " + fmt(op.p_inj_bar, 2) + " bar" : "–");
    cell(tr, run.source || "–");
    cell(tr, run.duration_s === null || run.duration_s === undefined ? "–" : fmt(run.duration_s, 1) + " s");
    const st = cell(tr, (run.status || "–") + (run.message ? ": " + run.message : ""));
    st.className = "status " + (run.status || "");
    st.title = st.textContent;
    const recs = document.createElement("span");
    for (const f of run.records || []) {
      const b = document.createElement("button");
      b.textContent = f + ((run.incomplete || []).includes(f) ? " (incomplete)" : ""); b.className = "open-record";
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

// channels shown when a record opens (the others one legend click away)
const SHOWN = /^(e_|u_|r_x|r_y|omega_rpm|p_inj_bar)/;
let currentRecord = null;

/** A unit as an engineer writes it (records may say "um" for µm). */
function unitText(u) {
  return u === "um" ? "µm" : u === "us" ? "µs" : u === "uV" ? "µV" : u;
}

/** Finite samples in a channel's buckets? (a channel of only NaN/null has nothing to draw) */
function hasData(d) {
  return d.min.some((v) => v !== null && Number.isFinite(v));
}

/** Axis groups for the traces shown (`visible === true`): one per unit, V split by role
 * (core.js groupOf), only the groups with a shown channel — a group whose channels are all
 * legend-only gets no empty panel; its traces ride on the first axis, hidden, until shown
 * (then the layout is rebuilt). Sets each trace's `yaxis`; returns the layout's axes. */
function recordAxes(traces) {
  const shown = GROUP_ORDER.concat([...new Set(traces.map((t) => t.legendgroup))]
    .filter((k) => !GROUP_ORDER.includes(k)))
    .filter((k) => traces.some((t) => t.legendgroup === k && t.visible === true));
  const labels = {};
  for (const t of traces) labels[t.legendgroup] = t.groupLabel;
  const st = stackedAxes(shown.map((k) => ({label: labels[k]})), 0.04);
  for (const t of traces) {
    const i = shown.indexOf(t.legendgroup);
    t.yaxis = i < 0 ? "y" : st.ref[i];
  }
  return {st, n: shown.length, shown};
}

function recordLayout(title, traces, t0, t1) {
  const {st, n, shown} = recordAxes(traces);
  const layout = layoutBase(title, Object.assign({
    xaxis: {title: {text: "t, s"}, anchor: st.ref.length ? st.ref[st.ref.length - 1] : "y"},
    // a new set of axes is a new revision: Plotly would otherwise bring back the user state of
    // an axis that is gone (an untitled, empty panel)
    uirevision: title + "|" + shown.join(","), margin: {l: 70, r: 10, t: 30, b: 40},
    legend: {orientation: "v", x: 1.01, y: 1, font: {size: 10}, groupclick: "toggleitem"},
  }, st.axes));
  if (!n) {
    layout.annotations = [{xref: "paper", yref: "paper", x: 0.5, y: 0.5, showarrow: false,
      text: "no channel shown: click one in the legend", font: {size: 13, color: "#555"}}];
    layout.yaxis = {visible: false};
  }
  if (t0 !== undefined) layout.xaxis.range = [t0, t1];
  return {layout, n};
}

export async function openRecord(run, file, t0, t1) {
  currentRecord = {run, file};
  let q = "?points=2000";
  if (t0 !== undefined) q += "&t0=" + t0 + "&t1=" + t1;
  const path = "/api/runs/" + encodeURIComponent(run) + "/" + file.split("/").map(encodeURIComponent).join("/");
  const r = await api(path + q);
  if (!r.ok) { say("record: " + (r.body.error || r.status), "error"); return; }
  const v = r.body;
  const names = Object.keys(v.channels).filter((c) => c !== "seq");
  const unit = (c) => unitText((v.units && v.units[c]) || unitOf(c) || "1");
  const el = $("record-plot");
  // a zoom keeps what the operator chose to show
  const before = el.data && el.dataset.file === run + "/" + file
    ? Object.fromEntries(el.data.map((t) => [t.meta, t.visible])) : null;
  const col = colours(names), traces = [], empty = [];
  for (const c of names) {
    const d = v.channels[c], {x, y} = band(v.t_s, d.min, d.max), g = groupOf(c, unit(c));
    const data = hasData(d);
    if (!data) empty.push(c);
    traces.push({x, y, name: c + " [" + unit(c) + "]" + (data ? "" : " (no samples here)"), meta: c,
      type: "scatter", mode: "lines", line: {width: 1, color: col[c]},
      // a channel with nothing to draw is never shown (an empty panel says nothing)
      visible: !data ? "legendonly" : before && c in before ? before[c] : (SHOWN.test(c) ? true : "legendonly"),
      legendgroup: g.key, groupLabel: g.label});
  }
  $("record-title").textContent = run + "/" + file + ": " + v.n + " samples at " + v.fs_hz +
    " Hz" + (v.decimated ? ", min/max decimated to " + v.t_s.length + " buckets (zoom for detail)" : "") +
    (empty.length ? "; no samples in this window: " + empty.join(", ") : "");
  const title = run + "/" + file;
  const {layout, n} = recordLayout(title, traces, t0, t1);
  el.style.height = Math.max(420, 150 * n) + "px";
  el.dataset.file = title;
  await Plotly.react("record-plot", traces, layout, RECORD_CONFIG);
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
    // a legend click shows or hides a channel: the axis groups follow (a group appears with its
    // first shown channel, goes with its last)
    el.on("plotly_restyle", () => { restack(el); });
  }
}

function restack(el) {
  const traces = el.data.map((t) => Object.assign({}, t));
  const range = el.layout.xaxis && !el.layout.xaxis.autorange ? el.layout.xaxis.range : undefined;
  const {layout, n} = recordLayout(el.dataset.file, traces, range && range[0], range && range[1]);
  el.style.height = Math.max(420, 150 * n) + "px";
  Plotly.react(el, traces, layout, RECORD_CONFIG);
}
