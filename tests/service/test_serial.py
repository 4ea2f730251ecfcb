"""Serial frame driver against the front-end emulator on a pseudo-terminal pair, at 5 kHz.

The emulator runs in a process of its own (emuproc.py: sharing this process's interpreter
lock, it was starved on a loaded machine). Every wait for the device or the driver to react
is a wait on the condition (``_run_until``), not a fixed time."""

import struct
import time

import numpy as np
import pytest
from emuproc import EmulatorProcess
from faultkit import wait_for

from rigd.errors import FaultError
from rigd.frame import IN_E_X, IN_PHI, IN_SEQ, IN_STATUS, IN_YP2, N_IN
from rigd_drivers.serial import protocol as sp
from rigd_drivers.serial.driver import (
    DRV_CRC,
    DRV_DISCONNECT,
    DRV_GAP,
    DRV_TIMEOUT,
    SerialFrameDriver,
)


def test_wire_format_pinned():
    assert sp.crc16(np.frombuffer(b"123456789", np.uint8), 0, 9) == 0x29B1
    buf = np.zeros(30, np.uint8)
    sp.encode_sensor(buf, 0x01020304, 0x0002, 1.23, -2.5, 5.0, 10.0, 0.0, 7.5, np.pi, 12.3, -4.0)
    body = struct.pack("<BBIHhhHHHHHhh", 0x01, 24, 0x01020304, 2, 123, -250, 5000, 10000, 0,
                       7500, 32768, 123, -40)
    crc = sp.crc16(np.frombuffer(body, np.uint8), 0, len(body))
    assert buf.tobytes() == b"\xa5\x5a" + body + struct.pack("<H", crc)
    d = np.zeros(20, np.uint8)
    sp.encode_drive(d, 9, True, np.array([-1.0, 5.0, 12.0, np.nan]))
    assert d.tobytes()[:18] == b"\xa5\x5a\x02\x0e" + struct.pack("<IH4H", 9, 1, 0, 5000, 10000, 0)
    out = np.zeros(6)
    assert sp.decode_drive(d, 0, out) == 1 and out[3] == 5.0
    d[12] ^= 1
    assert sp.decode_drive(d, 0, out) == 0


def _drain(drv, frame, seqs, statuses):
    while True:
        before = frame[IN_SEQ]
        drv.read(frame)
        statuses.append(int(frame[IN_STATUS]))
        if frame[IN_SEQ] == before:
            return
        seqs.append(int(frame[IN_SEQ]))


def _run_until(drv, frame, pred, timeout=180.0, drive=None, write=True):
    """Run host cycles until ``pred(statuses)`` holds; with ``write=False`` the host only
    reads (it sends the device no drive frame). ``timeout`` (s) only bounds a hang: on the
    shared machine other test runs' SCHED_FIFO 80 loops can take most of both cores from this
    host loop (SCHED_FIFO 20) for a long while."""
    seqs, statuses = [], []
    drive = np.array([5.0, 6.0, 5.0, 4.0]) if drive is None else drive
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        _drain(drv, frame, seqs, statuses)
        if write:
            drv.write(drive)
        if pred(statuses):
            return seqs, statuses
        time.sleep(0.0003)
    raise AssertionError(f"condition not reached within {timeout} s; counters "
                         f"{drv.counters()}, last status {statuses[-1:]}")


def _past_startup(drv, frame):
    """Run the host until the driver is past its start-up resynchronisation window (its first
    second of frames, in which a host pause drops the queued history on purpose)."""
    _run_until(drv, frame, lambda st: drv._delivered > 1.2 * drv.fs)


#: SCHED_FIFO priority of this test's host loop: like the daemon's loop thread (clock.priority,
#: 80 by default) above the machine's ordinary work, here below the rig's and above the
#: emulator process's (emuproc.EMULATOR_PRIORITY)
HOST_PRIORITY = 20


@pytest.fixture()
def realtime_host():
    """Run this test's host loop (the calling thread) under SCHED_FIFO, as the daemon runs its
    loop thread; back to SCHED_OTHER afterwards. Best effort: without the permission it stays
    an ordinary thread.

    Why (issue 16 item 6): as an ordinary thread on a loaded machine the host loop was
    starved for more than the driver's FIFO holds (``backlog`` 1024 frames = 0.2 s); the
    driver then dropped the oldest frames, counted (``overflow_dropped``) and flagged
    (``DRV_GAP``) as it must — "every frame, in order" failed although nothing was lost
    silently. The rig's loop never is such a thread."""
    from rigd.loop.clock import boosted

    with boosted(HOST_PRIORITY):
        yield


