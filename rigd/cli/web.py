"""``rigd web``: the rig in a browser — live console, control, runs (docs/web.md).

    rigd web                                   # http://127.0.0.1:8080/, daemon at $RIGD_SOCKET
    rigd web --listen 127.0.0.1:8081 --runs-dir runs --config-dir config

A separate process, a client of the daemon's control socket. Reach it from another machine
through an SSH tunnel (``ssh -L 8080:127.0.0.1:8080 rig``), not by listening on a public
address. State-changing requests need the token printed at start (kept in ``--token-file``,
mode 0600).
"""

from __future__ import annotations

import argparse
import ipaddress
import os
import socket
import sys
from pathlib import Path

from rigd.errors import InputError

HELP = "web console: live view, control and runs in a browser (127.0.0.1:8080)"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--socket", default=os.environ.get("RIGD_SOCKET", "/run/rigd/rigd.sock"),
                   help="daemon control socket (default $RIGD_SOCKET or /run/rigd/rigd.sock)")
    p.add_argument("--listen", default="127.0.0.1:8080", metavar="HOST:PORT",
                   help="address to serve on (default 127.0.0.1:8080; port 0: any free port)")
    p.add_argument("--runs-dir", default="runs", help="runs folder to list and serve "
                   "(default runs)")
    p.add_argument("--config-dir", default="config", help="folder of experiment and "
                   "controller YAMLs offered on the page (default config)")
    p.add_argument("--token-file", help="file holding the token (created with a new token, "
                   "mode 0600, when absent; default ~/.config/rigd/web-token)")
    p.add_argument("--film-gap-um", type=float, default=25.0, metavar="UM",
                   help="radial film gap drawn around the orbit, µm (default 25, the rig's)")
    p.add_argument("--timeout", type=float, default=10.0, metavar="S",
                   help="reply timeout of daemon requests, s (default 10)")


def parse_listen(text: str) -> tuple[str, int]:
    """``HOST:PORT`` -> ``(host, port)`` (``[::1]:8080`` for IPv6); InputError if malformed."""
    host, sep, port = text.rpartition(":")
    host = host.strip("[]")
    if not sep or not host or not port.isdigit() or int(port) > 65535:
        raise InputError(f"--listen {text!r}: expected HOST:PORT, e.g. 127.0.0.1:8080")
    return host, int(port)


def loopback_hosts(host: str) -> tuple[str, ...] | None:
    """Host names accepted when serving on a loopback address (None: any, e.g. 0.0.0.0)."""
    try:
        loopback = ipaddress.ip_address(host).is_loopback
    except ValueError:
        loopback = host == "localhost"
    return ("127.0.0.1", "localhost", "::1", "[::1]") if loopback else None


def _bind(host: str, port: int) -> socket.socket:
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    s = socket.socket(family, socket.SOCK_STREAM)
    s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:
        s.bind((host, port))
    except OSError as exc:
        s.close()
        raise InputError(f"cannot listen on {host}:{port}: {exc.strerror or exc}") from None
    s.listen(128)
    return s


def run(args: argparse.Namespace) -> int:
    import uvicorn

    from rigd.web.app import Settings, build_app
    from rigd.web.auth import load_or_create_token

    host, port = parse_listen(args.listen)
    runs_dir, config_dir = Path(args.runs_dir), Path(args.config_dir)
    if not config_dir.is_dir():
        raise InputError("no such folder (--config-dir)", str(config_dir))
    runs_dir.mkdir(parents=True, exist_ok=True)
    token_file = Path(args.token_file) if args.token_file else (
        Path.home() / ".config" / "rigd" / "web-token")
    if not args.token_file:
        token_file.parent.mkdir(parents=True, exist_ok=True, mode=0o700)
    token, created = load_or_create_token(token_file)
    sock = _bind(host, port)
    port = sock.getsockname()[1]
    if created:
        print(f"rigd web: new token (kept in {token_file}, mode 0600): {token}", file=sys.stderr)
    else:
        print(f"rigd web: token from {token_file}", file=sys.stderr)
    print(f"rigd web: serving http://{host}:{port}/ (daemon {args.socket}, runs {runs_dir}, "
          f"config {config_dir})", file=sys.stderr, flush=True)
    app = build_app(Settings(socket=args.socket, runs_dir=runs_dir.resolve(),
                             config_dir=config_dir.resolve(), token=token,
                             timeout_s=args.timeout, film_gap_um=args.film_gap_um,
                             allowed_hosts=loopback_hosts(host)))
    server = uvicorn.Server(uvicorn.Config(app, log_level="warning", access_log=False,
                                           timeout_graceful_shutdown=2))
    server.run(sockets=[sock])
    return 0
