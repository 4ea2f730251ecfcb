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
  if (!token()) return null;
  try {
    const r = await fetch("/api/login", {method: "POST", headers: {"Authorization": "Bearer " + token()}});
    if (!r.ok) return null;
    return (await r.json()).access || null;
  } catch (e) {
    return null;
  }
}

// The one-click URL `rigd web` prints (http://host:port/#token=...): a fragment is never sent
// to the server (nor logged by it, nor sent as a Referer). The token is kept for this tab and
// taken out of the address bar (and this history entry) before anything else runs.
function tokenFromAddress() {
  const hash = new URLSearchParams(location.hash.slice(1));
  if (!hash.has("token")) return false;
  const tk = hash.get("token").trim();
  hash.delete("token");
  const rest = hash.toString();
  history.replaceState(history.state, "", location.pathname + location.search + (rest ? "#" + rest : ""));
  if (tk) sessionStorage.setItem("rigd-token", tk);
  return !!tk;
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

const ACCESS = {control: "control token: reads and commands", read: "read-only token: commands are refused"};

async function main() {
  const fromAddress = tokenFromAddress();
  wireControls();
  // the messages name the button by its own label: the words always match it
  const button = '"' + $("token-save").textContent.trim() + '"';
  const loggedIn = (access) => {
    rigd.access = access;
    say("logged in with the " + ACCESS[access] + " (kept for this tab)", "ok");
    start();
  };
  const refusedFromAddress = () => say("the token in the address was refused (HTTP 401): open the URL rigd web printed at start, or paste its token and press " + button, "error");
  $("token-save").onclick = async () => {
    sessionStorage.setItem("rigd-token", $("token").value.trim());
    const access = await login();
    if (access) loggedIn(access);
    else say("token refused (HTTP 401): paste the token rigd web printed at start and press " + button, "error");
  };
  // a URL with a new token pasted into this tab changes only the fragment: no reload
  window.addEventListener("hashchange", async () => {
    if (!tokenFromAddress()) return;
    $("token").value = token();
    const access = await login();
    if (access) loggedIn(access);
    else refusedFromAddress();
  });
  const access = await login();
  if (access) loggedIn(access);
  else if (fromAddress) refusedFromAddress();
  else say("open the URL rigd web printed at start, or paste the token it printed (or its read-only token) and press " + button, "error");
}

main();