@pytest.fixture()
def link(tmp_path, realtime_host):
    # Timeouts generous for a shared, loaded test machine (other people's real-time threads
    # preempt even a SCHED_FIFO emulator; this test's host loop is a plain thread): the device
    # holds after 0.5 s of host silence (2 ms on the rig), the driver reports a timeout after
    # 250 ms without a frame (5 ms on the rig). The behaviours are the same, only slower.
    emu = EmulatorProcess(str(tmp_path / "frontend"), fs=5000.0, hold_timeout=0.5,
                          # flow-control-like: test-host pauses lose nothing
                          tx_buffer_s=0.5)
    # backlog 1024 frames (0.2 s): a pause of the host loop must not overflow the FIFO
    # (first_frame_s: a hang bound for the open and the reconnection, not what is tested)
    drv = SerialFrameDriver({"port": emu.port, "backlog": 1024, "timeout_ms": 250,
                             "reconnect_s": 0.05, "first_frame_s": 60})
    drv.open()
    yield emu, drv, np.zeros(N_IN)
    drv.close()
    emu.stop()


def test_full_rate_stream_and_drive(link):
    """10,000 device frames at 5 kHz, both ways. The contract (the driver's docstring): every
    frame reaches the host in order, or its absence is counted and flagged — never lost
    silently. Frames that stood queued through a whole ``lag_window`` of reads are skipped
    (``late_skipped``, ``DRV_GAP``) by design: on the shared 2-core test machine every thread,
    even a SCHED_FIFO 95 one that only sleeps, is stalled now and then for several ms (5.6 ms
    measured); the emulator then sends the samples it missed in a burst, faster than the host
    drains them, and those stale frames are skipped. So this test does not ask for no skip
    (the pty tests below prove on a deterministic device that jitter and a host catching up
    lose nothing); it asks that every frame is accounted for, exactly, and that the link
    itself corrupts nothing at full rate."""
    emu, drv, frame = link
    _past_startup(drv, frame)  # the backlog queued while the port was opening is drained
    # _run_until returns after a drain whose last read found the FIFO empty: every frame
    # decoded so far has been handed over or counted, at the start as at the end
    c0, prev = drv.counters(), int(frame[IN_SEQ])
    # 2 s of device frames, however long the host takes to read them (a fixed 2 s window of
    # a starved host received 8279 on a loaded machine)
    seqs, statuses = _run_until(drv, frame,
                                lambda st: drv.counters()["frames"] - c0["frames"] >= 10000)
    c = drv.counters()
    d = {k: c[k] - c0[k] for k in ("frames", "crc_errors", "gaps", "gap_frames",
                                    "overflow_dropped", "late_skipped")}
    steps = np.diff([prev, *seqs])
    assert np.all(steps >= 1), "in order, no frame twice"
    # every frame missing from the stream the host got is counted, and every count is a
    # frame missing from it: the sequence numbers and the counters agree exactly
    missing = int(np.sum(steps - 1))
    assert missing == d["gap_frames"] + d["overflow_dropped"] + d["late_skipped"], (missing, d)
    # every frame decoded was handed over or counted as dropped
    assert len(seqs) + d["overflow_dropped"] + d["late_skipped"] == d["frames"], (len(seqs), d)
    # a loss is flagged in the status the host read (DRV_GAP), and a flag means a loss
    flagged = any(s & DRV_GAP for s in statuses)
    assert flagged == (missing > 0), (missing, d)
    # the link itself corrupts nothing at 5 kHz. (A sequence gap is the device's own loss:
    # its transmit buffer holds 0.5 s, and a host starved longer than that — 2 s measured
    # beside other test runs' SCHED_FIFO loops at load 20 — makes it drop frames, which the
    # host then counts in gap_frames, as the identity above checks.)
    assert d["crc_errors"] == 0, d
    assert d["frames"] >= 10000
    # every host cycle writes a drive frame (how many depends on the host's pace; > 100 in 2 s)
    assert emu.drive_frames > 100 and not emu.holding
    np.testing.assert_allclose(emu.applied, [5.0, 6.0, 5.0, 4.0])
    # the emulated valves followed the drive: u_x = y_p2 - y_p4 = 2 V -> e_x ≈ 3 µm
    assert frame[IN_YP2] == pytest.approx(6.0, abs=0.01)
    assert frame[IN_E_X] == pytest.approx(3.0, abs=0.25)
    assert 0.0 <= frame[IN_PHI] < 2 * np.pi


