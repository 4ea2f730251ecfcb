"""Fast driver for the microcontroller front-end on a serial link (pyserial).

Protocol: :mod:`rigd_drivers.serial.protocol` (specification in docs/drivers.md). Each
``read`` takes the bytes waiting on the port without blocking, decodes every complete frame
into a small FIFO (numba, no allocation) and hands the *oldest* one to the loop, so that every
sample reaches the recording in order while the link jitters. Each ``write`` sends one drive
frame without blocking.

Jitter, not latency: a FIFO that empties now and then (USB delivers a burst of frames per
millisecond) absorbs the link's jitter, and one that shrinks is a host catching up after a
stall. A FIFO that neither empties nor shrinks in a window of ``lag_window`` reads (cycles;
consecutive blocks) holds frames the loop takes late, for good — after a burst (the
device or the host stalled, then caught up) one in and one out keeps the queue standing, and a
control loop fed frames k periods old is a control loop with k periods more delay (the valve
PD loop over the emulator goes unstable beyond about 6). Stale frames are worse than lost
ones: the frames that stood queued through the whole window are skipped, so the next read
hands over the newest; they are counted (``late_skipped``) and flagged like an overflow
(``DRV_GAP``), never dropped silently.

Health reaches the loop through ``frame_in[IN_STATUS]`` (0 = healthy; the supervisor latches
a fault on any bit) and ``frame_in[IN_SEQ]`` (the device sample counter: a repeated value is a
stale frame). Bits 0–7 are the device's own status bits (``DEV_*``); the driver adds:

======  ==================  ==========================================================
bit     name                set when
======  ==================  ==========================================================
8       ``DRV_TIMEOUT``     no frame for ``timeout_ms`` (set while it lasts)
9       ``DRV_DISCONNECT``  the port is gone (EIO/HUP); reconnecting in a thread
10      ``DRV_CRC``         a frame with a bad CRC was seen since the last read
11      ``DRV_GAP``         the device sequence skipped, the FIFO overflowed, or frames
                            that stood queued for ``lag_window`` reads were skipped
======  ==================  ==========================================================

CRC errors, gaps, skipped late frames, timeouts, disconnects and reconnects are counted
(:meth:`counters`). The port's lifecycle (open, the first frame, hold, close, reconnect) is
:mod:`rigd_drivers.serial.port`.
"""

from __future__ import annotations

import os
import threading
import time
from typing import ClassVar

import numpy as np
from pydantic import Field

from rigd.configio import StrictModel
from rigd.driver import STATUS_DISCONNECT, STATUS_TIMEOUT, FastDriver
from rigd.frame import (
    IN_E_X,
    IN_E_Y,
    IN_F_X,
    IN_F_Y,
    IN_PHI,
    IN_SEQ,
    IN_STATUS,
    IN_YP1,
    IN_YP2,
    IN_YP3,
    IN_YP4,
)
from rigd_drivers.serial import protocol as sp
from rigd_drivers.serial.port import PortLink

DRV_TIMEOUT = STATUS_TIMEOUT        # 1 << 8: the loop records the channels as invalid
DRV_DISCONNECT = STATUS_DISCONNECT  # 1 << 9: likewise
DRV_CRC = 1 << 10
DRV_GAP = 1 << 11

#: the front-end's and this driver's status bits in words (the fault list names them)
STATUS_NAMES = {
    sp.DEV_ENCODER_LOST: "front-end: encoder index pulse missing or quadrature error",
    sp.DEV_ADC_OVERRANGE: "front-end: an ADC channel clipped",
    sp.DEV_HOST_TIMEOUT: "front-end: no valid drive frame from the host, holding the safe "
                         "voltage",
    sp.DEV_DRIVE_CRC: "front-end: a drive frame with a bad CRC was received",
    DRV_TIMEOUT: "serial: no frame from the front-end within timeout_ms",
    DRV_DISCONNECT: "serial: the front-end's port is gone (disconnected; reconnecting)",
    DRV_CRC: "serial: a frame with a bad CRC was received",
    DRV_GAP: "serial: frames lost (sequence gap, FIFO overflow or late frames skipped)",
}


