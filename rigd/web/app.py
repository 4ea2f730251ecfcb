"""The Starlette application of ``rigd web`` (routes: docs/web.md)."""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

from starlette.applications import Starlette
from starlette.concurrency import run_in_threadpool
from starlette.requests import Request
from starlette.responses import FileResponse, JSONResponse, Response, StreamingResponse
from starlette.routing import Mount, Route
from starlette.staticfiles import StaticFiles

from rigd import __version__
from rigd.configio import read_yaml
from rigd.errors import InputError
from rigd.experiments.schemas import load_experiment, validate_spec
from rigd.service.client import controller_args, experiment_args
from rigd.service.safe_request import SafeWordClient, SafeWordUnavailable
from rigd.web import runs as runs_mod
from rigd.web import sse
from rigd.web.auth import Tokens
from rigd.web.ctl import COMMANDS, Daemon, DaemonDown, DaemonRefused, DaemonSilent
from rigd.web.files import file_response, save_upload, upload_name, yaml_files
from rigd.web.guard import BODY_TIMEOUT_S, MAX_BODY, Guard
from rigd.web.paths import PathRefused, resolve_inside, split_rooted

STATIC = Path(str(resources.files("rigd.web") / "static"))
#: SSE clients at once (multiplexed onto at most rigd.web.sse.MAX_FEEDS daemon connections)
MAX_STREAMS = 256
#: the console page loads only its own files, and no string is ever run as code: no
#: 'unsafe-eval' (plotly.js evaluates strings only for its WebGL traces, regl, and its map
#: traces' workers — the page uses neither: SVG frames, its lines on a canvas of its own) and
#: no inline script; Plotly adds inline styles
PAGE_CSP = ("default-src 'self'; script-src 'self'; "
            "style-src 'self' 'unsafe-inline'; "
            "img-src 'self' data: blob:; connect-src 'self'; frame-ancestors 'none'; "
            "base-uri 'none'; form-action 'none'")
#: every other response: nothing may load or run, no framing
DEFAULT_CSP = "default-src 'none'; frame-ancestors 'none'; base-uri 'none'; form-action 'none'"
#: deepest JSON request body (the commands' bodies are 3 levels deep)
MAX_JSON_DEPTH = 16


@dataclass
class Settings:
    """What ``rigd web`` serves.

    Attributes
    ----------
    socket : str
        The daemon's control socket.
    runs_dir, config_dir : Path
        The only folders whose files are served or named in requests.
    token : str
        The control token: every request (``Authorization: Bearer``).
    read_token : str, optional
        The read-only token: GET/HEAD only (403 on a command); None: none.
    secure : bool
        Served over TLS (the session cookie gets ``Secure``).
    request_timeout_s : float
        Seconds a request body may take to arrive (408 beyond).
    film_gap_um : float
        Radial film gap, µm: the circle drawn around the orbit.
    allowed_hosts : tuple of str, optional
        Accepted ``Host`` header names (without port); None accepts any. ``rigd web`` accepts
        only the names of its listen address (and ``--allow-host``): a web page whose domain
        an attacker re-points to the rig (DNS rebinding) cannot read the console's answers.
    timeout_s : float
        Reply timeout of daemon requests, s.
    """

    socket: str
    runs_dir: Path
    config_dir: Path
    token: str
    timeout_s: float = 10.0
    max_body: int = MAX_BODY
    film_gap_um: float = 25.0
    allowed_hosts: tuple[str, ...] | None = None
    read_token: str | None = None
    secure: bool = False
    request_timeout_s: float = BODY_TIMEOUT_S


def _finite(text: str) -> float:
    value = float(text)
    if not math.isfinite(value):
        raise ValueError(f"{text!r} is not a finite number")
    return value


def _err(status: int, message: str) -> JSONResponse:
    return JSONResponse({"error": " ".join(str(message).split())}, status_code=status)


def plotly_js() -> Path:
    """``plotly.min.js`` of the installed plotly wheel (package data, no CDN)."""
    return Path(str(resources.files("plotly") / "package_data" / "plotly.min.js"))


async def _json_body(request: Request) -> dict[str, Any]:
    raw = await request.body()
    if not raw:
        return {}
    try:
        body = json.loads(raw)
    except RecursionError:
        body = None
    except (ValueError, UnicodeDecodeError) as exc:
        raise InputError(f"request body is not JSON: {exc}") from None
    if body is None or json_depth(body) > MAX_JSON_DEPTH:
        raise InputError(f"request body nested deeper than {MAX_JSON_DEPTH} levels")
    if not isinstance(body, dict):
        raise InputError("request body must be a JSON object")
    return body


def json_depth(obj: Any) -> int:
    """Nesting depth of a parsed JSON value (a scalar is 0), without recursion."""
    depth, level = 0, [(obj, 0)]
    while level:
        value, d = level.pop()
        if isinstance(value, (dict, list)):
            depth = max(depth, d + 1)
            if d + 1 > MAX_JSON_DEPTH:
                return d + 1
            level.extend((v, d + 1) for v in (value.values() if isinstance(value, dict)
                                               else value))
    return depth