def test_crc_gap_timeout_encoder_flagged_and_counted(link):
    emu, drv, frame = link
    _past_startup(drv, frame)
    c0 = drv.counters()        # start-up (first compile, resync) is not what is counted here

    def d(k):
        return drv.counters()[k] - c0[k]

    emu.corrupt = 3
    before, st = _run_until(drv, frame, lambda st: d("crc_errors") >= 3)
    assert d("crc_errors") == 3 and any(s & DRV_CRC for s in st)
    before += _run_until(drv, frame, lambda st: len(st) > 10 and st[-1] == 0)[0]
    emu.skip = 5
    seqs, st = _run_until(drv, frame, lambda st: d("gaps") >= 2)
    assert d("gap_frames") == 5 + 3 and d("gaps") == 2  # the 3 corrupted frames were gaps too
    assert any(s & DRV_GAP for s in st) and 6 in np.diff(before[-1:] + seqs)
    emu.paused = True
    _, st = _run_until(drv, frame, lambda st: st and st[-1] & DRV_TIMEOUT)
    assert d("timeouts") == 1
    emu.paused = False
    emu.encoder_lost = True
    _, st = _run_until(drv, frame, lambda st: st and st[-1] & sp.DEV_ENCODER_LOST
                       and not st[-1] & DRV_TIMEOUT)
    emu.encoder_lost = False
    _run_until(drv, frame, lambda st: st and st[-1] == 0)


def test_disconnect_then_reconnect(link):
    emu, drv, frame = link
    _past_startup(drv, frame)
    emu.unplug()
    _, st = _run_until(drv, frame, lambda st: st and st[-1] & DRV_DISCONNECT)
    assert drv.counters()["disconnects"] == 1
    assert not drv.connected
    emu.replug()
    _run_until(drv, frame, lambda st: drv.connected)
    _past_startup(drv, frame)
    # the stream is back: 1000 more frames, in order, every missing one counted (the
    # accounting of test_full_rate_stream_and_drive), however slowly a busy host reads them
    c0, prev, n0 = drv.counters(), int(frame[IN_SEQ]), drv._delivered
    seqs, st = _run_until(drv, frame, lambda st: drv._delivered >= n0 + 1000)
    c = drv.counters()
    assert c["reconnects"] == 1 and drv.connected and c["disconnects"] == 1
    steps = np.diff([prev, *seqs])
    assert np.all(steps >= 1) and int(np.sum(steps - 1)) == sum(
        c[k] - c0[k] for k in ("gap_frames", "overflow_dropped", "late_skipped"))
    assert c["gap_frames"] == c0["gap_frames"]          # none lost on the link itself
    assert not st[-1] & (DRV_DISCONNECT | DRV_TIMEOUT)  # connected, frames arriving


def test_close_puts_device_in_safe_hold(link):
    emu, drv, frame = link
    drive = np.array([9.0, 9.0, 1.0, 1.0])
    _run_until(drv, frame, lambda st: not emu.holding and emu.applied[0] == 9.0, drive=drive)
    drv.close()
    assert wait_for(lambda: emu.holding, 180)
    assert np.all(emu.applied == 5.0)


def test_device_holds_when_host_goes_silent(link):
    emu, drv, frame = link
    drive = np.array([9.0, 9.0, 1.0, 1.0])
    _run_until(drv, frame, lambda st: not emu.holding and emu.applied[0] == 9.0, drive=drive)
    # the host goes silent (no read, no write) until the device has noticed
    assert wait_for(lambda: emu.holding, 180)
    assert np.all(emu.applied == 5.0)
    # the host reads again (still sending nothing): the frames queued since it went silent
    # come first, then those that carry the device's host-timeout bit. Read until one is
    # there — a single drain stopped at the first empty read while the device still had
    # them queued (E-1 of the under-load runs, once the host loop ran SCHED_FIFO)
    _run_until(drv, frame, lambda st: any(s & sp.DEV_HOST_TIMEOUT for s in st), write=False)
    assert emu.holding


