"""The live stream and the `safe` command against a real daemon process (`rigd run`, simulated
plant, real-time clock, real socket): updates cover every frame once and equal the min/max of
the recorded HDF5 frames, bad subscriptions are one line, a subscriber that stops reading is
dropped, `rigd ctl safe` latches operator_safe with the excitation playing."""

import json
import socket
import time
from pathlib import Path

import h5py
import numpy as np
import pytest
import yaml
from daemon_helpers import PROCESS_S, Daemon, make_config
from faultkit import controller_file

from rigd.frame import REC
from rigd.service.client import ControlClient

ROOT_EXP = Path(__file__).resolve().parents[2] / "config" / "experiments"
CHANNELS = ["seq", "t", "e_x", "e_y", "u_x", "r_p1", "x_x", "k_on", "fault"]


@pytest.fixture(scope="module")
def daemon(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("stream")
    rec = tmp / "rec.h5"
    d = Daemon(tmp, make_config(tmp), "--record", str(rec), "--controller",
               str(controller_file(tmp)))
    d.rec = rec
    try:
        d.wait_notify("READY=1", timeout=300)   # a cold numba cache on a loaded machine
    except BaseException:
        d.stop()
        raise
    yield d
    code, _ = d.stop()
    assert code == 0, d.log()


def _client(d, timeout=30.0):
    return ControlClient(d.sock, timeout=timeout).connect()


def _wait(cond, what, timeout=60.0):
    end = time.monotonic() + timeout
    while not cond():
        if time.monotonic() > end:
            raise AssertionError(f"timed out waiting for {what}")
        time.sleep(0.01)


def _recorded(d, last_seq):
    """Frames of the daemon's recording once it holds ``last_seq`` (SWMR, flushed at 0.5 s)."""
    got = {}

    def have():
        with h5py.File(d.rec, "r", libver="latest", swmr=True) as f:
            fr = f["frames"][:]
        got["fr"] = fr
        return len(fr) and fr[-1, REC["seq"]] >= last_seq

    _wait(have, f"the recording to reach seq {last_seq}")
    return got["fr"]


def test_updates_cover_every_frame_once_and_bracket_the_recording(daemon):
    c = _client(daemon)
    it = c.stream(rate_hz=50, points=8, channels=CHANNELS)
    assert c.subscribed == {"fs_hz": 5000.0, "rate_hz": 50.0, "points": 8,
                            "channels": CHANNELS}
    ups, got_ns = [], []
    t0 = time.monotonic()
    for u in it:
        got_ns.append(time.time_ns())
        ups.append(u)
        if len(ups) == 100:
            break
    elapsed = time.monotonic() - t0
    c.close()
    # never faster than asked (no bursts after a stall); slower on a starved machine, where
    # each update covers more frames (the delivered rate is a bench figure: bench/web.py)
    assert len(ups) - 1 <= 50 * elapsed + 2
    seqs = [u["seq"] for u in ups]
    assert all(b > a for a, b in zip(seqs, seqs[1:]))
    for prev, u in zip(ups, ups[1:]):
        assert u["dropped"] == 0
        assert u["seq"] - u["n"] == prev["seq"], "each frame covered exactly once"
    for u, recv in zip(ups, got_ns):
        assert u["wall_ns"] <= recv
        assert 1 <= len(u["t"]) <= 8 and u["t_s"] == pytest.approx(u["seq"] / 5000.0)
        for ch in CHANNELS:
            lo, hi = np.array(u["min"][ch]), np.array(u["max"][ch])
            assert len(lo) == len(hi) == len(u["t"])
            assert np.all(lo <= hi)
        st = u["status"]
        assert isinstance(st["cycle"], int) and st["fault"]["code"] == 0 and st["running"]
        assert st["k_loaded"] is True and st["clock"] == "realtime"
    fr = _recorded(daemon, seqs[-1])
    by_seq = {int(s): i for i, s in enumerate(fr[:, REC["seq"]])}
    checked = 0
    for u in ups[1:]:
        first = u["seq"] - u["n"] + 1
        starts = [round(t * 5000.0) for t in u["t"]] + [u["seq"] + 1]
        assert starts[0] == first
        for b in range(len(u["t"])):
            rows = fr[by_seq[starts[b]]:by_seq[starts[b + 1] - 1] + 1]
            assert len(rows) == starts[b + 1] - starts[b]
            for ch in CHANNELS:
                col = rows[:, REC[ch]]
                lo, hi = u["min"][ch][b], u["max"][ch][b]    # rounded outward to 1e-5
                assert lo <= col.min() < lo + 1.0001e-5, (ch, lo, col.min())
                assert hi - 1.0001e-5 < col.max() <= hi, (ch, hi, col.max())
            checked += 1
    assert checked >= 99


@pytest.mark.parametrize("args,needle", [
    ({"rate_hz": 5}, "rate_hz"),
    ({"rate_hz": 1000}, "rate_hz"),
    ({"rate_hz": "fast"}, "rate_hz"),
    ({"points": 0}, "points"),
    ({"points": 2.5}, "points"),
    ({"channels": []}, "channels"),
    ({"channels": ["e_x", "nope"]}, "unknown channel 'nope'"),
    ({"channels": ["e_x", "e_x"]}, "named twice"),
    ({"channels": "e_x"}, "channels"),
    ({"every": 3}, "every: unknown argument"),
])
def test_bad_subscribe_is_one_line_and_no_stream(daemon, args, needle):
    with _client(daemon) as c:
        r = c.request("stream.subscribe", **args)
        assert r["ok"] is False and needle in r["error"], r
        assert r["error"].startswith("stream.subscribe: ") and "\n" not in r["error"]
        # the connection is still a plain request/reply one: the next line is ping's reply
        r = c.request("ping")
        assert r["ok"] and r["result"]["pong"]


def test_subscriber_that_stops_reading_is_dropped_daemon_unharmed(daemon):
    with _client(daemon) as probe:
        seq0 = probe.call("status")["seq"]
        n0 = probe.call("ping")["clients"]
        slow = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        slow.connect(daemon.sock)
        # every channel, as many points as allowed, 100 updates/s: ~6 MB/s, never read
        slow.sendall(b'{"id":1,"cmd":"stream.subscribe","rate_hz":100,"points":2000}\n')
        _wait(lambda: probe.call("ping")["clients"] == n0 + 1, "the slow client to connect")
        _wait(lambda: probe.call("ping")["clients"] == n0, "the slow subscriber to be dropped")
        # what it had been sent is still readable, then end of file
        slow.settimeout(30)
        data = b""
        while chunk := slow.recv(1 << 20):
            data += chunk
        slow.close()
        lines = data.split(b"\n")
        assert json.loads(lines[0])["ok"] is True
        assert any(b'"stream"' in ln for ln in lines[1:])
        st = probe.call("status")
        assert st["seq"] > seq0 and st["fault"]["code"] == 0 and st["running"]
        # and another subscriber is served as before
        c2 = _client(daemon)
        u = next(c2.stream(rate_hz=20, points=4, channels=["e_x"]))
        assert u["seq"] > seq0
        c2.close()


def test_ctl_safe_latches_operator_safe_with_the_excitation_playing(daemon):
    d = daemon
    d.ctl("enable")
    # the shipped PRBS, 20 s long: still playing when `safe` lands on a slow machine. The
    # latched fault ends the experiment at the fault's cycle (its record closed there); the
    # wait for it below is bounded by PROCESS_S, not by a guess of the machine
    spec = yaml.safe_load((ROOT_EXP / "prbs.yaml").read_text())
    spec["duration_s"] = 20.0
    exp = d.tmp / "prbs20.yaml"
    exp.write_text(yaml.safe_dump(spec))
    d.ctl("start", str(exp), "--run-dir", str(d.tmp / "runs" / "p"))
    c = _client(d)
    it = c.stream(rate_hz=50, points=4, channels=["x_x", "fault"])
    u = next(it)
    _wait(lambda: max(next(it)["max"]["x_x"]) > 0.5, "the PRBS excitation to play")
    r = d.ctl("safe")
    assert "safe state: FAULT operator_safe latched at cycle" in r.stdout, r.stdout
    st = d.ctl_json("status")
    assert st["fault"]["name"] == "operator_safe" and st["controller"]["enabled"] is False
    fault_seq = st["fault"]["seq"]
    # the stream shows it: status and the recorded fault channel
    for u in it:
        if u["status"]["fault"]["name"] == "operator_safe" and \
                u["seq"] - u["n"] + 1 > fault_seq:             # only frames after the trip
            break
    assert max(u["max"]["fault"]) == 14.0 and max(u["max"]["x_x"]) == 0.0
    c.close()
    _wait(lambda: d.ctl_json("experiment")["state"] != "running", "the experiment to stop",
          timeout=PROCESS_S)
    fr = _recorded(d, fault_seq + 50)
    i = int(np.flatnonzero(fr[:, REC["seq"]] == fault_seq)[0])
    before, after = fr[i - 200:i], fr[i:i + 50]
    assert np.any(before[:, REC["x_x"]] != 0) and np.all(before[:, REC["fault"]] == 0)
    assert np.all(after[:, REC["fault"]] == 14)
    assert np.all(after[:, REC["k_on"]] == 0)
    assert np.all(after[:, [REC[n] for n in ("x_x", "x_y", "k_x", "k_y", "r_x", "r_y")]] == 0)
    np.testing.assert_allclose(after[:, [REC[f"r_p{k}"] for k in range(1, 5)]], 5.0)
    # a second safe while latched: still answered, the first fault stays
    assert d.ctl_json("safe")["fault"]["seq"] == fault_seq
    d.ctl("reset")
    _wait(lambda: d.ctl_json("status")["fault"]["code"] == 0, "the reset")
