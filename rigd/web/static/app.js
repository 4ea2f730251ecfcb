// rigd console: live view (GET /api/stream, Server-Sent Events), control (POST /api/<cmd>
// with the Bearer token from sessionStorage), runs (GET /api/runs). docs/web.md.
// Modules: core.js (state, API, messages, units, colours), header.js (state at a glance),
// live.js (stream, buffers, restarts, trends, pause/trigger), plots.js (drawing),
// controls.js (SAFE, forms), runs.js (Runs tab).
import {$, api, rigd, say, token} from "./core.js";
import {loadFiles, wireControls} from "./controls.js";
import {connectStream, onDirty, refreshStatus, startWatch} from "./live.js";
import {onHeaderPending} from "./header.js";
import {markDirty, startRendering, wake} from "./plots.js";

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

let started = false;
async function start() {
  if (started) return;
  started = true;
  onDirty(markDirty);
  onHeaderPending(wake);
  const c = await api("/api/console");
  if (c.ok && c.body.film_gap_um) rigd.filmGap = c.body.film_gap_um;
  loadFiles();
  await refreshStatus();
  startWatch();
  connectStream();
  startRendering();
}

async function main() {
  wireControls();
  $("token-save").onclick = async () => {
    sessionStorage.setItem("rigd-token", $("token").value.trim());
    if (await login()) {
      say("token kept for this tab (sessionStorage); sent as Authorization: Bearer", "ok");
      start();
    } else {
      say("login: token refused (HTTP 401): use the token rigd web printed at start", "error");
    }
  };
  if (await login()) start();
  else say("enter the token printed by rigd web (or its read-only token) and press Keep", "error");
}

main();