class SerialFrameOptions(StrictModel):
    """``drivers.serial`` section of the rig config."""

    port: str = Field(description="serial device, e.g. /dev/serial/by-id/usb-rigd-frontend")
    baudrate: int = Field(2_000_000, gt=0, description="UART rate (ignored by USB CDC-ACM)")
    timeout_ms: float = Field(5.0, gt=0, description="no frame this long -> timeout fault, ms")
    reconnect_s: float = Field(0.5, gt=0, description="retry period after a disconnect, s")
    backlog: int = Field(8, ge=2, le=1024, description="decoded frames buffered, frames")
    lag_window: int = Field(25, ge=2, description="a FIFO that neither emptied nor shrank in "
                            "this many consecutive reads (cycles; 25 = 5 ms at 5 kHz) holds "
                            "late frames, not jitter: they are skipped (counted late_skipped, "
                            "flagged as a gap), reads")
    first_frame_s: float = Field(2.0, gt=0, description="open/reconnect: wait this long for "
                                 "the device's first frame (a silent device is refused), s")
    fault_on_crc: bool = Field(True, description="a CRC error sets DRV_CRC (-> fault)")
    fault_on_gap: bool = Field(True, description="a sequence gap sets DRV_GAP (-> fault)")


class SerialFrameDriver(PortLink, FastDriver):
    """Sensors in and valve drive out over the front-end's serial frame protocol (the port's
    open, first frame, hold, close and reconnect: :class:`rigd_drivers.serial.port.PortLink`)."""

    name = "serial"
    Options: ClassVar[type[StrictModel]] = SerialFrameOptions
    status_names: ClassVar[dict[int, str]] = STATUS_NAMES

    def __init__(self, options=None, *, fs: float = 5000.0):
        super().__init__(options, fs=fs)
        opts = options if isinstance(options, SerialFrameOptions) else \
            SerialFrameOptions.model_validate(options or {})
        self.opts = opts
        self._rx = np.zeros(8192, np.uint8)
        self._rxmv = memoryview(self._rx)
        self._state = np.zeros(sp.N_STATE, np.int64)
        self._fifo = np.zeros((opts.backlog, sp.N_ROW))
        self._row = np.zeros(sp.N_ROW)
        self._tx = np.zeros(sp.DRIVE_FRAME, np.uint8)
        self._txmv = memoryview(self._tx)
        self._ser = None
        self._fd = -1
        self._tx_seq = 0
        self._last_rx = 0.0
        self._timeout_s = opts.timeout_ms / 1000.0
        self._in_timeout = False
        self._dev_status = 0
        self._reconnecting = threading.Lock()
        self._closed = True
        self._hold = False           # deactivated: the device holds its safe voltage
        self.n_timeouts = 0
        self.n_disconnects = 0
        self.n_reconnects = 0
        self.n_tx_overflow = 0
        self.n_resyncs = 0
        self.n_late_skipped = 0
        self._lag_reads = 0          # reads in the current lag window
        self._lag_min = 0            # fewest frames left queued after a read in that window
        self._lag_first = 0          # frames left queued after its first read
        self._lag_last = 0           # ... and after its latest read
        self._last_call = 0.0
        self._delivered = 0
        self._reset_rx()

    # --- per cycle ---------------------------------------------------------------------
    def read(self, frame_in: np.ndarray) -> None:
        """Newest sensor frame into ``frame_in`` (status bits for timeout/CRC/gap/disconnect).

        Runs in: loop thread — non-blocking reads (VMIN=VTIME=0) into preallocated buffers; a
        lost port is handed to a reconnect thread. Only in the first second after
        (re)connecting may it drain a start-up backlog (at most 50 ms, ``_resync``).
        """
        fd = self._fd
        status = 0
        if fd < 0:
            frame_in[IN_STATUS] = DRV_DISCONNECT | DRV_TIMEOUT
            return
        st = self._state
        # the time is taken BEFORE the port is read: "nothing for timeout_ms" is then true of
        # everything the device sent up to ``now``. Taken after, a preemption between the
        # read and the clock (a loaded host) counted the frames that arrived meanwhile,
        # unread yet, as missing: a false timeout
        now = time.monotonic()
        try:
            # VMIN=VTIME=0: returns 0 at once when nothing is waiting. A vanished pty or
            # USB device raises EIO here or in write() (which runs every cycle).
            n = os.readv(fd, (self._rxmv[st[sp.C_RXLEN]:],))
        except (BlockingIOError, InterruptedError):
            n = 0
        except OSError:
            self._lost()
            frame_in[IN_STATUS] = DRV_DISCONNECT | DRV_TIMEOUT
            return
        if n:
            st[sp.C_RXLEN] += n
            sp.ingest_sensor(self._rx, st, self._fifo)
        if now - self._last_call > self._timeout_s and self._delivered < self.fs:
            self._resync(fd)
        self._last_call = now
        ev = st[sp.C_EVENTS]
        if ev:
            st[sp.C_EVENTS] = 0
            if ev & sp.EV_CRC and self.opts.fault_on_crc:
                status |= DRV_CRC
            if ev & (sp.EV_GAP | sp.EV_OVERFLOW) and self.opts.fault_on_gap:
                status |= DRV_GAP
        self._lag_reads += 1
        if self._lag_reads > self.opts.lag_window:
            # a whole window of reads after none of which the FIFO was empty, and it did not
            # shrink (a host catching up after a stall drains it: that is left alone): what
            # stood queued all along is latency, not jitter — skipped (counted, flagged), the
            # newest frames go on
            if self._lag_min > 0 and self._lag_last >= self._lag_first:
                self.n_late_skipped += sp.drop_oldest(st, self._fifo, self._lag_min)
                if self.opts.fault_on_gap:
                    status |= DRV_GAP
            self._lag_reads = 1
            self._lag_min = st[sp.C_COUNT]
        row = self._row
        if sp.pop_sensor(st, self._fifo, row):
            self._last_rx = now
            self._delivered += 1
            self._in_timeout = False
            frame_in[IN_E_X] = row[sp.R_EX]
            frame_in[IN_E_Y] = row[sp.R_EY]
            frame_in[IN_YP1] = row[sp.R_YP1]
            frame_in[IN_YP2] = row[sp.R_YP2]
            frame_in[IN_YP3] = row[sp.R_YP3]
            frame_in[IN_YP4] = row[sp.R_YP4]
            frame_in[IN_PHI] = row[sp.R_PHI]
            frame_in[IN_F_X] = row[sp.R_FX]
            frame_in[IN_F_Y] = row[sp.R_FY]
            frame_in[IN_SEQ] = row[sp.R_SEQ]
            self._dev_status = int(row[sp.R_STATUS]) & 0xFF
        elif now - self._last_rx > self._timeout_s:
            if not self._in_timeout:
                self._in_timeout = True
                self.n_timeouts += 1
            status |= DRV_TIMEOUT
        left = st[sp.C_COUNT]
        if left < self._lag_min:
            self._lag_min = left
        if self._lag_reads == 1:
            self._lag_first = left
        self._lag_last = left
        frame_in[IN_STATUS] = status | self._dev_status  # device bits of the latest frame

    def _resync(self, fd: int) -> None:
        """Start-up: the host was not cycling yet (between ``open`` and the first cycles of
        the loop) and what queued up meanwhile is history. Drain the port (at most 50 ms), keep
        the newest frame and start gap counting afresh; counted in ``resyncs``. Only during
        the first second of frames after (re)connecting: later, a host stall that loses frames
        is a gap fault (and the loop's overrun supervision reports the stall itself).

        Once the loop has taken a frame from this port the queued frames are part of its
        stream: discarding them is a loss, never silent — counted in ``overflow_dropped`` and
        flagged like a FIFO overflow (``DRV_GAP`` with ``fault_on_gap``)."""
        st = self._state
        end = time.monotonic() + 0.05
        while time.monotonic() < end:
            try:
                n = os.readv(fd, (self._rxmv[st[sp.C_RXLEN]:],))
            except (BlockingIOError, InterruptedError):
                n = 0
            except OSError:
                return  # the next read() finds the port gone
            if n == 0:
                break
            st[sp.C_RXLEN] += n
            sp.ingest_sensor(self._rx, st, self._fifo)
        discarded = 0
        while st[sp.C_COUNT] > 1:
            sp.pop_sensor(st, self._fifo, self._row)
            discarded += 1
        if self._delivered == 0:
            st[sp.C_EVENTS] = 0               # history: the loop never saw this stream
        elif discarded:
            st[sp.C_OVERFLOW] += discarded    # a loss in the loop's stream: counted, flagged
            st[sp.C_EVENTS] |= sp.EV_OVERFLOW
        self.n_resyncs += 1

    def write(self, drive: np.ndarray) -> None:
        """Send one drive frame (outputs enabled) unless deactivated or disconnected.

        Runs in: loop thread — O(1), one non-blocking write from a preallocated buffer.
        """
        fd = self._fd
        if fd < 0 or self._hold:
            return
        self._tx_seq += 1
        n = sp.encode_drive(self._tx, self._tx_seq, True, drive)
        try:
            w = os.write(fd, self._txmv[:n])
            if w < n:
                self.n_tx_overflow += 1
        except (BlockingIOError, InterruptedError):
            self.n_tx_overflow += 1
        except OSError:
            self._lost()

    def counters(self) -> dict[str, int]:
        st = self._state
        c = {name: int(st[i]) for i, name in sp.COUNTER_NAMES.items()}
        c.update(timeouts=self.n_timeouts, disconnects=self.n_disconnects,
                 reconnects=self.n_reconnects, resyncs=self.n_resyncs,
                 late_skipped=self.n_late_skipped,
                 tx_overflow=self.n_tx_overflow,
                 connected=int(self.connected))
        return c