def _number(body: dict[str, Any], key: str) -> float:
    """``body[key]`` as a finite number; missing, empty, a string or a bool is refused (an
    empty form field must never become 0 rpm)."""
    v = body.get(key)
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise InputError(f"{key}: a finite number is required, got {json.dumps(v)[:40]}")
    return float(v)


def _upload(body: dict[str, Any]) -> tuple[str, str] | None:
    """``(name, text)`` of an uploaded file in the body (``{"upload": {"name", "text"}}``)."""
    up = body.get("upload")
    if up is None:
        return None
    if not isinstance(up, dict) or not isinstance(up.get("text"), str):
        raise InputError("upload must be {\"name\": ..., \"text\": ...}")
    return upload_name(up.get("name")), up["text"]


def build_app(settings: Settings) -> Starlette:
    """The ASGI app, wrapped in the request :class:`~rigd.web.guard.Guard` (host, token or
    session, sizes)."""
    daemon = Daemon(settings.socket, settings.timeout_s)
    roots = {"config": settings.config_dir, "runs": settings.runs_dir}
    hub = sse.StreamHub(settings.socket, settings.timeout_s, MAX_STREAMS)

    async def call(cmd: str, **args: Any) -> Response:
        try:
            result = await run_in_threadpool(daemon.call, cmd, **args)
        except DaemonDown as exc:
            return _err(503, str(exc))
        except DaemonSilent as exc:
            return _err(504, str(exc))
        except DaemonRefused as exc:
            return _err(409, str(exc))
        return JSONResponse(result)

    async def index(request: Request) -> Response:
        return FileResponse(STATIC / "index.html", headers={"cache-control": "no-store",
                                                             "content-security-policy": PAGE_CSP})

    async def console(request: Request) -> Response:
        return JSONResponse({"film_gap_um": settings.film_gap_um, "version": __version__})

    async def plotly(request: Request) -> Response:
        return FileResponse(plotly_js(), media_type="text/javascript")

    def query_route(cmd: str):
        async def handler(request: Request) -> Response:
            return await call(cmd)
        return handler

    async def safe(request: Request) -> Response:
        """SAFE through the daemon's SAFE word, in this event loop (no worker thread, no
        daemon client slot); the socket's ``safe`` when the word cannot be mapped."""
        try:
            word = SafeWordClient(settings.socket)
        except SafeWordUnavailable as exc:
            why = str(exc)
        else:
            try:
                result = await word.safe_async(settings.timeout_s)
            finally:
                word.close()
            if result is not None:
                return JSONResponse(result)
            why = f"{word.path}: no cycle took the request (is the loop running?)"
        reply = await call("safe")
        if reply.status_code >= 400:
            return _err(reply.status_code, json.loads(reply.body)["error"]
                        + f" (SAFE word: {why})")
        return reply

    async def command(request: Request) -> Response:
        name = request.path_params["name"]
        if name == "safe":
            return await safe(request)
        if name not in COMMANDS:
            return _err(404, f"no command {name!r} (known: {', '.join(COMMANDS)})")
        try:
            body = await _json_body(request)
            args, kept = await run_in_threadpool(_command_args, name, body)
        except PathRefused as exc:
            return _err(400, f"{name}: {exc}")
        except InputError as exc:
            return _err(400, f"{name}: {exc}")
        except OSError as exc:
            return _err(400, f"{name}: {exc.strerror or exc}")
        answer = await call(COMMANDS[name], **args)
        if kept is not None and answer.status_code not in (200, 504):
            kept.unlink(missing_ok=True)   # refused (or never sent): a rejected upload is not kept
        return answer

    def _command_args(name: str, body: dict[str, Any]) -> tuple[dict[str, Any], Path | None]:
        """The daemon request of ``POST /api/<name>``, validated here first, and the upload
        it keeps (None: none)."""
        allowed = {"load": {"path", "upload"}, "start": {"path", "upload"},
                   "op": {"omega_rpm", "p_inj_bar"}}.get(name, set())
        extra = sorted(set(body) - allowed)
        if extra:
            raise InputError(f"unknown field {extra[0]!r}"
                             + (f" (allowed: {', '.join(sorted(allowed))})" if allowed else ""))
        if name == "op":
            return {k: _number(body, k) for k in ("omega_rpm", "p_inj_bar")}, None
        if name not in ("load", "start"):
            return {}, None
        up = _upload(body)
        if (up is None) == (body.get("path") is None):
            raise InputError("give exactly one of 'path' (config/... or runs/...) or 'upload'")
        # the file's content goes to the daemon, read here (the daemon opens no file a
        # client names); the daemon's socket process checks it (gates) as for `rigd ctl`
        if name == "start":
            if up is not None:
                # the CLI's loader, on the uploaded text: same checks, same one-line errors
                validate_spec(read_yaml(up[0], up[1]))
                path = save_upload(settings.runs_dir, "experiment", *up)
                return experiment_args(str(path)), path
            path = split_rooted(body["path"], roots)
            load_experiment(path)
            return experiment_args(str(path)), None
        if up is not None:
            path = save_upload(settings.runs_dir, "controller", *up)
            try:
                return controller_args(str(path)), path
            except InputError:
                path.unlink(missing_ok=True)   # refused: a rejected upload is not kept
                raise
        path = split_rooted(body["path"], roots)
        if not path.is_file():
            raise InputError(f"no such file {body['path']!r}")
        return controller_args(str(path)), None

    async def files(request: Request) -> Response:
        """YAML files to choose from: every one in the config folder (experiments,
        controllers), and those of the runs folder with ``controller`` in their path (what
        ``rigd design`` and uploads leave there), as ``config/...`` / ``runs/...``."""
        return JSONResponse(await run_in_threadpool(yaml_files, roots, runs_mod.MAX_LIST))

    async def runs(request: Request) -> Response:
        return JSONResponse(await run_in_threadpool(runs_mod.list_runs, settings.runs_dir))

    async def record(request: Request) -> Response:
        q = request.query_params
        try:
            path = resolve_inside(settings.runs_dir, request.path_params["path"])
            if not path.is_file():
                return _err(404, "no such record")
            points = int(q.get("points", "2000"))
            t0 = _finite(q["t0"]) if q.get("t0") else None
            t1 = _finite(q["t1"]) if q.get("t1") else None
            chans = [c for c in q.get("channels", "").split(",") if c] or None
        except PathRefused as exc:
            return _err(404, str(exc))
        except ValueError as exc:
            return _err(400, f"bad query: {exc}")
        try:
            view = await run_in_threadpool(runs_mod.record_view, path, points, t0, t1, chans)
        except (InputError, OSError, ValueError) as exc:
            return _err(400, f"cannot open the record: {exc}")
        return JSONResponse(view)

    async def run_file(request: Request) -> Response:
        try:
            path = resolve_inside(settings.runs_dir, request.path_params["path"])
        except PathRefused as exc:
            return _err(404, str(exc))
        if not path.is_file():
            return _err(404, "no such file")
        return file_response(settings.runs_dir, path)

    async def stream(request: Request) -> Response:
        q = request.query_params
        try:
            sub: dict[str, Any] = {"rate_hz": float(q.get("rate_hz", "50")),
                                   "points": int(q.get("points", "200")),
                                   "channels": ([c for c in q["channels"].split(",") if c]
                                                if q.get("channels") else None)}
        except ValueError as exc:
            return _err(400, f"bad query: {exc}")
        try:
            lease, key = hub.acquire(sub)
        except sse.StreamFull as exc:
            return _err(503, str(exc))

        return StreamingResponse(hub.events(lease, key, sub), media_type="text/event-stream",
                                 headers={"cache-control": "no-store",
                                          "x-accel-buffering": "no"})

    routes = [
        Route("/", index),
        Route("/static/plotly.min.js", plotly),
        Mount("/static", StaticFiles(directory=STATIC), name="static"),
        Route("/api/console", console),
        Route("/api/status", query_route("status")),
        Route("/api/ping", query_route("ping")),
        Route("/api/timing", query_route("timing")),
        Route("/api/faults", query_route("faults")),
        Route("/api/experiment", query_route("experiment.status")),
        Route("/api/stream", stream),
        Route("/api/files", files),
        Route("/api/runs", runs),
        Route("/api/runs/{path:path}", record),
        Route("/runs/{path:path}", run_file),
        Route("/api/{name}", command, methods=["POST"]),
    ]
    app = Starlette(routes=routes)
    tokens = Tokens(settings.token, settings.read_token, settings.secure)
    return SecurityHeaders(Guard(app, tokens, settings.max_body, settings.allowed_hosts,
                                 settings.request_timeout_s))


class SecurityHeaders:
    """``nosniff``, no framing and a content security policy on every response: the page's
    own (:data:`PAGE_CSP`, report pages :data:`REPORT_CSP`) or :data:`DEFAULT_CSP` (nothing
    may load or run) on everything else, the guard's answers included."""

    def __init__(self, app):
        self.app = app

    async def __call__(self, scope, receive, send):
        async def send_with_headers(message):
            if message["type"] == "http.response.start":
                headers = list(message.get("headers", []))
                extra = [(b"x-content-type-options", b"nosniff"), (b"x-frame-options", b"DENY")]
                if not any(k.lower() == b"content-security-policy" for k, _ in headers):
                    extra.append((b"content-security-policy", DEFAULT_CSP.encode()))
                message["headers"] = headers + extra
            await send(message)

        await self.app(scope, receive, send_with_headers)
