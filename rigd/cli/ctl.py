"""``rigd ctl``: talk to the running daemon through its control socket.

Examples::

    rigd ctl status
    rigd ctl --socket /tmp/rigd.sock timing --json
    rigd ctl load controllers/k_4bar.yaml && rigd ctl enable
    rigd ctl op 3000 4.5
    rigd ctl start config/experiments/prbs.yaml
    rigd ctl safe
"""

from __future__ import annotations

import argparse
import json
import os
import sys

from rigd.errors import DaemonGone, InputError

HELP = "control the running daemon (status, timing, faults, enable/disable K∞, experiments)"

#: sub-command -> (socket command, help)
_SIMPLE = {
    "ping": ("ping", "is the daemon alive?"),
    "status": ("status", "loop state"),
    "timing": ("timing", "cycle timing statistics"),
    "faults": ("faults", "latched and past faults"),
    "reset": ("fault.reset", "reset the latched fault"),
    "enable": ("controller.enable", "enable K∞ (bumpless)"),
    "disable": ("controller.disable", "disable K∞ (bumpless)"),
    "stop": ("experiment.stop", "stop the running experiment"),
    "experiment": ("experiment.status", "state of the current/last experiment"),
    "safe": ("safe", "safe state now: latch fault operator_safe (K∞ off, excitation off, "
                     "r_p,i = r0; `reset` to leave it)"),
}


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--socket", default=os.environ.get("RIGD_SOCKET", "/run/rigd/rigd.sock"),
                   help="control socket (default $RIGD_SOCKET or /run/rigd/rigd.sock)")
    p.add_argument("--timeout", type=float, default=10.0, help="reply timeout, s")
    sub = p.add_subparsers(dest="ctl_command", metavar="COMMAND", required=True)
    for name, (_, h) in _SIMPLE.items():
        s = sub.add_parser(name, help=h, description=h)
        s.add_argument("--json", action="store_true", help="print the raw JSON result")
    s = sub.add_parser("load", help="load a controller YAML (read by you, checked by the "
                                    "daemon: gain bound, closed loop)")
    s.add_argument("file")
    s.add_argument("--json", action="store_true")
    s = sub.add_parser("start", help="start an experiment from its YAML")
    s.add_argument("experiment")
    s.add_argument("--run-dir", help="output folder (default: the daemon's runs folder)")
    s.add_argument("--json", action="store_true")
    s = sub.add_parser("op", help="set the operating point: shaft speed Ω and pressure P_I")
    s.add_argument("omega_rpm", type=float, metavar="OMEGA_RPM")
    s.add_argument("p_inj_bar", type=float, metavar="P_INJ_BAR")
    s.add_argument("--json", action="store_true")


def _request(args: argparse.Namespace) -> tuple[str, dict]:
    c = args.ctl_command
    if c in _SIMPLE:
        return _SIMPLE[c][0], {}
    # the files are read here, with the caller's rights, and sent: the daemon opens none
    if c == "load":
        from rigd.service.client import controller_args

        return "controller.load", controller_args(args.file)
    if c == "start":
        from rigd.service.client import experiment_args

        req = experiment_args(args.experiment)
        if args.run_dir:
            req["run_dir"] = os.path.abspath(args.run_dir)
        return "experiment.start", req
    if c == "op":
        return "operating_point.set", {"omega_rpm": args.omega_rpm, "p_inj_bar": args.p_inj_bar}
    raise InputError(f"unknown command {c!r}")  # pragma: no cover - argparse guards


def status_summary(st: dict) -> str:
    """Plain lines on top of ``rigd ctl status``: the fault, whether K∞ is really on, and
    the recorder's state."""
    f = st.get("fault") or {}
    if f.get("code"):
        fault = (f"FAULT {f.get('name')} latched at cycle {f.get('seq')}: {f.get('text')} "
                 f"(safe state; `rigd ctl reset` to clear)")
    else:
        fault = "no fault"
    c = st.get("controller") or {}
    blend = c.get("blend") or 0.0
    if not c.get("loaded"):
        k = "off (no controller loaded)"
    elif c.get("enabled"):
        k = "on" if blend >= 1.0 else f"switching on (blend {blend:.2f})"
    elif c.get("requested") and f.get("code"):
        k = "OFF: tripped by the fault (it was enabled; after a reset enable it again)"
    else:
        k = "off" if blend <= 0.0 else f"switching off (blend {blend:.2f})"
    state = "running" if st.get("running") else "stopped"
    age = st.get("age_s")
    if st.get("stalled"):
        state = (f"STALLED (no cycle for {age:.3f} s, stall bound "
                 f"{(st.get('stall_bound_s') or 0) * 1e3:g} ms)")
    elif age is not None:
        state += f" (last cycle {age * 1e3:.1f} ms ago)"
    return f"state: {state}, cycle {st.get('seq')}, {fault}\nK∞: {k}" + _recorder_line(st)


