"""The Starlette application of ``rigd web`` (routes: docs/web.md)."""

from __future__ import annotations

import json
import re
import time
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

from starlette.applications import Starlette
from starlette.concurrency import run_in_threadpool
from starlette.middleware import Middleware
from starlette.middleware.trustedhost import TrustedHostMiddleware
from starlette.requests import Request
from starlette.responses import FileResponse, JSONResponse, Response, StreamingResponse
from starlette.routing import Mount, Route
from starlette.staticfiles import StaticFiles

from rigd import __version__
from rigd.configio import read_yaml
from rigd.errors import InputError
from rigd.experiments.schemas import load_experiment, validate_spec
from rigd.fileio import atomic_write_text
from rigd.service.safe_request import SafeWordClient, SafeWordUnavailable
from rigd.web import runs as runs_mod
from rigd.web import sse
from rigd.web.auth import MAX_BODY, Guard
from rigd.web.ctl import COMMANDS, Daemon, DaemonDown, DaemonRefused, DaemonSilent
from rigd.web.paths import PathRefused, resolve_inside, split_rooted

STATIC = Path(str(resources.files("rigd.web") / "static"))
#: SSE clients at once (multiplexed onto at most rigd.web.sse.MAX_FEEDS daemon connections)
MAX_STREAMS = 256
#: the console page loads only its own files (Plotly adds inline styles)
PAGE_CSP = ("default-src 'self'; script-src 'self'; style-src 'self' 'unsafe-inline'; "
            "img-src 'self' data: blob:; connect-src 'self'; frame-ancestors 'none'; "
            "base-uri 'none'; form-action 'none'")
#: uploaded file names: plain words, dots, dashes
_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]{0,99}$")


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
        The Bearer token of state-changing requests.
    film_gap_um : float
        Radial film gap, µm: the circle drawn around the orbit.
    allowed_hosts : tuple of str, optional
        Accepted ``Host`` header names (without port); None accepts any. ``rigd web`` on a
        loopback address accepts only loopback names: a web page whose domain an attacker
        re-points to 127.0.0.1 (DNS rebinding) cannot read the console's answers.
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
    except (ValueError, UnicodeDecodeError) as exc:
        raise InputError(f"request body is not JSON: {exc}") from None
    if not isinstance(body, dict):
        raise InputError("request body must be a JSON object")
    return body


def _upload(body: dict[str, Any]) -> tuple[str, str] | None:
    """``(name, text)`` of an uploaded file in the body (``{"upload": {"name", "text"}}``)."""
    up = body.get("upload")
    if up is None:
        return None
    if not isinstance(up, dict) or not isinstance(up.get("text"), str):
        raise InputError("upload must be {\"name\": ..., \"text\": ...}")
    name = Path(str(up.get("name") or "upload.yaml")).name
    if not _NAME.match(name):
        raise InputError(f"upload name {name[:60]!r}: letters, digits, '.', '_', '-' only")
    return name, up["text"]


def _save_upload(settings: Settings, kind: str, name: str, text: str) -> Path:
    """Keep an upload in ``<runs>/uploads/`` (the daemon reads it from there; a record of what
    was run)."""
    stamp = time.strftime("%Y%m%dT%H%M%SZ", time.gmtime())
    path = settings.runs_dir / "uploads" / f"{stamp}-{kind}-{name}"
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_text(path, text)
    return path.resolve()


def _yaml_files(roots: dict[str, Path]) -> dict[str, list[str]]:
    out: dict[str, list[str]] = {}
    for key, root in roots.items():
        out[key] = []
        if not root.is_dir():
            continue
        base = root.resolve()
        for p in sorted(root.rglob("*.yaml")):
            rel = p.relative_to(root).as_posix()
            if key == "runs" and "controller" not in rel:
                continue
            if not p.resolve().is_relative_to(base):
                continue  # a symlink out of the folder is not offered
            out[key].append(f"{key}/{rel}")
            if len(out[key]) >= runs_mod.MAX_LIST:
                break
    return out


