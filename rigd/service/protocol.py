"""The control-socket protocol: JSON lines, request parsing/validation and replies.

One JSON object per line each way (UTF-8, ``\\n`` terminated, at most
:data:`MAX_LINE` bytes). A request is ``{"id": <any JSON>, "cmd": "<name>", ...arguments}``;
the reply echoes the id::

    {"id": 7, "ok": true, "result": {...}}
    {"id": 7, "ok": false, "error": "operating_point.set: omega_rpm: Input should be ..."}

Commands and their arguments are the table :data:`COMMANDS` (also in docs/service.md).
Arguments are validated by a pydantic model per command (strict mode: no coercion, so
``"3000"`` and ``true`` are not numbers) before anything reaches the loop; unknown keys, wrong
types, non-finite numbers and requests nested deeper than :data:`MAX_DEPTH` are refused with
one line naming the command and the argument.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from typing import Any

from pydantic import ConfigDict, Field, ValidationError, field_validator, model_validator

from rigd.bounded import confined
from rigd.configio import StrictModel
from rigd.errors import FaultError, InputError
from rigd.frame import REC, RECORD_NAMES
from rigd.plain import plain

#: Longest accepted request line, bytes (a longer one is refused and the client dropped).
MAX_LINE = 64 * 1024
#: Deepest accepted nesting of a request (objects and arrays), levels
MAX_DEPTH = 16


class Args(StrictModel):
    """Base of the argument models: unknown keys refused, strict types (no coercion: a string
    or a boolean is not a number, a number is not a string)."""

    model_config = ConfigDict(extra="forbid", strict=True, validate_assignment=True)


class NoArgs(Args):
    """A command without arguments."""


class WireMatrix(Args):
    shape: list[int] = Field(min_length=2, max_length=2, description="[rows, cols]")
    f64: str = Field(max_length=MAX_LINE, description="base64 of little-endian float64, "
                                                       "row-major")


class WirePlant(Args):
    A: WireMatrix
    B: WireMatrix
    C: WireMatrix
    D: WireMatrix


class WireController(WirePlant):
    """A controller's content as the client read it (rigd.controller.to_wire)."""

    fs_hz: float = Field(gt=0, allow_inf_nan=False, description="controller rate, Hz")
    design_plant: WirePlant | None = None


class LoadArgs(Args):
    path: str = Field(min_length=1, description="absolute path of the client's controller "
                                                "file: its name in status (never opened)")
    controller: WireController | None = Field(None, description="the file's content, read "
                                              "by the client (`rigd ctl load` sends it)")


class OperatingPointArgs(Args):
    omega_rpm: float = Field(ge=0.0, le=100000.0, allow_inf_nan=False, description="Ω, rpm")
    p_inj_bar: float = Field(ge=0.0, le=50.0, allow_inf_nan=False, description="P_I, bar")


class ExperimentArgs(Args):
    path: str | None = Field(None, min_length=1, description="the client's experiment YAML "
                             "(absolute): its name, with its content in 'text' (never opened)")
    text: str | None = Field(None, description="the experiment file's content, read by the "
                             "client (`rigd ctl start` sends it)")
    spec: dict[str, Any] | None = Field(None, description="experiment spec inline")
    run_dir: str | None = Field(None, min_length=1, description="output folder (absolute)")

    @model_validator(mode="after")
    def _one_source(self):
        if (self.path is None) == (self.spec is None):
            raise ValueError("give exactly one of 'path' (with 'text') or 'spec'")
        if self.text is not None and self.path is None:
            raise ValueError("'text' needs 'path' (its file's name)")
        return self