def _recorder_line(st: dict) -> str:
    """A third line: the recorder's state (a failed recording stays said after a reset)."""
    r = st.get("recorder") or {}
    if "state" not in r:
        return ""
    f = r.get("failure") or {}
    if r["state"] == "failed":
        return (f"\nrecorder: FAILED since {f.get('since')}: {f.get('why')}"
                + (" (that recording is dead until rigd restarts)" if f.get("open_ended")
                   else ""))
    files = r.get("files") or []
    return "\nrecorder: " + (f"recording {', '.join(files)}" if files else "idle")


def format_human(value, indent: int = 0) -> str:
    """Readable ``key: value`` lines for nested dicts/lists."""
    pad = "  " * indent
    if isinstance(value, dict):
        if not value:
            return pad + "(none)"
        lines = []
        for k, v in value.items():
            if isinstance(v, (dict, list)) and v:
                lines.append(f"{pad}{k}:")
                lines.append(format_human(v, indent + 1))
            else:
                lines.append(f"{pad}{k}: {_scalar(v)}")
        return "\n".join(lines)
    if isinstance(value, list):
        if not value:
            return pad + "(none)"
        out = []
        for item in value:
            if isinstance(item, dict):
                out.append(pad + "- " + ", ".join(f"{k}={_scalar(v)}" for k, v in item.items()))
            else:
                out.append(f"{pad}- {_scalar(item)}")
        return "\n".join(out)
    return pad + _scalar(value)


def _scalar(v) -> str:
    if isinstance(v, float):
        return f"{v:.6g}"
    if v is None:
        return "-"
    if isinstance(v, (dict, list)):
        return json.dumps(v)
    return str(v)


def _safe_by_word(args: argparse.Namespace) -> tuple[dict | None, str]:
    """SAFE through the daemon's SAFE word (no socket, no client slot): ``(result, "")``, or
    ``(None, why not)`` to go by the socket instead."""
    from rigd.service.safe_request import SafeWordClient, SafeWordUnavailable

    try:
        word = SafeWordClient(args.socket)
    except SafeWordUnavailable as exc:
        return None, str(exc)
    try:
        pid = word.daemon_pid
        if pid and not _alive(pid):
            raise DaemonGone(f"SAFE was NOT taken: the daemon (pid {pid}) of this SAFE word "
                             f"is not running (it ended); the valves are wherever the "
                             f"front-end's own host timeout left them", word.path)
        result = word.safe(args.timeout, alive=(lambda: _alive(pid)) if pid else None)
    finally:
        word.close()
    if result is None:
        if pid and not _alive(pid):
            raise DaemonGone(f"SAFE was NOT taken: the daemon (pid {pid}) ended while the "
                             f"request waited", word.path)
        return None, f"{word.path}: no cycle took the request within {args.timeout:g} s " \
                     f"(is the loop running?)"
    return result, ""


def _alive(pid: int) -> bool:
    """Whether process ``pid`` exists (a process of another user counts as alive)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def run(args: argparse.Namespace) -> int:
    from rigd.service.client import ControlClient

    cmd, req = _request(args)
    result, why = _safe_by_word(args) if args.ctl_command == "safe" else (None, "")
    if result is None:
        try:
            with ControlClient(args.socket, timeout=args.timeout) as client:
                reply = client.request(cmd, **req)
        except InputError as exc:
            if args.ctl_command == "safe":
                # neither the word nor the socket took it: say so, never leave it implied
                raise DaemonGone(f"SAFE was NOT taken: {exc}" + (f" (SAFE word: {why})"
                                                                 if why else "")) from None
            raise
        if not reply.get("ok"):
            if args.ctl_command == "safe":
                raise InputError(f"SAFE was NOT taken: {reply.get('error', 'refused')}"
                                 + (f" (SAFE word: {why})" if why else ""), "daemon")
            raise InputError(reply.get("error", "refused") + (f" (SAFE word: {why})"
                                                              if why else ""), "daemon")
        result = reply.get("result")
    if args.json:
        print(json.dumps(result, indent=None, separators=(",", ":")))
    elif args.ctl_command == "status":
        print(status_summary(result))
        print(format_human(result))
    elif args.ctl_command == "safe":
        f = result.get("fault") or {}
        at = (f", taken at cycle {result['latched_at']} (requested at cycle "
              f"{result['requested_at']}, via the {result.get('via', 'socket')})"
              if "latched_at" in result else "")
        print(f"safe state: FAULT {f.get('name')} latched at cycle {f.get('seq')}{at} (K∞ off, "
              f"excitation off, r_p,i = r0; `rigd ctl reset` to leave it)")
    elif args.ctl_command == "ping":
        print(f"rigd alive (pid {result.get('pid', '?')}, version {result.get('version', '?')})")
    else:
        print(format_human(result))
    sys.stdout.flush()
    return 0
