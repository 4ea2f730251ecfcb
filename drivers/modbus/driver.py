"""Slow driver for the rig's Modbus devices (pymodbus; TCP or RTU): P_I, Ω, setpoints.

A PLC or regulator exposes the slow channels; the driver polls them at ``poll_hz`` (10–100 Hz)
in its own thread and publishes the latest values as one immutable :class:`SlowSample`, which
the loop picks up without locking or waiting (:meth:`ModbusDriver.latest`, or
:meth:`ModbusDriver.fill` which writes ``IN_OMEGA``/``IN_P_INJ`` into the input frame).
Setpoints (``write_setpoints``) are queued and written by the same thread, never by the caller.

Register map (defaults; every address is configurable, see docs/drivers.md)::

    input registers (FC 4, read)         holding registers (FC 3 read, FC 16 write)
    0-1  P_I, injection pressure  bar    100-101  P_I setpoint      bar
    2-3  Ω, shaft speed           rpm    102-103  Ω setpoint        rpm
    4    status word (0 = healthy)

Values are IEEE-754 float32 in two registers, high word first (``word_order: big``, the
Modbus convention) or low word first (``little``).

Health: ``failures_to_fault`` consecutive failed polls (timeout, refused connection, Modbus
exception) mark the sample ``ok = False`` (the loop latches a fault) — from the first poll on,
so one late first answer after a connect is not a fault either; the thread keeps
reconnecting every ``reconnect_s`` and the sample is ``ok`` again when the device answers.
"""

from __future__ import annotations

import struct
import threading
import time
from dataclasses import dataclass
from typing import ClassVar, Literal

import numpy as np
from pydantic import Field, model_validator

from rigd.configio import StrictModel
from rigd.driver import SlowDriver
from rigd.errors import FaultError
from rigd.frame import IN_OMEGA, IN_P_INJ


class ModbusRegisters(StrictModel):
    """Register addresses (0-based PDU addresses)."""

    p_inj: int = Field(0, ge=0, le=65534, description="input register of P_I (float32)")
    omega: int = Field(2, ge=0, le=65534, description="input register of Ω (float32)")
    status: int | None = Field(4, ge=0, le=65535, description="input register, 0 = healthy")
    p_inj_setpoint: int | None = Field(100, ge=0, le=65534, description="holding, float32")
    omega_setpoint: int | None = Field(102, ge=0, le=65534, description="holding, float32")


class ModbusOptions(StrictModel):
    """``drivers.modbus`` section of the rig config."""

    transport: Literal["tcp", "rtu"] = "tcp"
    host: str | None = Field(None, description="TCP: PLC address")
    port: int = Field(502, gt=0, le=65535, description="TCP port")
    device: str | None = Field(None, description="RTU: serial device, e.g. /dev/ttyUSB0")
    baudrate: int = Field(19200, gt=0, description="RTU baud rate")
    parity: Literal["N", "E", "O"] = "E"
    stopbits: Literal[1, 2] = 1
    unit_id: int = Field(1, ge=0, le=247, description="Modbus device (slave) id")
    timeout_s: float = Field(0.05, gt=0, le=5.0, description="reply timeout, s")
    reconnect_s: float = Field(0.5, gt=0, description="retry period while unreachable, s")
    failures_to_fault: int = Field(3, ge=1, description="consecutive failed polls -> fault")
    word_order: Literal["big", "little"] = "big"
    registers: ModbusRegisters = Field(default_factory=ModbusRegisters)

    @model_validator(mode="after")
    def _where(self):
        if self.transport == "tcp" and not self.host:
            raise ValueError("transport 'tcp' needs 'host'")
        if self.transport == "rtu" and not self.device:
            raise ValueError("transport 'rtu' needs 'device'")
        return self


@dataclass(frozen=True)
class SlowSample:
    """Latest slow-channel values (published as a whole: readers never see a mix)."""

    t: float = 0.0               # time.monotonic() of the poll, s
    p_inj_bar: float = float("nan")
    omega_rpm: float = float("nan")
    status: int = 0              # device status word
    ok: bool = False             # False until the first good poll, and after a fault
    error: str = "not polled yet"


def regs_to_float(regs, word_order: str = "big") -> float:
    hi, lo = (regs[0], regs[1]) if word_order == "big" else (regs[1], regs[0])
    return struct.unpack(">f", struct.pack(">HH", hi, lo))[0]


def float_to_regs(value: float, word_order: str = "big") -> list[int]:
    hi, lo = struct.unpack(">HH", struct.pack(">f", float(value)))
    return [hi, lo] if word_order == "big" else [lo, hi]