def test_open_missing_port_is_a_fault(tmp_path):
    drv = SerialFrameDriver({"port": str(tmp_path / "nope")})
    with pytest.raises(FaultError, match="cannot open"):
        drv.open()



def test_open_waits_for_the_first_frame(realtime_host):
    """A front-end that starts streaming only after the port is open (booting, starting on
    DTR): ``open()`` returns once its first frame is there, so the frame timeout runs from a
    frame the device sent and the first read flags no timeout. One that never streams is
    refused at open with one clear line (issue 16 item 6: the timeout ran from the open, and
    the loop's first cycles latched driver_status). The device here is the test itself on the
    master side of a pty pair: it sends exactly when it is told to."""
    import os
    import threading
    import tty

    master, slave = os.openpty()
    tty.setraw(master)
    tty.setraw(slave)
    port = os.ttyname(slave)
    try:
        silent = SerialFrameDriver({"port": port, "first_frame_s": 0.3})
        with pytest.raises(FaultError, match="no frame from the front-end on .* within 0.3 s"):
            silent.open()
        assert not silent.connected
        # it starts streaming 0.3 s after the open: longer than the 50 ms frame timeout
        frames = np.zeros(10 * sp.SENSOR_FRAME, np.uint8)
        for k in range(10):
            sp.encode_sensor(frames[k * sp.SENSOR_FRAME:], k, 0, 1.0, 2.0, 5.0, 5.0, 5.0, 5.0,
                             0.5, 0.0, 0.0)
        # set before the write: open() can return as soon as the bytes are in the pty, before
        # the timer thread runs its next statement (the order was write-then-set: a race)
        sent = threading.Event()
        starts = threading.Timer(0.3, lambda: (sent.set(), os.write(master, frames.tobytes())))
        drv = SerialFrameDriver({"port": port, "timeout_ms": 50, "first_frame_s": 600})
        starts.start()
        try:
            drv.open()
            assert sent.is_set(), "open() returned before the device streamed"
            frame = np.full(N_IN, np.nan)
            drv.read(frame)
            assert frame[IN_SEQ] == 9, "the first read hands over the newest frame"
            assert not int(frame[IN_STATUS]) & DRV_TIMEOUT
            assert drv.counters()["timeouts"] == 0
        finally:
            starts.join()
            drv.close()
    finally:
        os.close(master)
        os.close(slave)


def test_a_host_pause_after_the_first_frames_is_a_counted_flagged_loss(link):
    """In the first second after (re)connecting a host pause longer than ``timeout_ms`` makes
    the driver drain the port and keep only the newest frame. Before the loop has taken a
    frame that backlog is history; after it, those frames were the loop's stream: the loss is
    counted (``overflow_dropped``) and flagged (``DRV_GAP``) — it was only a ``resyncs`` count.
    The pause only has to be longer than ``timeout_ms``: how much longer the scheduler makes
    it changes how many frames are dropped, not the relations asserted."""
    emu, drv, frame = link
    _run_until(drv, frame, lambda st: drv._delivered >= 20)
    assert drv._delivered < drv.fs                  # still inside the first second of frames
    c0, prev = drv.counters(), int(frame[IN_SEQ])
    time.sleep(drv.opts.timeout_ms / 1000.0 + 0.05)  # the injected host stall: > timeout_ms
    seqs, _ = _run_until(drv, frame, lambda st: any(s & DRV_GAP for s in st))
    n = drv._delivered                              # then the stream goes on: 3 more frames
    seqs += _run_until(drv, frame, lambda st: drv._delivered >= n + 3)[0]
    c = drv.counters()
    assert c["resyncs"] > c0["resyncs"]             # the pause was seen (resyncs counts it)
    dropped = c["overflow_dropped"] - c0["overflow_dropped"]
    assert dropped >= 1                             # frames the device sent during the pause
    # in order, and exactly the frames counted as dropped are missing from the host's stream
    steps = np.diff([prev, *seqs])
    assert np.all(steps >= 1) and np.count_nonzero(steps > 1) >= 1
    assert int(np.sum(steps - 1)) == dropped + c["late_skipped"] - c0["late_skipped"]
    assert c["gap_frames"] == c0["gap_frames"]      # none lost on the link itself


