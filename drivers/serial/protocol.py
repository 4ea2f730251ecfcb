"""Binary protocol between the rig PC and the microcontroller front-end (codec).

The front-end samples the sensors at f_s = 5 kHz and sends one *sensor frame* per sample; the
rig PC answers each cycle with one *drive frame* carrying the four valve drive voltages.
Everything is little-endian. Full specification: docs/drivers.md.

Frame (both directions)::

    offset size  field
    0      2     sync  0xA5 0x5A
    2      1     type  0x01 sensor, 0x02 drive
    3      1     len   payload length, bytes (24 sensor, 14 drive)
    4      len   payload
    4+len  2     crc   CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF) over type, len, payload

Sensor payload (24 bytes, type 0x01)::

    u32 seq       sample counter, +1 per sample, wraps at 2**32
    u16 status    device status bits (DEV_*)
    i16 e_x, e_y  shaft displacement, 0.01 µm/LSB (±327 µm)
    u16 y_p1..4   valve positions, 1 mV/LSB (0…10 V)
    u16 phi       encoder angle, 2π/65536 rad/LSB
    i16 f_x, f_y  hammer force, 0.1 N/LSB

Drive payload (14 bytes, type 0x02)::

    u32 seq       host cycle counter
    u16 flags     bit 0: outputs enabled (0: the device applies its own safe hold voltage)
    u16 v1..v4    valve drive voltages, 1 mV/LSB, clamped to 0…10 000

At 30 bytes per sensor frame, 5 kHz is 150 kB/s: a USB CDC-ACM link (baud rate ignored) or a
UART at ≥ 2 Mbaud.

Host heartbeat: the device holds its safe voltage (r0 on every valve) when no valid drive
frame with outputs enabled and a host cycle counter different from the previous one arrived
for ``hold_timeout`` (default 2 ms, 10 periods), and reports it with ``DEV_HOST_TIMEOUT``
until the host drives again; so a host that freezes — its loop stopped, the process
suspended, a link replaying the last frame — leaves the valves safe in hardware, whatever
the host can still do.

The decoding functions are numba-compiled, work on preallocated arrays and allocate nothing:
they run inside the 5 kHz cycle.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

SYNC0, SYNC1 = 0xA5, 0x5A
TYPE_SENSOR, TYPE_DRIVE = 0x01, 0x02
SENSOR_LEN, DRIVE_LEN = 24, 14
SENSOR_FRAME = 4 + SENSOR_LEN + 2   # 30 bytes
DRIVE_FRAME = 4 + DRIVE_LEN + 2     # 20 bytes

# device status bits (sensor frame)
DEV_ENCODER_LOST = 1 << 0    # encoder index pulse missing / quadrature error (loop: STATUS_ENCODER)
DEV_ADC_OVERRANGE = 1 << 1   # an ADC channel clipped (loop: STATUS_SENSOR)
DEV_HOST_TIMEOUT = 1 << 2    # no valid drive frame for hold_timeout: holding safe voltage
DEV_DRIVE_CRC = 1 << 3       # a drive frame with a bad CRC was received

# scale factors (physical unit per LSB)
S_E = 0.01                   # µm
S_V = 0.001                  # V
S_PHI = 2.0 * math.pi / 65536.0   # rad
S_F = 0.1                    # N

# decoded sensor row layout (float64[N_ROW])
R_SEQ, R_STATUS, R_EX, R_EY, R_YP1, R_YP2, R_YP3, R_YP4, R_PHI, R_FX, R_FY = range(11)
N_ROW = 11

# counters (int64 state array)
C_RXLEN, C_HEAD, C_COUNT, C_LASTSEQ, C_FRAMES, C_CRC, C_GAP_FRAMES, C_GAP_EVENTS, \
    C_SKIPPED_BYTES, C_OVERFLOW, C_EVENTS = range(11)
N_STATE = 11
COUNTER_NAMES = {C_FRAMES: "frames", C_CRC: "crc_errors", C_GAP_FRAMES: "gap_frames",
                 C_GAP_EVENTS: "gaps", C_SKIPPED_BYTES: "skipped_bytes",
                 C_OVERFLOW: "overflow_dropped"}
# event bits accumulated in state[C_EVENTS] until the driver reads them
EV_CRC, EV_GAP, EV_OVERFLOW = 1, 2, 4


@njit(cache=True, nogil=True)
def crc16(buf, start, n):
    """CRC-16/CCITT-FALSE of ``buf[start:start+n]`` (uint8 array)."""
    crc = 0xFFFF
    for i in range(start, start + n):
        crc ^= np.int64(buf[i]) << 8
        for _ in range(8):
            if crc & 0x8000:
                crc = ((crc << 1) ^ 0x1021) & 0xFFFF
            else:
                crc = (crc << 1) & 0xFFFF
    return crc


@njit(cache=True, nogil=True)
def _put_u16(buf, i, v):
    buf[i] = v & 0xFF
    buf[i + 1] = (v >> 8) & 0xFF


@njit(cache=True, nogil=True)
def _put_u32(buf, i, v):
    for k in range(4):
        buf[i + k] = (v >> (8 * k)) & 0xFF


@njit(cache=True, nogil=True)
def _get_u16(buf, i):
    return np.int64(buf[i]) | (np.int64(buf[i + 1]) << 8)


@njit(cache=True, nogil=True)
def _get_i16(buf, i):
    v = _get_u16(buf, i)
    return v - 65536 if v >= 32768 else v


@njit(cache=True, nogil=True)
def _get_u32(buf, i):
    return _get_u16(buf, i) | (_get_u16(buf, i + 2) << 16)


@njit(cache=True, nogil=True)
def _q(x, scale, lo, hi):
    """Quantise ``x`` to an integer count with saturation (NaN -> lo)."""
    if x != x:  # NaN
        return lo
    v = np.int64(np.floor(x / scale + 0.5)) if abs(x / scale) < 1e12 else (hi if x > 0 else lo)
    return min(max(v, lo), hi)


@njit(cache=True, nogil=True)
def encode_sensor(buf, seq, status, ex, ey, yp1, yp2, yp3, yp4, phi, fx, fy):
    """Write one sensor frame into ``buf[0:30]`` (uint8); returns 30."""
    buf[0] = SYNC0
    buf[1] = SYNC1
    buf[2] = TYPE_SENSOR
    buf[3] = SENSOR_LEN
    _put_u32(buf, 4, seq & 0xFFFFFFFF)
    _put_u16(buf, 8, status & 0xFFFF)
    _put_u16(buf, 10, _q(ex, S_E, -32768, 32767) & 0xFFFF)
    _put_u16(buf, 12, _q(ey, S_E, -32768, 32767) & 0xFFFF)
    _put_u16(buf, 14, _q(yp1, S_V, 0, 65535))
    _put_u16(buf, 16, _q(yp2, S_V, 0, 65535))
    _put_u16(buf, 18, _q(yp3, S_V, 0, 65535))
    _put_u16(buf, 20, _q(yp4, S_V, 0, 65535))
    a = phi % (2.0 * math.pi)
    _put_u16(buf, 22, _q(a, S_PHI, 0, 65536) & 0xFFFF)
    _put_u16(buf, 24, _q(fx, S_F, -32768, 32767) & 0xFFFF)
    _put_u16(buf, 26, _q(fy, S_F, -32768, 32767) & 0xFFFF)
    _put_u16(buf, 28, crc16(buf, 2, 2 + SENSOR_LEN))
    return SENSOR_FRAME


@njit(cache=True, nogil=True)
def encode_drive(buf, seq, enabled, drive):
    """Write one drive frame (``drive``: float64[4], V) into ``buf[0:20]``; returns 20."""
    buf[0] = SYNC0
    buf[1] = SYNC1
    buf[2] = TYPE_DRIVE
    buf[3] = DRIVE_LEN
    _put_u32(buf, 4, seq & 0xFFFFFFFF)
    _put_u16(buf, 8, 1 if enabled else 0)
    for k in range(4):
        _put_u16(buf, 10 + 2 * k, _q(drive[k], S_V, 0, 10000))
    _put_u16(buf, 18, crc16(buf, 2, 2 + DRIVE_LEN))
    return DRIVE_FRAME


@njit(cache=True, nogil=True)
def _decode_sensor_row(buf, i, row):
    row[R_SEQ] = _get_u32(buf, i + 4)
    row[R_STATUS] = _get_u16(buf, i + 8)
    row[R_EX] = _get_i16(buf, i + 10) * S_E
    row[R_EY] = _get_i16(buf, i + 12) * S_E
    for k in range(4):
        row[R_YP1 + k] = _get_u16(buf, i + 14 + 2 * k) * S_V
    row[R_PHI] = _get_u16(buf, i + 22) * S_PHI
    row[R_FX] = _get_i16(buf, i + 24) * S_F
    row[R_FY] = _get_i16(buf, i + 26) * S_F


@njit(cache=True, nogil=True)
def ingest_sensor(rx, state, fifo):
    """Parse the bytes ``rx[0:state[C_RXLEN]]`` into the sensor-frame FIFO.

    Complete, CRC-valid sensor frames are appended to ``fifo`` (float64[cap, N_ROW], ring
    buffer with head ``state[C_HEAD]`` and count ``state[C_COUNT]``; when full the oldest is
    dropped and counted). Sequence gaps, CRC errors and skipped bytes are counted in
    ``state``; the unparsed tail is moved to the front of ``rx``. Returns frames added.
    """
    n = state[C_RXLEN]
    cap = fifo.shape[0]
    i = 0
    added = 0
    while n - i >= 4:
        if rx[i] != SYNC0 or rx[i + 1] != SYNC1:
            i += 1
            state[C_SKIPPED_BYTES] += 1
            continue
        ln = np.int64(rx[i + 3])
        if rx[i + 2] != TYPE_SENSOR or ln != SENSOR_LEN:
            i += 1  # not a frame we know: resynchronise
            state[C_SKIPPED_BYTES] += 1
            continue
        if n - i < SENSOR_FRAME:
            break  # incomplete: wait for more bytes
        if crc16(rx, i + 2, 2 + SENSOR_LEN) != _get_u16(rx, i + 4 + SENSOR_LEN):
            state[C_CRC] += 1
            state[C_EVENTS] |= EV_CRC
            i += 1
            state[C_SKIPPED_BYTES] += 1
            continue
        seq = _get_u32(rx, i + 4)
        last = state[C_LASTSEQ]
        if last >= 0:
            missing = (seq - last - 1) & 0xFFFFFFFF
            if missing != 0 and missing < 0x80000000:
                state[C_GAP_FRAMES] += missing
                state[C_GAP_EVENTS] += 1
                state[C_EVENTS] |= EV_GAP
        state[C_LASTSEQ] = seq
        if state[C_COUNT] == cap:
            state[C_HEAD] = (state[C_HEAD] + 1) % cap
            state[C_COUNT] -= 1
            state[C_OVERFLOW] += 1
            state[C_EVENTS] |= EV_OVERFLOW
        slot = (state[C_HEAD] + state[C_COUNT]) % cap
        _decode_sensor_row(rx, i, fifo[slot])
        state[C_COUNT] += 1
        state[C_FRAMES] += 1
        added += 1
        i += SENSOR_FRAME
    # compact
    rest = n - i
    for k in range(rest):
        rx[k] = rx[i + k]
    state[C_RXLEN] = rest
    return added


@njit(cache=True, nogil=True)
def pop_sensor(state, fifo, row):
    """Move the oldest FIFO frame into ``row``; False if the FIFO is empty."""
    if state[C_COUNT] == 0:
        return False
    h = state[C_HEAD]
    for k in range(N_ROW):
        row[k] = fifo[h, k]
    state[C_HEAD] = (h + 1) % fifo.shape[0]
    state[C_COUNT] -= 1
    return True


@njit(cache=True, nogil=True)
def drop_oldest(state, fifo, k):
    """Drop the ``k`` oldest FIFO frames (at most those queued); returns how many were
    dropped. O(1), nothing copied."""
    k = min(k, state[C_COUNT])
    if k > 0:
        state[C_HEAD] = (state[C_HEAD] + k) % fifo.shape[0]
        state[C_COUNT] -= k
    return k


@njit(cache=True, nogil=True)
def decode_drive(buf, i, out):
    """Decode a drive frame at ``buf[i]`` into ``out`` (float64[6]: seq, flags, v1..v4).

    Returns 1 if valid, 0 if the CRC is wrong, -1 if it is not a drive frame header.
    """
    if (buf[i] != SYNC0 or buf[i + 1] != SYNC1 or buf[i + 2] != TYPE_DRIVE
            or buf[i + 3] != DRIVE_LEN):
        return -1
    if crc16(buf, i + 2, 2 + DRIVE_LEN) != _get_u16(buf, i + 4 + DRIVE_LEN):
        return 0
    out[0] = _get_u32(buf, i + 4)
    out[1] = _get_u16(buf, i + 8)
    for k in range(4):
        out[2 + k] = _get_u16(buf, i + 10 + 2 * k) * S_V
    return 1
