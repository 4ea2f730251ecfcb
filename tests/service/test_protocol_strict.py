"""Strict request fields: no coercion of strings or booleans into numbers (``op`` with "3000"
or true), bounded nesting, and the inline spec / ids keep working."""

import json

import pytest

from rigd.service.protocol import MAX_DEPTH, RequestError, parse_request


def _refusal(req) -> str:
    line = req if isinstance(req, bytes) else json.dumps(req).encode()
    with pytest.raises(RequestError) as ei:
        parse_request(line)
    msg = str(ei.value)
    assert "\n" not in msg
    return msg


@pytest.mark.parametrize("field, value", [
    ("omega_rpm", "3000"), ("omega_rpm", True), ("omega_rpm", None), ("omega_rpm", [3000]),
    ("p_inj_bar", "4"), ("p_inj_bar", False), ("p_inj_bar", {"v": 4}),
])
def test_operating_point_numbers_are_numbers(field, value):
    req = {"id": 1, "cmd": "operating_point.set", "omega_rpm": 3000.0, "p_inj_bar": 4.0}
    req[field] = value
    msg = _refusal(req)
    assert msg.startswith(f"operating_point.set: {field}: "), msg


def test_ints_are_still_numbers_and_the_values_arrive_as_floats():
    _, cmd, args = parse_request(b'{"cmd": "operating_point.set", "omega_rpm": 3000, '
                                 b'"p_inj_bar": 4}')
    assert cmd == "operating_point.set" and args.omega_rpm == 3000.0
    assert isinstance(args.omega_rpm, float)


@pytest.mark.parametrize("req, where", [
    ({"cmd": "controller.load", "path": 5}, "controller.load: path"),
    ({"cmd": "controller.load", "path": True}, "controller.load: path"),
    ({"cmd": "experiment.start", "path": "/a.yaml", "run_dir": 1}, "experiment.start: run_dir"),
    ({"cmd": "experiment.start", "spec": "prbs"}, "experiment.start: spec"),
    ({"cmd": "stream.subscribe", "points": 200.0}, "stream.subscribe: points"),
    ({"cmd": "stream.subscribe", "points": "200"}, "stream.subscribe: points"),
    ({"cmd": "stream.subscribe", "rate_hz": True}, "stream.subscribe: rate_hz"),
    ({"cmd": "stream.subscribe", "channels": "e_x"}, "stream.subscribe: channels"),
    ({"cmd": "safe", "now": True}, "safe: now: unknown argument"),
    ({"cmd": True}, "no 'cmd' string"),
])
def test_every_command_field_is_typed_strictly(req, where):
    assert where in _refusal(req)


def test_nesting_is_bounded():
    ok = {"cmd": "experiment.start", "spec": {"a": {"b": [[1]]}}}
    parse_request(json.dumps(ok).encode())            # validated further by the experiment
    deep = b'{"cmd": "ping", "x": ' + b"[" * 40 + b"]" * 40 + b"}"
    assert f"deeper than {MAX_DEPTH} levels" in _refusal(deep)
    very = b"[" * 200_000 + b"]" * 200_000          # beyond the recursion limit of the parser
    assert f"deeper than {MAX_DEPTH} levels" in _refusal(very)