@pytest.fixture()
def pty_device():
    """The device side as the test itself on the master of a pty pair (it sends exactly the
    frames it is told to, when it is told to) and a driver on the slave; ``send(seqs)`` writes
    sensor frames with those sequence numbers in one write and returns once they are waiting
    on the driver's side (so the next ``read`` gets them all: a host cycle after a burst)."""
    import fcntl
    import os
    import termios
    import threading
    import tty

    master, slave = os.openpty()
    tty.setraw(master)
    tty.setraw(slave)
    buf = np.zeros(64 * sp.SENSOR_FRAME, np.uint8)
    waiting = np.zeros(1, np.int32)

    def write(seqs):
        n = len(seqs) * sp.SENSOR_FRAME
        for k, s in enumerate(seqs):
            sp.encode_sensor(buf[k * sp.SENSOR_FRAME:], s, 0, 1.0, 2.0, 5.0, 5.0, 5.0, 5.0,
                             0.5, 0.0, 0.0)
        os.write(master, buf[:n].tobytes())
        return n

    def send(seqs):
        n = write(seqs)
        end = time.monotonic() + 60
        while True:
            fcntl.ioctl(slave, termios.FIONREAD, waiting)
            if waiting[0] >= n:
                return
            assert time.monotonic() < end, "the pty did not pass the frames on"
            time.sleep(0.0002)

    # no frame timeout and no start-up resync in the way: this is about the FIFO only
    drv = SerialFrameDriver({"port": os.ttyname(slave), "timeout_ms": 600_000,
                             "first_frame_s": 600, "lag_window": 25, "backlog": 64})
    # open() drains what was sent before it listened, then waits for a first frame: seq 0,
    # sent until it is taken; then everything left is read away (the FIFO starts empty)
    opened = threading.Event()

    def boot():
        while not opened.wait(0.02):
            fcntl.ioctl(slave, termios.FIONREAD, waiting)
            if waiting[0] == 0:          # one at a time: never fill the pty while it opens
                write([0])

    booting = threading.Thread(target=boot, daemon=True)
    booting.start()
    try:
        drv.open()
    finally:
        opened.set()
        booting.join()
    frame = np.zeros(N_IN)
    while True:
        fcntl.ioctl(slave, termios.FIONREAD, waiting)
        if waiting[0] == 0 and drv._state[sp.C_COUNT] == 0:
            break
        drv.read(frame)
    try:
        yield send, drv
    finally:
        drv.close()
        os.close(master)
        os.close(slave)


def _cycle(drv, frame):
    """One host cycle's read: the sequence number and status handed over."""
    drv.read(frame)
    return int(frame[IN_SEQ]), int(frame[IN_STATUS])


def test_a_standing_backlog_is_skipped_counted_and_flagged(pty_device):
    """After a burst (the device or the host stalled, then caught up) one frame in and one out
    per cycle keeps the FIFO standing: every frame the loop gets is as many periods late as
    frames wait behind it, for good — the cause of ``shaft_displacement`` latched before the
    unplug in test_fault_serial_disconnect_then_reconnect (the valve PD loop over the emulator
    is unstable beyond ~6 periods of delay). Once the FIFO has not emptied in a whole window of
    ``lag_window`` reads (consecutive blocks of reads), the frames that stood queued are
    skipped, counted in ``late_skipped`` and flagged (``DRV_GAP``); from then on the loop gets
    the frame just sent. Counted in reads (cycles), not wall time: a host preempted between
    two reads has not seen a standing queue."""
    send, drv = pty_device
    frame = np.full(N_IN, np.nan)
    got = []
    # the burst: seq 1..7 at once (the device or the host stalled), the first handed over
    send(range(1, 8))
    sent = 8
    seq, status = _cycle(drv, frame)
    got.append(seq)
    # then one frame per cycle, as the device sends: 6 frames stand queued behind each read
    # until a whole window of reads has passed with the FIFO never empty
    statuses = [status]
    # (the windows are consecutive blocks of reads: a queue standing since any read is seen
    # at the end of the next whole window, within two windows)
    for _ in range(3 * drv.opts.lag_window):
        send([sent])
        seq, status = _cycle(drv, frame)
        sent += 1
        got.append(seq)
        statuses.append(status)
        if drv.counters()["late_skipped"]:
            break
    assert len(got) <= 2 * drv.opts.lag_window + 1, "skipped within two windows of reads"
    c = drv.counters()
    assert c["late_skipped"] == 6, c      # exactly the frames that stood queued
    assert statuses[-1] & DRV_GAP         # flagged in the cycle that skipped them
    assert not any(s & DRV_GAP for s in statuses[:-1])
    assert np.all(np.diff(got[:-1]) == 1), "in order while queued"
    assert got[-1] - got[-2] == 7         # the 6 skipped, then the newest but none
    # from now on each read hands over the frame just sent: no latency left, nothing skipped
    for _ in range(20):
        send([sent])
        seq, status = _cycle(drv, frame)
        assert seq == sent and not status & DRV_GAP
        sent += 1
    assert drv.counters()["late_skipped"] == 6
    assert c["overflow_dropped"] == 0 and c["gaps"] == 0