class StreamArgs(Args):
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
COMMANDS: dict[str, tuple[type[Args], str]] = {
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


#: the commands that act on the rig (not queries, not the stream): what the connections kept
#: beyond ``max_clients`` take when every slot is held (rigd.service.server.RESERVED)
CONTROL = ("safe", "fault.reset", "controller.enable", "controller.disable", "controller.load",
           "operating_point.set", "experiment.start", "experiment.stop")

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
    """Parse and validate one request line: ``(id, cmd, args)`` of :func:`parse_envelope`."""
    return parse_envelope(line)[:3]


#: longest ``timeout_s`` a request may give, s
MAX_TIMEOUT_S = 3600.0


def parse_envelope(line: bytes | str) -> tuple[Any, str, StrictModel, float | None]:
    """Parse and validate one request line.

    Besides ``id`` and ``cmd`` a request may carry ``timeout_s`` (a number, 0 < t <= 3600):
    how long its client waits for the reply. A command not applied by then is dropped, never
    applied later (the client sends a little less than its own wait, so that the daemon's
    "dropped" reply reaches it).

    Returns
    -------
    (id, cmd, args, timeout_s)
        ``args`` is the validated argument model of the command; ``timeout_s`` None when
        not given.

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
    except json.JSONDecodeError as exc:
        raise RequestError(f"request is not JSON: {exc.msg}") from None
    except RecursionError:
        raise RequestError(f"request nests deeper than {MAX_DEPTH} levels") from None
    if not isinstance(req, dict):
        raise RequestError("request must be a JSON object")
    if _depth(req) > MAX_DEPTH:
        raise RequestError(f"request nests deeper than {MAX_DEPTH} levels")
    req_id = req.pop("id", None)
    if isinstance(req_id, (dict, list)):
        req_id = None  # only scalar ids are echoed
    timeout_s = req.pop("timeout_s", None)
    if timeout_s is not None and (isinstance(timeout_s, bool)
                                  or not isinstance(timeout_s, (int, float))
                                  or not 0.0 < timeout_s <= MAX_TIMEOUT_S):
        raise RequestError(f"timeout_s: a number of seconds in (0, {MAX_TIMEOUT_S:g}]", req_id)
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
        msg = "unknown argument" if e["type"] == "extra_forbidden" else plain_error(e)
        raise RequestError(f"{cmd}: {loc}: {msg}", req_id) from None
    return req_id, cmd, args, (None if timeout_s is None else float(timeout_s))


def plain_error(e: dict[str, Any]) -> str:
    """One pydantic error (``ValidationError.errors()[0]``) in plain words, with the value
    given: ``must be <= 100000 (got 1e+09)`` rather than pydantic's own phrasing."""
    got = e.get("input")
    shown = repr(got) if not isinstance(got, float) else f"{got:g}"
    shown = shown if len(shown) <= 40 else shown[:37] + "..."
    ctx = e.get("ctx") or {}
    t = e.get("type", "")
    bounds = {"greater_than_equal": (">=", "ge"), "less_than_equal": ("<=", "le"),
              "greater_than": (">", "gt"), "less_than": ("<", "lt")}
    if t in bounds:
        op, key = bounds[t]
        lim = ctx.get(key)
        return f"must be {op} {lim:g} (got {shown})" if isinstance(lim, (int, float)) \
            else f"must be {op} {lim} (got {shown})"
    if t == "finite_number":
        return f"must be a finite number (got {shown})"
    if t in ("float_type", "float_parsing", "int_type", "int_parsing", "int_from_float"):
        kind = "an integer" if t.startswith("int") else "a number"
        return f"must be {kind} (got {type(got).__name__} {shown})"
    if t == "missing":
        return "missing: this argument is required"
    if t in ("string_type", "bool_type", "dict_type", "list_type"):
        return f"must be a {t.removesuffix('_type')} (got {type(got).__name__} {shown})"
    return str(e.get("msg", "invalid")).removeprefix("Value error, ")


def _depth(obj: Any) -> int:
    """Nesting depth of parsed JSON (a scalar: 0), iteratively (no recursion to exhaust)."""
    deepest, todo = 0, [(obj, 1)]
    while todo:
        o, d = todo.pop()
        if isinstance(o, dict):
            o = o.values()
        elif not isinstance(o, list):
            continue
        deepest = max(deepest, d)
        if d <= MAX_DEPTH:          # deeper is refused anyway: no need to walk it all
            todo.extend((v, d + 1) for v in o)
    return deepest


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
    reads_files : bool
        True: ``controller.load`` and ``experiment.start`` without a payload read their file
        here (a dispatcher in a test or tool process). The daemon gives False: in the loop's
        process files are read by the socket process only (:mod:`rigd.service.reader`), and a
        command arrives with its *payload* (a packed controller, a validated experiment).
    """

    def __init__(self, loop: Any, experiments: Any = None,
                 info: Callable[[], dict] | None = None, cache_s: float = 0.0,
                 reads_files: bool = True):
        self.loop = loop
        self.reads_files = reads_files
        #: read-only answers (status, timing, faults) are reused for this long, s: a flood of
        #: queries then costs the loop's process a bounded amount of work (see docs/service.md)
        self.cache_s = cache_s
        self._cache: dict[str, tuple[float, Any]] = {}
        self.experiments = experiments
        self.info = info or (lambda: {})
        self.served = 0
        self.refused = 0
        self._gen: int | None = None
        self._deadline: float | None = None

    def handle_line(self, line: bytes, gen: int | None = None,
                    deadline: float | None = None, payload: Any = None) -> bytes:
        """Parse, run and answer one request line; never raises.

        ``gen`` is the loop's SAFE generation when the request arrived and ``deadline`` the
        ``time.monotonic()`` its caller stops waiting at: a command a SAFE overtook, or not
        applied by then, is dropped, never applied later, and the reply says so.
        ``payload``: what the socket process read and validated for the command (a packed
        controller for ``controller.load``, an Experiment for ``experiment.start``).
        """
        req_id = None
        try:
            req_id, cmd, args = parse_request(line)
            self._gen, self._deadline = gen, deadline
            result = self.run(cmd, args, payload)
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

    def run(self, cmd: str, args: StrictModel, payload: Any = None) -> Any:
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
        when = self._when()
        if cmd == "fault.reset":
            self._applied(cmd, loop.reset_fault(**when))
            return {"reset": True}
        if cmd in ("controller.enable", "controller.disable"):
            on = cmd == "controller.enable"
            if on:
                self._refuse_if_faulted(cmd)
            self._applied(cmd, loop.enable_controller(on, **when))
            return {"enabled": on}
        check_paths(cmd, args)
        check_content(cmd, args)
        if cmd in ("controller.load", "experiment.start") and payload is None \
                and not self.reads_files:
            raise RequestError(f"{cmd}: not read: files are read by the socket process, and "
                               f"this request did not come through it")
        if cmd == "controller.load":
            path = args.path
            if payload is None:       # in-process: the client's content, never its file
                from rigd.controller import from_wire

                ctrl = from_wire(args.controller.model_dump(), source=path,
                                 expected_fs_hz=getattr(loop, "fs", None))
            else:
                ctrl = unpack_controller(payload)
            self._applied(cmd, loop.load_controller(ctrl, **when))
            return {"loaded": path}
        if cmd == "operating_point.set":
            self._applied(cmd, loop.set_operating_point(args.omega_rpm, args.p_inj_bar,
                                                        **when))
            return {"omega_rpm": args.omega_rpm, "p_inj_bar": args.p_inj_bar}
        if self.experiments is None:
            raise RequestError(f"{cmd}: experiments are not available in this daemon")
        if cmd == "experiment.start":
            if payload is not None:
                return self.experiments.start(experiment=payload, run_dir=args.run_dir)
            # in-process only (tests, no socket process): the experiments object reads it
            return self.experiments.start(path=args.path, spec=args.spec, run_dir=args.run_dir)
        if cmd == "experiment.status":
            return self.experiments.status()
        if cmd == "experiment.stop":
            return self.experiments.stop()
        raise RequestError(f"unknown command {cmd!r}")  # pragma: no cover - table-driven


    def _when(self) -> dict[str, Any]:
        """The ``gen``/``deadline`` of the request being run, for the loop's commands."""
        if not hasattr(self.loop, "safe_generation"):
            return {}             # a loop double without them
        return {"gen": self._gen, "deadline": self._deadline}

    def _refuse_if_faulted(self, cmd: str) -> None:
        """``enable`` while a fault is latched is refused with the fault's text (the loop
        would drop it too: K∞ cannot come in while the safe state holds)."""
        from rigd.loop import faults as FC
        from rigd.loop import layout as L

        state = getattr(self.loop, "state", None)
        if state is None:
            return                # a loop double without kernel state
        st = state.st
        code = int(st[L.S_FAULT])
        if code:
            raise RequestError(f"{cmd}: refused: fault {FC.fault_name(code)} latched at cycle "
                               f"{int(st[L.S_FAULT_SEQ])}: "
                               f"{FC.describe(code, int(st[L.S_FAULT_DETAIL]))}; reset it "
                               f"first (`rigd ctl reset`), then enable")

    def _applied(self, cmd: str, ticket: Any) -> None:
        """Reply only once the loop has applied the command (its ``status`` shows it then).
        A command the loop dropped, or did not apply in time (it is then cancelled: never
        applied later), is an error reply saying so. A loop double without tickets
        (``None``) or a loop not running cycles replies at once."""
        wait = getattr(self.loop, "wait_applied", None)
        if wait is None or ticket is None:
            return
        timeout = None
        if self._deadline is not None:
            default = 2.0 + 2.0 * self.loop.config.loop.k_ramp_s
            timeout = max(0.0, min(default, self._deadline - time.monotonic()))
        applied = wait(ticket, timeout, cancel=True)
        self._cache.clear()   # a query answered while we waited must not outlive the change
        if applied:
            return
        why = getattr(ticket, "dropped", "")
        if why:
            raise RequestError(f"{cmd}: not applied, dropped: {why}; it will never be "
                               f"applied")
        if self.loop.running:
            raise RequestError(f"{cmd}: queued, but the loop has not applied it yet (is it "
                               f"running? `status` shows when it does)")

    def _safe(self, confirm_s: float = 2.0) -> dict[str, Any]:
        """Latch ``operator_safe`` (the loop's safe state from its next cycle), stop the
        experiment, and wait until the loop shows a latched fault (any: the first one wins).

        Through the loop's SAFE word (:mod:`rigd.loop.safeword`) when it has one: the reply
        then names the cycle the request was made at and the cycle it latched at.
        """
        from rigd.loop import faults as FC

        request = getattr(self.loop, "request_safe", None)
        if request is not None:
            c0 = request()
            if self.experiments is not None:
                self.experiments.stop()
            ack = self.loop.wait_safe(c0, confirm_s)
            if ack is None:
                raise RequestError(f"safe: requested, but the loop did not confirm a latched "
                                   f"fault within {confirm_s:g} s (is it running?)")
            return {"safe": True, "via": "daemon", **ack}
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


def unpack_controller(packed: dict[str, Any]):
    """A :class:`rigd.controller.Controller` from :func:`rigd.service.reader.pack_controller`'s
    arrays (the loop re-checks shapes, rate, finiteness and stability: cheap, no file)."""
    from rigd.controller import Controller

    return Controller(*(packed[k] for k in "ABCD"), float(packed["fs_hz"]),
                      str(packed["source"]))


def check_paths(cmd: str, args: StrictModel, runs_root: str | None = None) -> None:
    """Paths in a request must be absolute (the daemon's working directory is not the
    client's), and a ``run_dir`` inside ``runs_root`` (when given; symlinks resolved);
    RequestError otherwise. Part of validation: run before anything reaches the loop (by the
    socket process)."""
    for name in ("path", "run_dir"):
        value = getattr(args, name, None)
        if value is not None:
            _absolute(value, f"{cmd}: {name}")
    run_dir = getattr(args, "run_dir", None)
    if run_dir is not None and runs_root is not None:
        try:
            confined(run_dir, runs_root, f"{cmd}: run_dir")
        except InputError as exc:
            raise RequestError(str(exc)) from None


def check_content(cmd: str, args: StrictModel) -> None:
    """A ``controller.load`` or an ``experiment.start`` by path must carry the file's content
    (``controller`` / ``text``), read by the client with its own rights: the daemon opens no
    file a client names (a confused deputy would read for it what it may not read);
    RequestError otherwise."""
    if cmd == "controller.load" and args.controller is None:
        raise RequestError(f"{cmd}: the controller's content is missing ('controller'): the "
                           f"daemon opens no file a client names; `rigd ctl load FILE` "
                           f"reads the file and sends it")
    if cmd == "experiment.start" and args.path is not None and args.text is None:
        raise RequestError(f"{cmd}: the experiment file's content is missing ('text'): the "
                           f"daemon opens no file a client names; `rigd ctl start FILE` "
                           f"reads the file and sends it")


def _absolute(path: str, where: str) -> str:
    import os

    if not os.path.isabs(path):
        raise RequestError(f"{where}: must be an absolute path (got {path!r})")
    return path