def build_app(settings: Settings) -> Starlette:
    """The ASGI app, wrapped in the token/size :class:`~rigd.web.auth.Guard`."""
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
                result = await word.safe_async(min(settings.timeout_s, 2.0))
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
            args = await run_in_threadpool(_command_args, name, body)
        except PathRefused as exc:
            return _err(400, f"{name}: {exc}")
        except InputError as exc:
            return _err(400, f"{name}: {exc}")
        return await call(COMMANDS[name], **args)

    def _command_args(name: str, body: dict[str, Any]) -> dict[str, Any]:
        """The daemon request of ``POST /api/<name>``, validated here first."""
        allowed = {"load": {"path", "upload"}, "start": {"path", "upload"},
                   "op": {"omega_rpm", "p_inj_bar"}}.get(name, set())
        extra = sorted(set(body) - allowed)
        if extra:
            raise InputError(f"unknown field {extra[0]!r}"
                             + (f" (allowed: {', '.join(sorted(allowed))})" if allowed else ""))
        if name == "op":
            return {k: body.get(k) for k in ("omega_rpm", "p_inj_bar")}
        if name not in ("load", "start"):
            return {}
        up = _upload(body)
        if (up is None) == (body.get("path") is None):
            raise InputError("give exactly one of 'path' (config/... or runs/...) or 'upload'")
        if name == "start":
            if up is not None:
                # the CLI's loader, on the uploaded text: same checks, same one-line errors
                validate_spec(read_yaml(up[0], up[1]))
                path = _save_upload(settings, "experiment", *up)
            else:
                path = split_rooted(body["path"], roots)
                load_experiment(path)
            return {"path": str(path)}
        if up is not None:
            path = _save_upload(settings, "controller", *up)
        else:
            path = split_rooted(body["path"], roots)
            if not path.is_file():
                raise InputError(f"no such file {body['path']!r}")
        return {"path": str(path)}

    async def files(request: Request) -> Response:
        """YAML files to choose from: every one in the config folder (experiments,
        controllers), and those of the runs folder with ``controller`` in their path (what
        ``rigd design`` and uploads leave there), as ``config/...`` / ``runs/...``."""
        return JSONResponse(await run_in_threadpool(_yaml_files, roots))

    async def runs(request: Request) -> Response:
        return JSONResponse(await run_in_threadpool(runs_mod.list_runs, settings.runs_dir))

    async def record(request: Request) -> Response:
        q = request.query_params
        try:
            path = resolve_inside(settings.runs_dir, request.path_params["path"])
            if not path.is_file():
                return _err(404, "no such record")
            points = int(q.get("points", "2000"))
            t0 = float(q["t0"]) if q.get("t0") else None
            t1 = float(q["t1"]) if q.get("t1") else None
            chans = [c for c in q.get("channels", "").split(",") if c] or None
        except PathRefused as exc:
            return _err(404, str(exc))
        except ValueError as exc:
            return _err(400, f"bad query: {exc}")
        try:
            view = await run_in_threadpool(runs_mod.record_view, path, points, t0, t1, chans)
        except InputError as exc:
            return _err(400, str(exc))
        return JSONResponse(view)

    async def run_file(request: Request) -> Response:
        try:
            path = resolve_inside(settings.runs_dir, request.path_params["path"])
        except PathRefused as exc:
            return _err(404, str(exc))
        if not path.is_file():
            return _err(404, "no such file")
        return FileResponse(path)

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
    middleware = [Middleware(SecurityHeaders)]
    if settings.allowed_hosts is not None:
        middleware.insert(0, Middleware(TrustedHostMiddleware,
                                        allowed_hosts=list(settings.allowed_hosts)))
    app = Starlette(routes=routes, middleware=middleware)
    return Guard(app, settings.token, settings.max_body)


class SecurityHeaders:
    """``nosniff`` and no framing on every response (report pages under ``/runs/`` keep
    their inline scripts: the content security policy is the console page's only)."""

    def __init__(self, app):
        self.app = app

    async def __call__(self, scope, receive, send):
        async def send_with_headers(message):
            if message["type"] == "http.response.start":
                message.setdefault("headers", [])
                message["headers"] = list(message["headers"]) + [
                    (b"x-content-type-options", b"nosniff"), (b"x-frame-options", b"DENY")]
            await send(message)

        await self.app(scope, receive, send_with_headers)