class ModbusDriver(SlowDriver):
    """Poll P_I and Ω (and write their setpoints) over Modbus TCP or RTU."""

    name = "modbus"
    Options: ClassVar[type[StrictModel]] = ModbusOptions

    def __init__(self, options=None, *, fs: float = 5000.0):
        super().__init__(options, fs=fs)
        self.opts = options if isinstance(options, ModbusOptions) else \
            ModbusOptions.model_validate(options or {})
        # the poll rate is the config's drivers.slow[i].poll_hz (set by the loop builder)
        self._client = None
        self._sample = SlowSample()
        self._pending: dict[str, float] = {}
        self._pending_lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._fails = 0
        self._next_connect = 0.0
        #: why the device was last found down (the retry-wait message says it)
        self._why_down = "not connected yet"
        self.n_polls = 0
        self.n_errors = 0
        self.n_faults = 0
        self.n_reconnects = 0
        self.n_setpoints = 0
        self._was_down = False

    # --- connection ---------------------------------------------------------------------
    def _make_client(self):
        from pymodbus.client import ModbusSerialClient, ModbusTcpClient

        o = self.opts
        if o.transport == "tcp":
            return ModbusTcpClient(o.host, port=o.port, timeout=o.timeout_s, retries=0,
                                   reconnect_delay=0)
        return ModbusSerialClient(o.device, baudrate=o.baudrate, parity=o.parity,
                                  stopbits=o.stopbits, timeout=o.timeout_s, retries=0,
                                  reconnect_delay=0)

    def _ensure_connected(self) -> None:
        c = self._client
        if c is not None and c.connected:
            return
        now = time.monotonic()
        if now < self._next_connect:
            # the loss in words, also between retries: where, and why the last try failed
            raise FaultError(f"modbus: {self._where()}: not connected ({self._why_down}; "
                             f"next try within {self.opts.reconnect_s:g} s)")
        self._next_connect = now + self.opts.reconnect_s
        if c is None:
            c = self._client = self._make_client()
        if not c.connect():
            self._why_down = "the connection was refused or timed out"
            raise FaultError(f"modbus: cannot connect to {self._where()}")

    def _where(self) -> str:
        o = self.opts
        return f"{o.host}:{o.port}" if o.transport == "tcp" else str(o.device)

    def _drop(self) -> None:
        if self._client is not None:
            try:
                self._client.close()
            except Exception:  # noqa: BLE001
                pass

    # --- SlowDriver API -------------------------------------------------------------------
    def poll(self) -> dict[str, float]:
        """Read P_I, Ω and the status word once (blocks up to ``timeout_s``), send queued
        setpoints, and publish the result as :meth:`latest`.

        Called by the loop's slow-driver thread (``ControlLoop``), or by this driver's own
        thread after :meth:`start_polling` when used stand-alone. Not thread-safe: one
        polling thread only.

        Returns
        -------
        dict
            The values; empty while the device has not answered yet and fewer than
            ``failures_to_fault`` polls in a row have failed (the same grace as after a good
            poll: one late first answer after a connect is not a fault).

        Raises
        ------
        FaultError
            ``failures_to_fault`` polls in a row failed (unreachable, timeout, Modbus error),
            or the device reports a non-zero status.
        """
        s = self.poll_once()
        if not s.ok:
            if s.t == 0.0 and 0 < self._fails < self.opts.failures_to_fault:
                return {}    # never answered yet, not down yet
            raise FaultError(s.error)
        return {"p_inj_bar": s.p_inj_bar, "omega_rpm": s.omega_rpm, "status": float(s.status)}

    def _read(self) -> dict[str, float]:
        from pymodbus.exceptions import ModbusException

        self._ensure_connected()
        r = self.opts.registers
        o = self.opts
        try:
            lo = min(r.p_inj, r.omega, r.status if r.status is not None else r.p_inj)
            hi = max(r.p_inj + 2, r.omega + 2, (r.status + 1) if r.status is not None else 0)
            if hi - lo <= 16:  # one request for the whole block
                rr = self._client.read_input_registers(lo, count=hi - lo, device_id=o.unit_id)
                if rr.isError():
                    raise FaultError(f"modbus: {self._where()}: {rr}")
                regs = rr.registers
                get = lambda a, n: regs[a - lo:a - lo + n]  # noqa: E731
            else:
                def get(a, n):
                    rr = self._client.read_input_registers(a, count=n, device_id=o.unit_id)
                    if rr.isError():
                        raise FaultError(f"modbus: {self._where()}: {rr}")
                    return rr.registers
            out = {"p_inj_bar": regs_to_float(get(r.p_inj, 2), o.word_order),
                   "omega_rpm": regs_to_float(get(r.omega, 2), o.word_order),
                   "status": float(get(r.status, 1)[0]) if r.status is not None else 0.0}
            self._send_setpoints()
        except ModbusException as exc:
            self._drop()
            self._why_down = str(exc)
            raise FaultError(f"modbus: {self._where()}: {exc}") from None
        except OSError as exc:
            self._drop()
            self._why_down = str(exc)
            raise FaultError(f"modbus: {self._where()}: {exc}") from None
        return out

    def write_setpoints(self, **setpoints: float) -> None:
        """Queue setpoints (``p_inj_bar``, ``omega_rpm``); written by the polling thread."""
        unknown = set(setpoints) - {"p_inj_bar", "omega_rpm"}
        if unknown:
            raise NotImplementedError(f"modbus driver has no setpoint {sorted(unknown)}")
        with self._pending_lock:
            self._pending.update({k: float(v) for k, v in setpoints.items()})

    def _send_setpoints(self) -> None:
        with self._pending_lock:
            pending, self._pending = self._pending, {}
        r, o = self.opts.registers, self.opts
        try:
            for key, addr in (("p_inj_bar", r.p_inj_setpoint), ("omega_rpm", r.omega_setpoint)):
                if key in pending and addr is not None:
                    wr = self._client.write_registers(addr, float_to_regs(pending[key],
                                                                          o.word_order),
                                                      device_id=o.unit_id)
                    if wr.isError():
                        raise FaultError(f"modbus: setpoint {key}: {wr}")
                    self.n_setpoints += 1
                    del pending[key]
        finally:
            if pending:  # not sent: retry next poll (unless newer values arrived)
                with self._pending_lock:
                    for k, v in pending.items():
                        self._pending.setdefault(k, v)

    # --- the polling thread -----------------------------------------------------------
    def open(self) -> None:
        """Make the client and connect once, before the loop starts (blocks up to
        ``timeout_s``): the first poll is then a plain read, not pymodbus's import and a
        connect. A device that is down is not a start-up failure: the first poll fails and the
        loop latches ``slow_driver`` then (the connect is retried every ``reconnect_s``)."""
        self._client = self._make_client()
        try:
            self._client.connect()   # False when down: the first poll tries again, then faults
        except Exception:  # noqa: BLE001 - reported by the first poll, as any outage
            pass

    def start_polling(self) -> None:
        """Poll in this driver's own thread at ``poll_hz`` (stand-alone use; the loop has its
        own slow-driver threads and must not be combined with this)."""
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, name="modbus-poll", daemon=True)
        self._thread.start()

    def on_deactivate(self, safe_drive) -> None:
        """Drop setpoints not yet sent: nothing reaches the regulators after the loop stops
        commanding (the device keeps its last setpoints; polling goes on until cleanup)."""
        with self._pending_lock:
            self._pending.clear()

    def close(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(5.0)
            self._thread = None
        self._drop()

    def _run(self) -> None:
        period = 1.0 / self.poll_hz
        nxt = time.monotonic()
        while not self._stop.is_set():
            self.poll_once()  # never raises
            nxt += period
            delay = nxt - time.monotonic()
            if delay < 0:
                nxt = time.monotonic()
                delay = 0
            self._stop.wait(delay)

    def poll_once(self) -> SlowSample:
        """One poll with fault bookkeeping; publishes and returns the new sample (no raise)."""
        now = time.monotonic()
        prev = self._sample
        try:
            v = self._read()
        except FaultError as exc:
            self.n_errors += 1
            self._fails += 1
            down = self._fails >= self.opts.failures_to_fault
            if down and prev.ok:
                self.n_faults += 1
            if down:
                self._was_down = True
            s = SlowSample(prev.t, prev.p_inj_bar, prev.omega_rpm, prev.status,
                           ok=prev.ok and not down, error=str(exc))
        else:
            self.n_polls += 1
            if self._was_down:
                self.n_reconnects += 1
                self._was_down = False
            self._fails = 0
            st = int(v["status"])
            s = SlowSample(now, v["p_inj_bar"], v["omega_rpm"], st, ok=(st == 0),
                           error="" if st == 0 else f"modbus: device status word {st:#06x}")
        self._sample = s  # one reference assignment: atomic for readers
        return s

    def latest(self) -> SlowSample:
        """The latest sample; never blocks."""
        return self._sample

    def fill(self, frame_in: np.ndarray) -> bool:
        """Write the latest Ω and P_I into ``frame_in``; returns the sample's ``ok``."""
        s = self._sample
        frame_in[IN_OMEGA] = s.omega_rpm
        frame_in[IN_P_INJ] = s.p_inj_bar
        return s.ok

    @property
    def healthy(self) -> bool:
        return self._sample.ok

    def counters(self) -> dict[str, int]:
        return {"polls": self.n_polls, "errors": self.n_errors, "faults": self.n_faults,
                "reconnects": self.n_reconnects, "setpoints_written": self.n_setpoints}
