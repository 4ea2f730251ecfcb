"""The serial front-end's port: open it, wait for the device's first frame, hold the outputs,
close it, and when it fails drop it and reconnect in a thread (the connection's lifecycle,
beside the per-cycle ``read``/``write`` of :mod:`rigd_drivers.serial.driver`).

:class:`PortLink` is a mixin of :class:`rigd_drivers.serial.driver.SerialFrameDriver`: it
works on the driver's port, receive buffers, protocol state and counters, which the driver
allocates (``__init__``), and never runs in the loop's cycle but for ``_lost`` (a port that
failed in ``read`` or ``write``: a few non-blocking closes, the reconnect in a thread).
"""

from __future__ import annotations

import os
import threading
import time

import numpy as np

from rigd.errors import FaultError
from rigd_drivers.serial import protocol as sp


class PortLink:
    """Open, attach, hold, close, reconnect (module docstring)."""

    # --- device ------------------------------------------------------------------------
    def _reset_rx(self) -> None:
        self._state[sp.C_RXLEN] = 0
        self._state[sp.C_HEAD] = 0
        self._state[sp.C_COUNT] = 0
        self._state[sp.C_LASTSEQ] = -1
        self._state[sp.C_EVENTS] = 0

    def _open_port(self):
        import serial

        ser = serial.Serial(self.opts.port, self.opts.baudrate, timeout=0, write_timeout=0,
                            exclusive=True)
        try:
            ser.reset_input_buffer()
        except Exception:  # noqa: BLE001 - not all ports support it
            pass
        return ser

    def open(self) -> None:
        """Open the port and wait for the device's first frame; :class:`FaultError` if it
        cannot be opened or the device sends nothing within ``first_frame_s``."""
        try:
            ser = self._open_port()
        except Exception as exc:  # serial.SerialException, OSError
            raise FaultError(f"serial driver: cannot open {self.opts.port}: {exc}") from None
        self._closed = False
        if not self._attach(ser):
            self._closed = True
            ser.close()
            raise FaultError(f"serial driver: no frame from the front-end on {self.opts.port} "
                             f"within {self.opts.first_frame_s:g} s (first_frame_s): is it "
                             "powered and streaming?")
        # warm the compiled kernels outside the cycle
        sp.ingest_sensor(self._rx, self._state, self._fifo)
        sp.drop_oldest(self._state, self._fifo, 0)
        sp.encode_drive(self._tx, 0, False, np.zeros(4))

    def _attach(self, ser) -> bool:
        """Take ``ser`` into use once the device streams; False if it sent no frame within
        ``first_frame_s`` (the port is then not used).

        Frames the device sent before we listened are history, not samples of this run:
        drain them (until the port is quiet for 1 ms, at most 0.2 s) and start counting
        sequence gaps from the first live frame. Then wait for that first frame: the frame
        timeout (``timeout_ms``) runs from a frame the device sent, never from the moment the
        port opened — a device that starts streaming some time after the port opens (a
        front-end booting, a firmware that starts on DTR, the emulator process starting up:
        0.24–0.35 s measured at load 10) otherwise latched a ``driver_status`` timeout in
        the loop's first cycles (issue 16 item 6).
        """
        fd = ser.fileno()
        end = time.monotonic() + 0.2
        quiet = 0
        while quiet < 2 and time.monotonic() < end:
            try:
                n = os.readv(fd, (self._rxmv,))
            except (BlockingIOError, InterruptedError):
                n = 0
            except OSError:
                break
            quiet = quiet + 1 if n < sp.SENSOR_FRAME else 0
            time.sleep(0.0005)
        self._reset_rx()
        if not self._first_frame(fd) or self._closed:   # closed meanwhile: not taken
            return False
        self._dev_status = 0
        self._delivered = 0
        self._ser = ser
        self._last_rx = time.monotonic()
        self._lag_reads = self._lag_min = self._lag_first = self._lag_last = 0
        self._in_timeout = False
        self._fd = ser.fileno()  # published last: read()/write() start using the port now
        return True

    def _first_frame(self, fd: int) -> bool:
        """Read until the first complete, CRC-valid sensor frame is in the FIFO (kept there);
        False after ``first_frame_s`` or if the port fails."""
        st = self._state
        end = time.monotonic() + self.opts.first_frame_s
        while True:
            try:
                n = os.readv(fd, (self._rxmv[st[sp.C_RXLEN]:],))
            except (BlockingIOError, InterruptedError):
                n = 0
            except OSError:
                return False
            if n:
                st[sp.C_RXLEN] += n
                sp.ingest_sensor(self._rx, st, self._fifo)
                if st[sp.C_COUNT] > 0:
                    st[sp.C_EVENTS] = 0   # the bytes before the first frame: not a fault
                    return True
            if time.monotonic() >= end or self._closed:
                return False
            time.sleep(0.0005)

    # --- lifecycle (rigd.driver): configure = open, cleanup = close ------------------------
    def on_activate(self) -> None:
        """Drive frames enable the outputs again (also after a reconnect)."""
        self._hold = False

    def on_deactivate(self, safe_drive) -> None:
        """Tell the device to hold its own safe voltage now (outputs disabled) and send no
        further drive until activated again, across reconnects too. The device's host-timeout
        hold stays the backstop if this frame is lost.

        Runs in: any thread, including a dying loop thread — a few non-blocking writes.
        """
        self._hold = True
        self._send_hold()

    def _send_hold(self) -> None:
        fd = self._fd
        if fd >= 0:
            n = sp.encode_drive(self._tx, self._tx_seq, False, np.zeros(4))
            for _ in range(3):
                try:
                    os.write(fd, self._txmv[:n])
                except OSError:
                    break

    def close(self) -> None:
        """Tell the device to hold its safe voltage (outputs disabled), then release the port."""
        self._closed = True
        self._send_hold()
        self._fd = -1
        if self._ser is not None:
            try:
                self._ser.close()
            except Exception:  # noqa: BLE001
                pass
            self._ser = None

    def _lost(self) -> None:
        """The port failed: drop it and reconnect in a background thread."""
        if self._fd < 0:
            return
        self._fd = -1
        self.n_disconnects += 1
        ser, self._ser = self._ser, None
        try:
            ser.close()
        except Exception:  # noqa: BLE001
            pass
        if not self._closed and self._reconnecting.acquire(blocking=False):
            threading.Thread(target=self._reconnect, name="serial-reconnect", daemon=True).start()

    def _reconnect(self) -> None:
        try:
            while not self._closed:
                time.sleep(self.opts.reconnect_s)
                try:
                    ser = self._open_port()
                except Exception:  # noqa: BLE001 - still unplugged
                    continue
                if self._closed:
                    ser.close()
                    return
                if not self._attach(ser):   # not streaming (yet): try again; or closed
                    ser.close()
                    continue
                self.n_reconnects += 1
                return
        finally:
            self._reconnecting.release()

    @property
    def connected(self) -> bool:
        return self._fd >= 0
