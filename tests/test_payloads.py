"""Payload formats and key layout (adapters.payloads): planted values round-trip; every kind of bad
input is rejected with its reason."""

import json
import math

import numpy as np
import pytest

from adapters.payloads import (
    BINARY_ENCODING,
    PayloadError,
    decode_payload,
    encode_binary_batch,
    encode_json_batch,
    encode_sample,
    parse_key,
)

T = 1_718_000_000.0


@pytest.mark.parametrize(
    "key, loop, signal",
    [
        ("plant/FIC101/pv", "FIC101", "pv"),
        ("plant/area1/FIC101/op", "area1/FIC101", "op"),
        ("plant/a/b/c/d/mode", "a/b/c/d", "mode"),
    ],
)
def test_parse_key(key, loop, signal):
    assert parse_key(key, "plant") == (loop, signal)


@pytest.mark.parametrize(
    "key, reason",
    [
        ("other/FIC101/pv", "bad_key"),
        ("plant/pv", "bad_key"),
        ("plant//pv", "bad_key"),
        ("plant/area1//pv", "bad_key"),
        ("plant/FIC101/temperature", "unknown_signal"),
        ("plant/FIC101/PV", "unknown_signal"),
    ],
)
def test_parse_key_rejects(key, reason):
    with pytest.raises(PayloadError) as e:
        parse_key(key, "plant")
    assert e.value.reason == reason


def test_single_sample():
    b = decode_payload(b'{"t": 1718000000.5, "v": 42.25}')
    assert b.dt is None and b.times.tolist() == [1718000000.5] and b.v.tolist() == [42.25]


def test_json_batch_with_null_gap():
    b = decode_payload(b'{"t0": 1718000000, "dt": 2, "v": [1, 2.5, null, 4]}')
    assert b.times.tolist() == [T, T + 2, T + 6]
    assert b.v.tolist() == [1.0, 2.5, 4.0]
    assert b.n_nonfinite == 1


def test_binary_batch_little_endian():
    payload = np.array([1.5, -2.0, 3.25], dtype="<f8").tobytes()
    att = json.dumps({"t0": T, "dt": 0.5}).encode()
    b = decode_payload(payload, encoding=BINARY_ENCODING, attachment=att)
    assert b.times.tolist() == [T, T + 0.5, T + 1.0]
    assert b.v.tolist() == [1.5, -2.0, 3.25]


def test_binary_with_default_encoding_and_attachment():
    payload = np.array([7.0], dtype="<f8").tobytes()
    b = decode_payload(payload, encoding="zenoh/bytes", attachment=b'{"t0": 1718000000, "dt": 1}')
    assert b.v.tolist() == [7.0]


def test_encoders_round_trip():
    v = np.array([0.1, math.nan, 3.0])
    b = decode_payload(encode_json_batch(T, 1.0, v))
    assert b.v.tolist() == [0.1, 3.0] and b.offsets.tolist() == [0, 2]
    p, a = encode_binary_batch(T, 1.0, v)
    b = decode_payload(p, encoding=BINARY_ENCODING, attachment=a)
    assert b.v.tolist() == [0.1, 3.0] and b.n_nonfinite == 1
    b = decode_payload(encode_sample(T + 3, -1.5))
    assert b.times.tolist() == [T + 3] and b.v.tolist() == [-1.5]


@pytest.mark.parametrize(
    "payload, reason",
    [
        (b"not json", "malformed"),
        (b"\xff\xfe", "malformed"),
        (b"[1, 2]", "malformed"),
        (b'{"t": 1718000000}', "malformed"),
        (b'{"v": 1.0}', "malformed"),
        (b'{"t": 1718000000, "v": "abc"}', "wrong_type"),
        (b'{"t": 1718000000, "v": true}', "wrong_type"),
        (b'{"t": "yesterday", "v": 1}', "bad_timestamp"),
        (b'{"t": 1718000000, "v": NaN}', "non_finite"),
        (b'{"t": 1718000000, "v": Infinity}', "non_finite"),
        (b'{"t": NaN, "v": 1}', "bad_timestamp"),
        (b'{"t": -5, "v": 1}', "bad_timestamp"),
        (b'{"t": 1e12, "v": 1}', "bad_timestamp"),
        (b'{"t0": 1718000000, "dt": 0, "v": [1]}', "bad_timestamp"),
        (b'{"t0": 1718000000, "dt": -1, "v": [1]}', "bad_timestamp"),
        (b'{"t0": 1718000000, "dt": 1, "v": []}', "malformed"),
        (b'{"t0": 1718000000, "dt": 1, "v": [1, "x"]}', "wrong_type"),
        (b'{"t0": 4102444790, "dt": 1, "v": [1,2,3,4,5,6,7,8,9,10,11,12]}', "bad_timestamp"),
    ],
)
def test_json_rejects(payload, reason):
    with pytest.raises(PayloadError) as e:
        decode_payload(payload)
    assert e.value.reason == reason


@pytest.mark.parametrize(
    "payload, att, reason",
    [
        (b"\x00" * 12, b'{"t0": 1718000000, "dt": 1}', "malformed"),     # not a multiple of 8 bytes
        (b"\x00" * 16, None, "malformed"),                               # no timing
        (b"\x00" * 16, b"garbage", "malformed"),
        (b"\x00" * 16, b'{"t0": 1718000000}', "malformed"),
        (b"\x00" * 16, b'{"t0": 1718000000, "dt": "1"}', "bad_timestamp"),
    ],
)
def test_binary_rejects(payload, att, reason):
    with pytest.raises(PayloadError) as e:
        decode_payload(payload, encoding=BINARY_ENCODING, attachment=att)
    assert e.value.reason == reason


def test_time_range_is_configurable():
    with pytest.raises(PayloadError) as e:
        decode_payload(b'{"t": 100.0, "v": 1}', time_range=(946684800.0, 4102444800.0))
    assert e.value.reason == "bad_timestamp"
    assert decode_payload(b'{"t": 100.0, "v": 1}', time_range=(0.0, 1e9)).v.tolist() == [1.0]
