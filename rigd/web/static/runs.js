// rigd console, the Runs tab: the runs folder (status with its reason), a record opened as
// zoomable traces — one axis group per unit, distinct colours, min/max decimated server-side
// and fetched again for the zoomed window — and the HTML pages of each run. docs/web.md.
import {$, RECORD_CONFIG, api, band, colours, fmt, layoutBase, rigd, say, stackedAxes, unitOf} from "./core.js";

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

// channels shown when a record opens (the others one legend click away)
const SHOWN = /^(e_|u_|r_x|r_y|omega_rpm|p_inj_bar)/;
let currentRecord = null;

/** A unit as an engineer writes it (records may say "um" for µm). */
function unitText(u) {
  return u === "um" ? "µm" : u === "us" ? "µs" : u === "uV" ? "µV" : u;
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
  const units = [...new Set(names.map(unit))];
  const el = $("record-plot");
  // a zoom keeps what the operator chose to show
  const before = el.data && el.dataset.file === run + "/" + file
    ? Object.fromEntries(el.data.map((t) => [t.meta, t.visible])) : null;
  const col = colours(names), traces = [];
  for (const c of names) {
    const d = v.channels[c], {x, y} = band(v.t_s, d.min, d.max), i = units.indexOf(unit(c));
    traces.push({x, y, name: c + " [" + unit(c) + "]", meta: c, type: rigd.traceType || "scatter",
      mode: "lines", line: {width: 1, color: col[c]}, yaxis: i === 0 ? "y" : "y" + (i + 1),
      visible: before && c in before ? before[c] : (SHOWN.test(c) ? true : "legendonly"),
      legendgroup: unit(c)});
  }
  $("record-title").textContent = run + "/" + file + ": " + v.n + " samples at " + v.fs_hz +
    " Hz" + (v.decimated ? ", min/max decimated to " + v.t_s.length + " buckets (zoom for detail)" : "");
  const st = stackedAxes(units.map((u) => ({label: u})), 0.03);
  const layout = layoutBase(run + "/" + file, Object.assign({
    xaxis: {title: {text: "t, s"}, anchor: st.ref[st.ref.length - 1]}, uirevision: file,
    margin: {l: 70, r: 10, t: 30, b: 40}, legend: {orientation: "v", x: 1.01, y: 1, font: {size: 10},
      groupclick: "toggleitem"},
  }, st.axes));
  el.style.height = Math.max(420, 150 * units.length) + "px";
  if (t0 !== undefined) layout.xaxis.range = [t0, t1];
  el.dataset.file = run + "/" + file;
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
  }
}
