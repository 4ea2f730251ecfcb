"""``rigd web``: the rig in a browser — live console, control, runs (docs/web.md).

    rigd web                                   # http://127.0.0.1:8080/, daemon at $RIGD_SOCKET
    rigd web --listen 127.0.0.1:8081 --runs-dir runs --config-dir config

A separate process, a client of the daemon's control socket. Reach it from another machine
through an SSH tunnel (``ssh -L 8080:127.0.0.1:8080 rig``), not by listening on a public
address. Every request but the page itself needs the token (kept in ``--token-file``, mode
0600) or, for reads only, the ``--read-token-file`` token. At start it prints a URL that
carries the control token in its fragment (``http://127.0.0.1:8080/#token=...``): opening it
logs the tab in.
"""

from __future__ import annotations

import argparse
import ipaddress
import os
import socket
import sys
from pathlib import Path

from rigd.errors import InputError
from rigd.web.guard import HEADER_TIMEOUT_S, MAX_HEAD
from rigd.web.priority import DEFAULT_PRIORITY, take_rt_priority

#: connections accepted at a time
BACKLOG = 64

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
    p.add_argument("--read-token-file", metavar="F", help="file holding a read-only token "
                   "(GET only: status, stream, runs, records; no command), created like "
                   "--token-file when absent; default: no read-only token")
    p.add_argument("--tls-cert", metavar="PEM", help="serve HTTPS with this certificate "
                   "(chain) file; needs --tls-key")
    p.add_argument("--tls-key", metavar="PEM", help="private key of --tls-cert")
    p.add_argument("--insecure", action="store_true", help="serve plain HTTP on a "
                   "non-loopback --listen address anyway (a warning is printed)")
    p.add_argument("--allow-host", action="append", default=[], metavar="NAME",
                   help="also accept this Host header name (repeatable; the listen address "
                   "is always accepted)")
    p.add_argument("--header-timeout", type=float, default=HEADER_TIMEOUT_S, metavar="S",
                   help="seconds a connection may take to send a request head, and a request "
                   f"its body (default {HEADER_TIMEOUT_S:g})")
    p.add_argument("--film-gap-um", type=float, default=25.0, metavar="UM",
                   help="radial film gap drawn around the orbit, µm (default 25, the rig's)")
    p.add_argument("--timeout", type=float, default=10.0, metavar="S",
                   help="reply timeout of daemon requests, s (default 10)")
    p.add_argument("--rt-priority", type=_rt_priority, default=DEFAULT_PRIORITY, metavar="N",
                   help="SCHED_FIFO priority of the event loop that carries the console's SAFE "
                   f"(1-98, below the daemon's loop; 0: normal priority; default "
                   f"{DEFAULT_PRIORITY}; best effort: needs CAP_SYS_NICE or LimitRTPRIO)")


def _rt_priority(text: str) -> int:
    """``--rt-priority`` value: an integer 0-98 (argparse reports the error, exit 2)."""
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
    if not 0 <= n <= 98:
        raise argparse.ArgumentTypeError(f"{n} is outside 0-98")
    return n


def parse_listen(text: str) -> tuple[str, int]:
    """``HOST:PORT`` -> ``(host, port)`` (``[::1]:8080`` for IPv6); InputError if malformed."""
    host, sep, port = text.rpartition(":")
    host = host.strip("[]")
    if not sep or not host or not port.isdigit() or int(port) > 65535:
        raise InputError(f"--listen {text!r}: expected HOST:PORT, e.g. 127.0.0.1:8080")
    return host, int(port)


LOOPBACK_NAMES = ("127.0.0.1", "localhost", "::1")


def is_loopback(host: str) -> bool:
    """Whether ``host`` (an address or ``localhost``) is a loopback address."""
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return host.lower() == "localhost"


def is_wildcard(host: str) -> bool:
    """Whether ``host`` is ``0.0.0.0`` or ``::`` (every address of the machine)."""
    try:
        return ipaddress.ip_address(host).is_unspecified
    except ValueError:
        return False


def _machine_names() -> set[str]:
    names = {socket.gethostname(), socket.getfqdn()}
    for name in list(names):
        try:
            names |= {ai[4][0] for ai in socket.getaddrinfo(name, None)}
        except OSError:
            pass
    return names


def allowed_hosts(host: str, extra: list[str] | tuple[str, ...] = ()) -> tuple[str, ...]:
    """``Host`` header names accepted when listening on ``host`` (lower case, no port).

    A loopback address: the loopback names; another address: that address (or name); a
    wildcard (``0.0.0.0``, ``::``): the loopback names, the machine's host name, its fully
    qualified name and their addresses. Always the ``extra`` names (``--allow-host``). A page
    of another domain that an attacker re-points at the rig (DNS rebinding) sends its own
    name and is refused.
    """
    names = {host.lower()} | {e.lower().strip("[]") for e in extra}
    if is_loopback(host) or is_wildcard(host):
        names |= set(LOOPBACK_NAMES)
    if is_wildcard(host):
        names |= {n.lower() for n in _machine_names()}
    return tuple(sorted(names))


