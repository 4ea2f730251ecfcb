"""The control-socket protocol: JSON lines, request parsing/validation and replies.

One JSON object per line each way (UTF-8, ``\\n`` terminated, at most
:data:`MAX_LINE` bytes). A request is ``{"id": <any JSON>, "cmd": "<name>", ...arguments}``;
the reply echoes the id::

    {"id": 7, "ok": true, "result": {...}}
    {"id": 7, "ok": false, "error": "operating_point.set: omega_rpm: Input should be ..."}

Commands and their arguments are the table :data:`COMMANDS` (also in docs/service.md).
Arguments are validated by a pydantic model per command before anything reaches the loop;
unknown keys, wrong types and non-finite numbers are refused with one line naming the command
and the argument.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from typing import Any

from pydantic import Field, ValidationError, field_validator, model_validator

from rigd.configio import StrictModel
from rigd.errors import FaultError, InputError
from rigd.frame import REC, RECORD_NAMES
from rigd.plain import plain

#: Longest accepted request line, bytes (a longer one is refused and the client dropped).
MAX_LINE = 64 * 1024


class NoArgs(StrictModel):
    """A command without arguments."""


class LoadArgs(StrictModel):
    path: str = Field(min_length=1, description="absolute path of a controller YAML")


class OperatingPointArgs(StrictModel):
    omega_rpm: float = Field(ge=0.0, le=100000.0, allow_inf_nan=False, description="Ω, rpm")
    p_inj_bar: float = Field(ge=0.0, le=50.0, allow_inf_nan=False, description="P_I, bar")


class ExperimentArgs(StrictModel):
    path: str | None = Field(None, min_length=1, description="experiment YAML (absolute)")
    spec: dict[str, Any] | None = Field(None, description="experiment spec inline")
    run_dir: str | None = Field(None, min_length=1, description="output folder (absolute)")

    @model_validator(mode="after")
    def _one_source(self):
        if (self.path is None) == (self.spec is None):
            raise ValueError("give exactly one of 'path' or 'spec'")
        return self


class StreamArgs(StrictModel):
    rate_hz: float = Field(50.0, ge=10.0, le=100.0, allow_inf_nan=False,
                           description="updates per second")
    points: int = Field(200, ge=1, le=2000, description="most min/max points per channel "
                                                         "per update")
    channels: list[str] | None = Field(None, min_length=1, max_length=len(RECORD_NAMES),
                                       description="record channels (default: all)")

    @field_validator("channels")
    @classmethod
    def _known(cls, channels):
        if channels is not None:
            bad = [c for c in channels if c not in REC]
            if bad:
                raise ValueError(f"unknown channel {bad[0][:40]!r} (known: "
                                 f"{', '.join(RECORD_NAMES)})")
            if len(set(channels)) != len(channels):
                raise ValueError("a channel is named twice")
        return channels


#: command name -> (argument model, one-line help)
COMMANDS: dict[str, tuple[type[StrictModel], str]] = {
    "ping": (NoArgs, "liveness check; returns pid and version"),
    "status": (NoArgs, "loop state: running, cycle, controller, operating point, fault"),
    "timing": (NoArgs, "cycle timing statistics (compute/lateness percentiles, overruns)"),
    "faults": (NoArgs, "latched and past faults"),
    "fault.reset": (NoArgs, "reset the latched fault (leaves the safe state)"),
    "controller.enable": (NoArgs, "blend K∞ in (bumpless)"),
    "controller.disable": (NoArgs, "blend K∞ out (bumpless)"),
    "controller.load": (LoadArgs, "load a controller YAML (validated first)"),
    "operating_point.set": (OperatingPointArgs, "set shaft speed Ω and injection pressure P_I"),
    "experiment.start": (ExperimentArgs, "start an experiment in the background"),
    "experiment.status": (NoArgs, "state of the current/last experiment"),
    "experiment.stop": (NoArgs, "stop the running experiment"),
    "safe": (NoArgs, "safe state now: latch fault operator_safe (K∞ off, excitation off, "
                     "r_p,i = r0), stop the experiment"),
    "stream.subscribe": (StreamArgs, "push min/max-decimated recent frames on this "
                                     "connection (served by the socket process)"),
}


class RequestError(Exception):
    """A request the daemon refuses; becomes an ``ok: false`` reply."""

    def __init__(self, message: str, req_id: Any = None):
        super().__init__(message)
        self.req_id = req_id


def encode(obj: dict[str, Any]) -> bytes:
    """One JSON line (``\\n`` terminated), strict JSON (no NaN)."""
    return (json.dumps(plain(obj), separators=(",", ":"), allow_nan=False) + "\n").encode()


def ok(req_id: Any, result: Any) -> bytes:
    return encode({"id": req_id, "ok": True, "result": result})


def error(req_id: Any, message: str) -> bytes:
    return encode({"id": req_id, "ok": False, "error": " ".join(str(message).split())})


def parse_request(line: bytes | str) -> tuple[Any, str, StrictModel]:
    """Parse and validate one request line.

    Returns
    -------
    (id, cmd, args)
        ``args`` is the validated argument model of the command.

    Raises
    ------
    RequestError
        Not JSON, not an object, no/unknown ``cmd``, or bad arguments (with the request id
        when one could be read).
    """
    if isinstance(line, bytes):
        try:
            line = line.decode("utf-8")
        except UnicodeDecodeError:
            raise RequestError("request is not UTF-8") from None
    try:
        req = json.loads(line)
    except (json.JSONDecodeError, RecursionError) as exc:
        raise RequestError(f"request is not JSON: {getattr(exc, 'msg', exc)}") from None
    if not isinstance(req, dict):
        raise RequestError("request must be a JSON object")
    req_id = req.pop("id", None)
    if isinstance(req_id, (dict, list)):
        req_id = None  # only scalar ids are echoed
    cmd = req.pop("cmd", None)
    if not isinstance(cmd, str):
        raise RequestError("request has no 'cmd' string", req_id)
    if cmd not in COMMANDS:
        raise RequestError(f"unknown command {cmd[:40]!r} (known: {', '.join(COMMANDS)})",
                           req_id)
    model = COMMANDS[cmd][0]
    try:
        args = model.model_validate(req)
    except ValidationError as exc:
        e = exc.errors()[0]
        loc = ".".join(str(p) for p in e["loc"]) or "arguments"
        msg = "unknown argument" if e["type"] == "extra_forbidden" else e["msg"]
        msg = msg.removeprefix("Value error, ")
        raise RequestError(f"{cmd}: {loc}: {msg}", req_id) from None
    return req_id, cmd, args


class Dispatcher:
    """Map validated requests to the loop's command methods and the experiment manager.

    Parameters
    ----------
    loop : object
        The running loop (:class:`rigd.loop.ControlLoop` API: ``status``, ``timing``,
        ``faults``, ``reset_fault``, ``enable_controller``, ``load_controller``,
        ``set_operating_point``).
    experiments : object, optional
        ``start(path=, spec=, run_dir=)``, ``status()``, ``stop()``; without it the
        ``experiment.*`` commands reply an error.
    info : callable, optional
        Extra fields for ``ping`` (pid, version, uptime).
    """

    def __init__(self, loop: Any, experiments: Any = None,
                 info: Callable[[], dict] | None = None, cache_s: float = 0.0):
        self.loop = loop
        #: read-only answers (status, timing, faults) are reused for this long, s: a flood of
        #: queries then costs the loop's process a bounded amount of work (see docs/service.md)
        self.cache_s = cache_s
        self._cache: dict[str, tuple[float, Any]] = {}
        self.experiments = experiments
        self.info = info or (lambda: {})
        self.served = 0
        self.refused = 0

    def handle_line(self, line: bytes) -> bytes:
        """Parse, run and answer one request line; never raises."""
        req_id = None
        try:
            req_id, cmd, args = parse_request(line)
            result = self.run(cmd, args)
            self.served += 1
            return ok(req_id, result)
        except RequestError as exc:
            self.refused += 1
            return error(exc.req_id if exc.req_id is not None else req_id, str(exc))
        except (InputError, FaultError, ValueError) as exc:
            self.refused += 1
            return error(req_id, str(exc))
        except Exception as exc:  # a bug must not kill the server: report it to the client
            self.refused += 1
            return error(req_id, f"internal error: {type(exc).__name__}: {exc}")

    def run(self, cmd: str, args: StrictModel) -> Any:
        loop = self.loop
        if cmd == "ping":
            return {"pong": True, **self.info()}
        if cmd == "status":
            return self._cached(cmd, loop.status)
        if cmd == "timing":
            return self._cached(cmd, loop.timing)
        if cmd == "faults":
            return self._cached(cmd, lambda: {"faults": loop.faults()})
        if cmd == "stream.subscribe":
            raise RequestError(f"{cmd}: served by the socket process only")
        self._cache.clear()  # a command changes the state: the next query is fresh
        if cmd == "safe":
            return self._safe()
        if cmd == "fault.reset":
            self._applied(cmd, loop.reset_fault())
            return {"reset": True}
        if cmd in ("controller.enable", "controller.disable"):
            self._applied(cmd, loop.enable_controller(cmd == "controller.enable"))
            return {"enabled": cmd == "controller.enable"}
        check_paths(cmd, args)
        if cmd == "controller.load":
            path = args.path
            self._applied(cmd, loop.load_controller(path))
            return {"loaded": path}
        if cmd == "operating_point.set":
            self._applied(cmd, loop.set_operating_point(args.omega_rpm, args.p_inj_bar))
            return {"omega_rpm": args.omega_rpm, "p_inj_bar": args.p_inj_bar}
        if self.experiments is None:
            raise RequestError(f"{cmd}: experiments are not available in this daemon")
        if cmd == "experiment.start":
            return self.experiments.start(path=args.path, spec=args.spec, run_dir=args.run_dir)
        if cmd == "experiment.status":
            return self.experiments.status()
        if cmd == "experiment.stop":
            return self.experiments.stop()
        raise RequestError(f"unknown command {cmd!r}")  # pragma: no cover - table-driven


    def _applied(self, cmd: str, ticket: Any) -> None:
        """Reply only once the loop has applied the command (its ``status`` shows it then);
        a loop that runs cycles but does not apply it in time is an error reply. A loop
        double without tickets (``None``) or a loop not running cycles replies at once."""
        wait = getattr(self.loop, "wait_applied", None)
        if wait is None or ticket is None:
            return
        if not wait(ticket) and self.loop.running:
            raise RequestError(f"{cmd}: queued, but the loop has not applied it yet (is it "
                               f"running? `status` shows when it does)")
        self._cache.clear()   # a query answered while we waited must not outlive the change

    def _safe(self, confirm_s: float = 2.0) -> dict[str, Any]:
        """Latch ``operator_safe`` (the loop's safe state from its next cycle), stop the
        experiment, and wait until the loop shows a latched fault (any: the first one wins).
        """
        from rigd.loop import faults as FC

        self.loop.trip(FC.OPERATOR_SAFE)
        if self.experiments is not None:
            self.experiments.stop()
        end = time.monotonic() + confirm_s
        while True:
            f = self.loop.status().get("fault", {})
            if f.get("code"):
                return {"safe": True, "fault": {k: f.get(k) for k in ("code", "name", "text",
                                                                       "seq")}}
            if time.monotonic() > end:
                raise RequestError(f"safe: requested, but the loop did not confirm a latched "
                                   f"fault within {confirm_s:g} s (is it running?)")
            time.sleep(0.002)

    def _cached(self, key: str, fn: Callable[[], Any]) -> Any:
        if self.cache_s <= 0:
            return fn()
        now = time.monotonic()
        hit = self._cache.get(key)
        if hit is not None and now - hit[0] < self.cache_s:
            return hit[1]
        value = fn()
        self._cache[key] = (now, value)
        return value


def check_paths(cmd: str, args: StrictModel) -> None:
    """Paths in a request must be absolute (the daemon's working directory is not the
    client's); RequestError otherwise. Part of validation: run before anything reaches the
    loop (also by the socket process)."""
    for name in ("path", "run_dir"):
        value = getattr(args, name, None)
        if value is not None:
            _absolute(value, f"{cmd}: {name}")


def _absolute(path: str, where: str) -> str:
    import os

    if not os.path.isabs(path):
        raise RequestError(f"{where}: must be an absolute path (got {path!r})")
    return path
