"""An emulator of the microcontroller front-end, speaking the serial frame protocol.

It plays the device side of :mod:`rigd_drivers.serial.protocol` on a serial port or on the
master side of a pseudo-terminal: sensor frames at ``fs`` (5 kHz by default, paced by the
monotonic clock and sent in small bursts), drive frames read back and applied to a simple
valve/shaft model, the device's own safe hold when the host goes quiet, and fault injection
(corrupted frames, sequence gaps, pauses, lost encoder, unplug/replug).

Use it in tests and to bench-test a rig PC without hardware::

    python -m rigd_drivers.serial.emulator --link /tmp/rigd-frontend
    # then in the rig config: drivers.serial.port: /tmp/rigd-frontend

The "unplug" of :meth:`FrontendEmulator.unplug` closes the pty master (the host sees EIO/HUP,
as for a USB device that disappears); :meth:`replug` creates a new pty and re-points the
symlink ``link`` to it, as udev does with ``/dev/serial/by-id/...``.
"""

from __future__ import annotations

import argparse
import math
import os
import threading
import time
import tty

import numpy as np

from rigd_drivers.serial import protocol as sp


class FrontendEmulator:
    """Device side of the serial protocol in a background thread.

    Parameters
    ----------
    link : str, optional
        Symlink path to create to the pty slave (the host opens this path).
    fs : float
        Sensor frame rate, Hz.
    hold_v : float
        Drive voltage the device applies on its own when the host is silent (r0), V.
    hold_timeout : float
        The **host heartbeat**: no valid drive frame with outputs enabled *and a host cycle
        counter that advanced* for this long, s, and the device applies ``hold_v`` on its
        own (``holding``; status bit ``DEV_HOST_TIMEOUT``) until the next advancing frame — a
        host that froze (a stopped process, a stuck loop) or whose link replays its last
        frame is safe in hardware. A frame with outputs disabled holds at once.
    omega_rpm : float
        Shaft speed of the model (encoder angle advances at this rate), rpm.
    fd : int, optional
        Use this already-open serial file descriptor instead of creating a pty.
    tx_buffer_s : float
        Device transmit buffer, s of frames (a microcontroller's DMA buffer: 10 ms). A host
        that does not read for longer loses frames (the host then sees a sequence gap).
    late_drop_s : float, optional
        The emulator's own stalls (a preempted process; a real device's sampling never
        stops): when it wakes more than this late, the samples it missed are modelled (the
        plant moves on, the sequence counter too) but only the newest is sent — the host sees
        a gap (counted here in ``late_dropped``), never a burst of stale frames that would
        stand queued as latency. None (default): every missed sample is sent, late.
    """

    def __init__(self, link: str | None = None, *, fs: float = 5000.0, hold_v: float = 5.0,
                 hold_timeout: float = 0.002, omega_rpm: float = 3000.0, fd: int | None = None,
                 tx_buffer_s: float = 0.01, late_drop_s: float | None = None):
        self.link = link
        self.fs = float(fs)
        self.hold_v = hold_v
        self.hold_timeout = hold_timeout
        self.omega_rpm = omega_rpm
        self._ext_fd = fd
        self.max_pending_s = tx_buffer_s  # device transmit buffer; beyond it frames are dropped
        self.master = -1
        self.slave_name = ""
        self.lock = threading.Lock()
        self.seq = 0
        self.sent = 0
        self.tx_dropped = 0          # frames not written because the host did not read
        self.late_drop_s = late_drop_s
        self.late_dropped = 0        # samples modelled but not sent: the emulator was late
        self.drive_frames = 0
        self.drive_crc_errors = 0
        self.repeated_frames = 0     # enabled drive frames whose host counter did not advance
        self.last_drive = np.full(6, np.nan)   # seq, flags, v1..v4 of the last drive frame
        self.applied = np.full(4, hold_v)       # what the "valves" get
        self.holding = True
        self.armed = False           # host timeout is reported only after a first drive frame
        self.yp = np.full(4, hold_v)
        # fault injection (set from any thread)
        self.corrupt = 0             # corrupt the next N frames' CRC
        self.skip = 0                # skip N sequence numbers once (a gap)
        self.paused = False          # send nothing (host sees a timeout)
        self.encoder_lost = False
        self.extra_status = 0
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._open()

    # --- the link ---------------------------------------------------------------------
    def _open(self) -> None:
        if self._ext_fd is not None:
            self.master = self._ext_fd
            return
        m, s = os.openpty()
        tty.setraw(s)          # no line discipline between the two ends
        tty.setraw(m)
        self.slave_name = os.ttyname(s)
        os.set_blocking(m, False)
        self.master = m
        self._slave_keep = s   # keep the slave open so the pty survives between host opens
        if self.link:
            tmp = self.link + ".new"
            try:
                os.unlink(tmp)
            except FileNotFoundError:
                pass
            os.symlink(self.slave_name, tmp)
            os.replace(tmp, self.link)

    def _close_link(self) -> None:
        if self.master >= 0 and self._ext_fd is None:
            os.close(self.master)
            os.close(self._slave_keep)
        self.master = -1

    def unplug(self) -> None:
        """Close the pty (the host gets EIO/HUP) and remove the symlink."""
        with self.lock:
            self._close_link()
            if self.link:
                try:
                    os.unlink(self.link)
                except FileNotFoundError:
                    pass

    def replug(self) -> None:
        """A new pty appears at the same symlink; the sequence counter continues."""
        with self.lock:
            self._close_link()
            self._open()
            self.armed = False

    @property
    def port(self) -> str:
        return self.link or self.slave_name

    # --- thread -----------------------------------------------------------------------
    def start(self) -> FrontendEmulator:
        self._thread = threading.Thread(target=self._run, name="frontend-emu", daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(5)
        self._close_link()
        if self.link:
            try:
                os.unlink(self.link)
            except FileNotFoundError:
                pass

    def __enter__(self):
        return self.start()

    def __exit__(self, *exc):
        self.stop()

    def _advance(self, phi: float, dt: float) -> float:
        """One sample of the emulated plant, sent or not: the valve positions follow the
        applied drive (lag 0.3 per sample) and the shaft angle turns by Ω·dt; returns the new
        angle φ (rad)."""
        self.yp += 0.3 * (self.applied - self.yp)
        return (phi + 2 * math.pi * self.omega_rpm / 60.0 * dt) % (2 * math.pi)

    def _run(self) -> None:
        out = np.zeros(sp.SENSOR_FRAME * 64, np.uint8)
        rx = np.zeros(4096, np.uint8)
        rxlen = 0
        row = np.zeros(6)
        t0 = time.monotonic()
        dt = 1.0 / self.fs
        last_host = time.monotonic()
        host_seq = -1
        phi = 0.0
        pending = bytearray()
        max_pending = int(self.max_pending_s * self.fs) * sp.SENSOR_FRAME
        late = False
        while not self._stop.is_set():
            now = time.monotonic()
            with self.lock:
                fd = self.master
                if fd < 0:
                    time.sleep(0.001)
                    t0, self.sent = now, 0
                    pending.clear()
                    continue
                # --- host -> device: drive frames
                try:
                    data = os.read(fd, 4096 - rxlen)
                except (BlockingIOError, InterruptedError):
                    data = b""
                except OSError:
                    data = b""
                if data:
                    rx[rxlen:rxlen + len(data)] = np.frombuffer(data, np.uint8)
                    rxlen += len(data)
                    i = 0
                    while rxlen - i >= sp.DRIVE_FRAME:
                        r = sp.decode_drive(rx, i, row)
                        if r == 1:
                            self.drive_frames += 1
                            self.last_drive[:] = row
                            self.armed = True
                            enabled = int(row[1]) & 1
                            if enabled and int(row[0]) == host_seq:
                                # the host's counter did not move: a replayed frame is no
                                # heartbeat (a frozen host whose link repeats its buffer)
                                self.repeated_frames += 1
                            elif enabled:
                                host_seq = int(row[0])
                                last_host = now
                                self.applied[:] = row[2:6]
                                self.holding = False
                            else:
                                last_host = now
                                self.applied[:] = self.hold_v
                                self.holding = True
                            i += sp.DRIVE_FRAME
                        elif r == 0:
                            self.drive_crc_errors += 1
                            i += 1
                        else:
                            i += 1
                    rx[:rxlen - i] = rx[i:rxlen].copy()
                    rxlen -= i
                host_timeout = self.armed and (now - last_host) > self.hold_timeout
                if host_timeout:
                    self.applied[:] = self.hold_v
                    self.holding = True
                # --- device -> host: sensor frames due by now
                due = int((now - t0) * self.fs) - self.sent
                if self.paused:
                    self.sent += due
                    self.seq += due
                    due = 0
                nbytes = 0
                # samples this many late are not sent (late_drop_s): the model runs through
                # them, only the newest goes out
                quiet = due - 1 if (self.late_drop_s is not None
                                    and due > self.late_drop_s * self.fs) else 0
                for _ in range(quiet):
                    phi = self._advance(phi, dt)
                    self.seq += 1
                    self.sent += 1
                self.late_dropped += quiet
                due -= quiet
                for _ in range(min(due, 64)):
                    phi = self._advance(phi, dt)
                    ux = self.yp[1] - self.yp[3]
                    uy = self.yp[0] - self.yp[2]
                    ex = 1.5 * ux + 0.2 * math.cos(phi)
                    ey = 1.3 * uy + 0.2 * math.sin(phi)
                    status = self.extra_status
                    if self.encoder_lost:
                        status |= sp.DEV_ENCODER_LOST
                    if host_timeout:
                        status |= sp.DEV_HOST_TIMEOUT
                    if self.skip:
                        self.seq += self.skip
                        self.skip = 0
                    buf = out[nbytes:nbytes + sp.SENSOR_FRAME]
                    sp.encode_sensor(buf, self.seq, status, ex, ey, self.yp[0], self.yp[1],
                                     self.yp[2], self.yp[3], 0.0 if self.encoder_lost else phi,
                                     0.0, 0.0)
                    if self.corrupt:
                        buf[sp.SENSOR_FRAME - 1] ^= 0x5A
                        self.corrupt -= 1
                    nbytes += sp.SENSOR_FRAME
                    self.seq += 1
                    self.sent += 1
                if nbytes:
                    # whole frames are queued; a slow host delays them (as UART flow control
                    # would) and only beyond max_pending_s of backlog are frames dropped
                    if len(pending) + nbytes > max_pending:
                        self.tx_dropped += nbytes // sp.SENSOR_FRAME
                    else:
                        pending += out[:nbytes].tobytes()
                if pending:
                    try:
                        w = os.write(fd, pending)
                        del pending[:w]
                    except (BlockingIOError, InterruptedError):
                        pass
                    except OSError:
                        pending.clear()
                late = due > 64
            if not late:
                time.sleep(0.0004)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description="Emulate the rigd front-end on a pseudo-terminal.")
    p.add_argument("--link", default="/tmp/rigd-frontend", help="symlink to the pty slave")
    p.add_argument("--fs", type=float, default=5000.0)
    p.add_argument("--omega-rpm", type=float, default=3000.0)
    a = p.parse_args(argv)
    emu = FrontendEmulator(a.link, fs=a.fs, omega_rpm=a.omega_rpm).start()
    print(f"front-end emulator on {emu.slave_name} (link {a.link}); Ctrl-C to stop", flush=True)
    try:
        while True:
            time.sleep(1.0)
            print(f"sent {emu.sent} frames, drive frames {emu.drive_frames}, "
                  f"holding {emu.holding}", flush=True)
    except KeyboardInterrupt:
        pass
    finally:
        emu.stop()
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