def check_transport(host: str, port: int, args: argparse.Namespace) -> bool:
    """Whether to serve TLS; InputError for a non-loopback address without TLS (unless
    ``--insecure``, which prints a warning) or an incomplete or unreadable certificate/key.
    """
    import ssl

    if bool(args.tls_cert) != bool(args.tls_key):
        raise InputError("--tls-cert and --tls-key go together")
    if args.tls_cert:
        try:
            ssl.create_default_context(ssl.Purpose.CLIENT_AUTH).load_cert_chain(
                args.tls_cert, args.tls_key)
        except (OSError, ssl.SSLError, ValueError) as exc:
            raise InputError(f"cannot use --tls-cert/--tls-key: {exc}") from None
        return True
    if is_loopback(host):
        return False
    if not args.insecure:
        raise InputError(f"--listen {host}:{port} is not a loopback address: give "
                         "--tls-cert/--tls-key (or --insecure to serve plain HTTP anyway)")
    print(f"rigd web: WARNING: --insecure: plain HTTP on {host}:{port}: the tokens, the "
          "session cookie and the rig's data cross the network unencrypted", file=sys.stderr)
    return False


def base_url(host: str, port: int, tls: bool, allow_host: list[str] | tuple[str, ...] = ()
             ) -> str:
    """The console's address, ``scheme://host:port/``; on a wildcard address (``0.0.0.0``,
    ``::``) the first ``--allow-host`` name, else the machine's host name."""
    if is_wildcard(host):
        host = allow_host[0] if allow_host else socket.gethostname()
    url_host = f"[{host}]" if ":" in host else host
    return f"{'https' if tls else 'http'}://{url_host}:{port}/"


def login_url(url: str, token: str) -> str:
    """``url`` carrying ``token`` in its fragment (``#token=...``): the one-click login.

    A fragment is never sent to the server (so never in its logs nor in a ``Referer``); the
    page (static/app.js) keeps the token for its tab (``sessionStorage``) and removes it from
    the address bar (``history.replaceState``) before it fetches anything.
    """
    from urllib.parse import quote

    return f"{url}#token={quote(token, safe='')}"


def _bind(host: str, port: int) -> socket.socket:
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    s = socket.socket(family, socket.SOCK_STREAM)
    s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:
        s.bind((host, port))
    except OSError as exc:
        s.close()
        raise InputError(f"cannot listen on {host}:{port}: {exc.strerror or exc}") from None
    s.listen(BACKLOG)
    return s


def run(args: argparse.Namespace) -> int:
    import uvicorn

    from rigd.web.app import Settings, build_app
    from rigd.web.auth import load_or_create_token
    from rigd.web.conn import guarded_protocol

    host, port = parse_listen(args.listen)
    if not 0 < args.header_timeout <= 3600:
        raise InputError(f"--header-timeout {args.header_timeout:g}: expected 0 < S <= 3600")
    tls = check_transport(host, port, args)
    runs_dir, config_dir = Path(args.runs_dir), Path(args.config_dir)
    if not config_dir.is_dir():
        raise InputError("no such folder (--config-dir)", str(config_dir))
    runs_dir.mkdir(parents=True, exist_ok=True)
    token_file = Path(args.token_file) if args.token_file else (
        Path.home() / ".config" / "rigd" / "web-token")
    if not args.token_file:
        token_file.parent.mkdir(parents=True, exist_ok=True, mode=0o700)
    token, created = load_or_create_token(token_file)
    read_token, read_created = (load_or_create_token(args.read_token_file)
                                if args.read_token_file else (None, False))
    if read_token is not None and read_token == token:
        raise InputError("holds the control token: the read-only token must differ",
                         args.read_token_file)
    sock = _bind(host, port)
    port = sock.getsockname()[1]
    if created:
        print(f"rigd web: new token (kept in {token_file}, mode 0600): {token}", file=sys.stderr)
    else:
        print(f"rigd web: token from {token_file}", file=sys.stderr)
    if read_created:
        print(f"rigd web: new read-only token (kept in {args.read_token_file}, mode 0600): "
              f"{read_token}", file=sys.stderr)
    elif read_token is not None:
        print(f"rigd web: read-only token from {args.read_token_file}", file=sys.stderr)
    url = base_url(host, port, tls, args.allow_host)
    listen_url_host = f"[{host}]" if ":" in host else host
    # this thread runs the event loop: the console's SAFE path (rigd.web.priority)
    print(f"rigd web: event loop (the console's SAFE path) at "
          f"{take_rt_priority(args.rt_priority)}", file=sys.stderr, flush=True)
    print(f"rigd web: serving {'https' if tls else 'http'}://{listen_url_host}:{port}/ "
          f"(daemon {args.socket}, "
          f"runs {runs_dir}, config {config_dir})", file=sys.stderr, flush=True)
    if read_token is not None:
        print(f"rigd web: read-only URL (reads only): {login_url(url, read_token)}",
              file=sys.stderr, flush=True)
    # last, like Jupyter's: the operator's one click (the control token: what they may do)
    print(f"rigd web: open {login_url(url, token)}", file=sys.stderr, flush=True)
    app = build_app(Settings(socket=args.socket, runs_dir=runs_dir.resolve(),
                             config_dir=config_dir.resolve(), token=token,
                             read_token=read_token, secure=tls,
                             request_timeout_s=args.header_timeout,
                             timeout_s=args.timeout, film_gap_um=args.film_gap_um,
                             allowed_hosts=allowed_hosts(host, args.allow_host)))
    server = uvicorn.Server(uvicorn.Config(
        app, log_level="warning", access_log=False, timeout_graceful_shutdown=2,
        http=guarded_protocol(args.header_timeout), h11_max_incomplete_event_size=MAX_HEAD,
        backlog=BACKLOG, ssl_certfile=args.tls_cert, ssl_keyfile=args.tls_key))
    server.run(sockets=[sock])
    return 0
