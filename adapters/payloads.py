"""Key expressions and payloads of loop samples on the bus: decode and encode, pure.

Key layout: ``{prefix}/{loop_id}/{signal}``; ``loop_id`` may contain ``/`` (``plant/area1/FIC101/pv``
is loop ``area1/FIC101``, signal ``pv``) and ``signal`` is one of :data:`SIGNALS`.

Payload formats (see the README section "Feeding loopwatch"):

* **single sample**, JSON: ``{"t": 1718000000.0, "v": 42.1}`` (``t`` in Unix seconds).
* **JSON batch**: ``{"t0": 1718000000.0, "dt": 1.0, "v": [42.1, 42.3, ...]}``; sample ``i`` is at
  ``t0 + i * dt``.  ``null`` marks a missing sample.
* **binary batch**: the payload is the values as little-endian float64 (``numpy '<f8'``), the
  timing is in the attachment as JSON ``{"t0": ..., "dt": ...}``.  The encoding
  ``application/octet-stream;f64le[]`` (what the simulator sends) selects it; so does the default
  encoding ``zenoh/bytes`` when an attachment is present.

Every decode error is a :class:`PayloadError` whose ``reason`` is one of :data:`REJECT_REASONS`,
so that the service can count rejections per loop and per reason.  Values that are not finite
(NaN, inf) inside an otherwise good batch are dropped one by one and counted by the caller
(:attr:`Batch.n_nonfinite`); a single sample that is not finite is rejected.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass

import numpy as np

from .errors import AdapterError

__all__ = [
    "json_number",
    "SIGNALS",
    "REJECT_REASONS",
    "BINARY_ENCODING",
    "PayloadError",
    "Batch",
    "parse_key",
    "decode_payload",
    "encode_sample",
    "encode_json_batch",
    "encode_binary_batch",
]

#: the signals a loop can carry
SIGNALS = ("op", "pv", "sp", "mv", "mode")

#: why a message or a sample is rejected (the keys of the per-loop reject counters)
REJECT_REASONS = (
    "bad_key",          # the key does not have the {prefix}/{loop_id}/{signal} layout
    "unknown_signal",   # the last key segment is not one of SIGNALS
    "malformed",        # not JSON / not the expected structure / wrong binary length
    "wrong_type",       # a field has the wrong type (e.g. "v": "abc")
    "non_finite",       # NaN or inf value
    "bad_timestamp",    # t / t0 / dt not finite, dt <= 0, or outside the accepted time range
    "too_large",        # more samples in one batch than allowed
    "late",             # older than what the loop's buffer still holds (counted by the monitor)
    "duplicate",        # a sample already received for that grid point (counted by the monitor)
)

#: zenoh encoding string of the binary batch format
BINARY_ENCODING = "application/octet-stream;f64le[]"

#: hard cap on samples per message (a safe limit against corrupt or hostile input)
MAX_BATCH = 1_000_000


class PayloadError(AdapterError, ValueError):
    """A message that cannot be used; ``reason`` is one of :data:`REJECT_REASONS`."""

    def __init__(self, reason: str, message: str) -> None:
        super().__init__(message)
        self.reason = reason


@dataclass(frozen=True)
class Batch:
    """Decoded samples of one message: ``v[i]`` at ``t0 + i * dt``.

    ``dt`` is ``None`` for a single sample.  ``v`` holds only finite values, ``offsets`` their
    positions ``i`` in the original batch (a batch with dropped non-finite values has gaps),
    ``n_nonfinite`` how many were dropped.
    """

    t0: float
    dt: float | None
    v: np.ndarray
    offsets: np.ndarray
    n_nonfinite: int = 0

    @property
    def times(self) -> np.ndarray:
        """Unix time of every kept sample."""
        if self.dt is None:
            return np.full(self.v.size, self.t0)
        return self.t0 + self.offsets * self.dt


def json_number(v: float | None) -> float | None:
    """A figure as JSON can hold it: JSON has no NaN or infinity, so those (and ``None``) are ``null``."""
    if v is None:
        return None
    v = float(v)
    return v if math.isfinite(v) else None


def parse_key(key: str, prefix: str) -> tuple[str, str]:
    """Split ``{prefix}/{loop_id}/{signal}`` into ``(loop_id, signal)``.

    Raises
    ------
    PayloadError
        ``bad_key`` when the key is not under ``prefix`` or has no loop id; ``unknown_signal``
        when the last segment is not one of :data:`SIGNALS`.
    """
    head = prefix.rstrip("/") + "/"
    if not key.startswith(head):
        raise PayloadError("bad_key", f"key {key!r} is not under {prefix!r}")
    rest = key[len(head):]
    loop_id, sep, signal = rest.rpartition("/")
    if not sep or not loop_id or any(not part for part in loop_id.split("/")):
        raise PayloadError("bad_key", f"key {key!r} must be {prefix}/<loop_id>/<signal>")
    if signal not in SIGNALS:
        raise PayloadError("unknown_signal", f"key {key!r}: signal {signal!r} is not one of {', '.join(SIGNALS)}")
    return loop_id, signal


def _number(obj: dict, name: str, reason: str = "wrong_type") -> float:
    if name not in obj:
        raise PayloadError("malformed", f"field {name!r} missing")
    v = obj[name]
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise PayloadError(reason, f"field {name!r} must be a number, got {type(v).__name__} {v!r:.40}")
    return float(v)


def _check_time(t0: float, dt: float | None, n: int, time_range: tuple[float, float]) -> None:
    lo, hi = time_range
    if not math.isfinite(t0) or not lo <= t0 <= hi:
        raise PayloadError("bad_timestamp", f"time {t0!r} outside the accepted range [{lo:g}, {hi:g}] s")
    if dt is not None:
        if not (math.isfinite(dt) and dt > 0):
            raise PayloadError("bad_timestamp", f"dt {dt!r} must be a finite number > 0")
        end = t0 + (n - 1) * dt
        if not end <= hi:
            raise PayloadError("bad_timestamp", f"batch end time {end!r} beyond the accepted range (<= {hi:g} s)")


def _batch_values(values: np.ndarray, t0: float, dt: float, time_range: tuple[float, float]) -> Batch:
    if values.size == 0:
        raise PayloadError("malformed", "empty batch")
    if values.size > MAX_BATCH:
        raise PayloadError("too_large", f"{values.size} samples in one message (at most {MAX_BATCH})")
    _check_time(t0, dt, values.size, time_range)
    ok = np.isfinite(values)
    n_bad = int(values.size - np.count_nonzero(ok))
    if n_bad:
        offsets = np.flatnonzero(ok)
        values = values[ok]
    else:
        offsets = np.arange(values.size)
    return Batch(t0, dt, values, offsets, n_bad)


def decode_payload(
    payload: bytes,
    *,
    encoding: str = "",
    attachment: bytes | None = None,
    time_range: tuple[float, float] = (0.0, 4102444800.0),
) -> Batch:
    """Decode one message in any of the three formats (see the module docstring).

    Parameters
    ----------
    payload : message bytes.
    encoding : the zenoh encoding as a string (``str(sample.encoding)``); ``BINARY_ENCODING``
        selects the binary batch.
    attachment : the zenoh attachment bytes, or ``None``.
    time_range : accepted ``[min, max]`` Unix time in seconds; samples outside are
        ``bad_timestamp`` (default: 1970 to 2100).

    Returns
    -------
    Batch

    Raises
    ------
    PayloadError
        with the rejection reason.
    """
    binary = encoding.startswith("application/octet-stream") or (
        attachment is not None and (encoding == "" or encoding.startswith("zenoh/bytes"))
    )
    if binary:
        if attachment is None:
            raise PayloadError("malformed", "binary batch without the timing attachment {\"t0\", \"dt\"}")
        try:
            timing = json.loads(attachment)
        except (ValueError, UnicodeDecodeError):
            raise PayloadError("malformed", f"attachment is not JSON: {attachment[:40]!r}") from None
        if not isinstance(timing, dict):
            raise PayloadError("malformed", "attachment must be a JSON object {\"t0\", \"dt\"}")
        t0, dt = _number(timing, "t0", "bad_timestamp"), _number(timing, "dt", "bad_timestamp")
        if len(payload) % 8:
            raise PayloadError("malformed", f"binary batch of {len(payload)} bytes is not a multiple of 8")
        values = np.frombuffer(payload, dtype="<f8").astype(np.float64)
        return _batch_values(values, t0, dt, time_range)

    try:
        obj = json.loads(payload)
    except (ValueError, UnicodeDecodeError):
        raise PayloadError("malformed", f"not JSON: {bytes(payload[:40])!r}") from None
    if not isinstance(obj, dict):
        raise PayloadError("malformed", f"JSON must be an object, got {type(obj).__name__}")
    if "v" not in obj:
        raise PayloadError("malformed", "field 'v' missing")
    if isinstance(obj["v"], list):
        t0, dt = _number(obj, "t0", "bad_timestamp"), _number(obj, "dt", "bad_timestamp")
        raw = obj["v"]
        if len(raw) > MAX_BATCH:
            raise PayloadError("too_large", f"{len(raw)} samples in one message (at most {MAX_BATCH})")
        if any(isinstance(x, bool) or not (x is None or isinstance(x, (int, float))) for x in raw):
            raise PayloadError("wrong_type", "every item of 'v' must be a number or null")
        values = np.array([math.nan if x is None else x for x in raw], dtype=np.float64)
        return _batch_values(values, t0, dt, time_range)
    t = _number(obj, "t", "bad_timestamp")
    v = _number(obj, "v")
    _check_time(t, None, 1, time_range)
    if not math.isfinite(v):
        raise PayloadError("non_finite", f"value {v!r} is not finite")
    return Batch(t, None, np.array([v]), np.zeros(1, dtype=np.int64))


def encode_sample(t: float, v: float) -> bytes:
    """One sample as JSON ``{"t": t, "v": v}``."""
    return json.dumps({"t": float(t), "v": float(v)}).encode()


def encode_json_batch(t0: float, dt: float, v: np.ndarray) -> bytes:
    """A batch as JSON ``{"t0", "dt", "v": [...]}`` (NaN written as ``null``)."""
    vals = [None if not math.isfinite(x) else x for x in np.asarray(v, dtype=np.float64).tolist()]
    return json.dumps({"t0": float(t0), "dt": float(dt), "v": vals}).encode()


def encode_binary_batch(t0: float, dt: float, v: np.ndarray) -> tuple[bytes, bytes]:
    """A batch as ``(payload, attachment)``: ``<f8`` values and JSON timing ``{"t0", "dt"}``."""
    payload = np.ascontiguousarray(v, dtype="<f8").tobytes()
    return payload, json.dumps({"t0": float(t0), "dt": float(dt)}).encode()