def test_jitter_that_empties_the_fifo_is_kept_in_order(pty_device):
    """A USB-like link delivers frames in bursts (here 4 at a time every 4th cycle): the FIFO
    empties once per burst, so that queue is jitter, not latency — over many lag windows every
    frame reaches the loop, in order, and nothing is skipped."""
    send, drv = pty_device
    frame = np.full(N_IN, np.nan)
    got = []
    sent = 1
    while len(got) < 20 * drv.opts.lag_window:
        send(range(sent, sent + 4))
        got.append(_cycle(drv, frame)[0])
        sent += 4
        for _ in range(3):
            drv.read(frame)
            got.append(int(frame[IN_SEQ]))
    c = drv.counters()
    assert c["late_skipped"] == 0 and c["overflow_dropped"] == 0, c
    assert got == list(range(1, sent)), "every frame, in order"


def test_a_host_catching_up_is_not_skipped(pty_device):
    """A host catching up after a stall (the loop's ``catch_up`` runs the missed cycles) drains
    the FIFO: a queue that shrinks over a window is not latency standing still — over several
    windows of reads nothing is skipped and every frame reaches the loop in order."""
    send, drv = pty_device
    frame = np.full(N_IN, np.nan)
    send(range(1, 61))                    # 60 frames queued by the stall
    sent = 61
    got = []
    while sent < 200:                     # then two reads per device frame: -1 per cycle
        send([sent])
        sent += 1
        for _ in range(2):
            drv.read(frame)
            if not got or int(frame[IN_SEQ]) != got[-1]:
                got.append(int(frame[IN_SEQ]))
    assert len(got) > 4 * drv.opts.lag_window       # several windows of it
    c = drv.counters()
    assert c["late_skipped"] == 0 and c["overflow_dropped"] == 0, c
    assert got == list(range(1, sent)), "every frame, in order"


def test_emulator_stall_ends_in_the_newest_sample_not_a_burst(tmp_path):
    """``late_drop_s``: when the emulator itself stalls (held here for 0.1 s = 500 samples), it
    models the missed samples but sends only the newest — the host sees one gap of them,
    counted on both sides, not a burst of stale frames that would stand queued as latency."""
    from rigd_drivers.serial.emulator import FrontendEmulator

    emu = FrontendEmulator(str(tmp_path / "fe"), fs=5000.0, hold_timeout=600.0,
                           tx_buffer_s=0.5, late_drop_s=0.002).start()
    # first_frame_s only bounds a hang: the emulator's first iteration (in a thread of this
    # process, loading its compiled codec) took more than the 2 s default at load 25
    drv = SerialFrameDriver({"port": emu.port, "timeout_ms": 600_000, "backlog": 1024,
                             "first_frame_s": 600})
    try:
        drv.open()
        frame = np.zeros(N_IN)
        _run_until(drv, frame, lambda st: drv._delivered > 50)
        g0, d0 = drv.counters()["gap_frames"], emu.late_dropped
        with emu.lock:                    # the emulator's loop waits: a stall of the device
            stalled_at = emu.seq
            time.sleep(0.1)
        # until the host has a sample modelled after the stall (its sequence number is past
        # the 500 of the stall): the emulator has then counted what it did not send, and the
        # host has seen that gap. (Waiting for any new gap returned on an earlier one — this
        # thread-run emulator, starved on a loaded machine, drops late samples of its own —
        # before the emulator had run once after the stall.)
        _run_until(drv, frame, lambda st: frame[IN_SEQ] >= stalled_at + 400)
        dropped = emu.late_dropped - d0
        assert dropped >= 400, dropped    # ~500 samples of the stall modelled, not sent
        assert drv.counters()["gap_frames"] - g0 >= 400       # the host sees them as a gap
        assert drv.counters()["overflow_dropped"] == 0
    finally:
        drv.close()
        emu.stop()
