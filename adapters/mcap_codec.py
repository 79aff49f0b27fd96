"""MCAP messages of the monitor recording: JSON Schemas, topics, encode and decode, pure.

One topic family per loop, all JSON messages with a JSON Schema (Foxglove and the ``mcap`` tools
open them):

* ``/loopwatch/{loop_id}/config`` -- ``loopwatch.LoopConfig``: the analysed signal, the grid and
  window, and the whole :class:`~pipeline.diagnosis.DiagnosisConfig` the window was analysed
  with (written before the loop's first window in every file, so each file replays on its own).
* ``/loopwatch/{loop_id}/window`` -- ``loopwatch.Window``: the samples the analysis saw: grid
  times ``t`` and, per signal, the values ``v`` (NaN = missing) and the data's own time stamps
  ``t_ns``.  Arrays are base64 of little-endian float64 / int64 (bit-exact; the convention of
  Foxglove's own schemas for binary fields, ``contentEncoding: base64``).
* ``/loopwatch/{loop_id}/result`` -- ``loopwatch.WindowResult``: verdict, reason, the gate's
  figures, kept IMFs, DNL per IMF, TDNL, the robust test, amplitude, period.  Plain JSON numbers
  (Foxglove can plot them); a non-finite figure is ``null``.
* ``/loopwatch/{loop_id}/alert`` -- ``loopwatch.Alert``: an alert transition, with the fields of
  ``foxglove.Log`` (timestamp, level, message, name) besides the monitor's alert JSON.
* ``/loopwatch/config`` -- ``loopwatch.RunConfig``: the settings the monitor ran with.

Times: ``log_time`` = ``publish_time`` = the window's last grid time in integer nanoseconds (the
data's time, not the wall clock); ``timestamp`` fields use Foxglove's ``{sec, nsec}``.  Floats
in JSON are written with Python's shortest round-trip repr, so they read back bit for bit.
"""

from __future__ import annotations

import base64
import dataclasses
import json
import math
import types
import typing
from typing import Any, Literal, Union, get_args, get_origin

import numpy as np

from pipeline.diagnosis import DiagnosisConfig, WindowDiagnosis

from .errors import AdapterError
from .payloads import SIGNALS, json_number

__all__ = [
    "SCHEMAS",
    "RUN_TOPIC",
    "RecordingFormatError",
    "loop_topic",
    "parse_topic",
    "seconds_to_ns",
    "ns_to_seconds",
    "decode_f64",
    "to_json",
    "from_json",
    "encode_window",
    "decode_window",
    "encode_result",
    "decode_diagnosis",
    "encode_alert",
    "encode_loop_config",
    "decode_diagnosis_config",
    "encode_run_config",
    "WindowRecord",
    "dumps",
]

RUN_TOPIC = "/loopwatch/config"
_KINDS = ("config", "window", "result", "alert")


class RecordingFormatError(AdapterError, ValueError):
    """A recorded message does not have the expected structure; the message names topic and field."""


# ---------------------------------------------------------------------------- schemas

_TIME = {"type": "object", "title": "time", "description": "Foxglove time: Unix seconds + nanoseconds",
         "properties": {"sec": {"type": "integer", "minimum": 0},
                        "nsec": {"type": "integer", "minimum": 0, "maximum": 999_999_999}},
         "required": ["sec", "nsec"], "additionalProperties": False}
_B64 = {"type": "string", "contentEncoding": "base64"}
_NUM = {"type": ["number", "null"], "description": "null when not finite"}
_NUMS = {"type": "array", "items": _NUM}

_WINDOW = {
    "title": "loopwatch.Window", "type": "object",
    "description": "One analysed window of a loop: the samples the analysis saw.",
    "properties": {
        "timestamp": _TIME, "loop": {"type": "string"}, "seq": {"type": "integer", "minimum": 0},
        "index0": {"type": "integer", "description": "grid index of the first sample"},
        "n": {"type": "integer", "minimum": 1}, "sample_time_s": {"type": "number", "exclusiveMinimum": 0},
        "t": dict(_B64, description="grid times, n little-endian float64 Unix seconds"),
        "signals": {
            "type": "object", "additionalProperties": False,
            "properties": {name: {
                "type": "object", "additionalProperties": False, "required": ["v"],
                "properties": {"v": dict(_B64, description="n little-endian float64 values, NaN = missing"),
                               "t_ns": dict(_B64, description="n little-endian int64: each sample's own time "
                                                              "stamp in Unix ns (the grid time where missing); "
                                                              "absent when every sample of the signal was "
                                                              "stamped on the grid (within 1 us): its time is t")}}
                for name in SIGNALS},
        },
    },
    "required": ["timestamp", "loop", "seq", "index0", "n", "sample_time_s", "t", "signals"],
    "additionalProperties": False,
}
_GATE = {"type": ["object", "null"], "properties": {
    "oscillating": {"type": "boolean"}, "period_s": _NUM, "amplitude": _NUM, "regularity": _NUM,
    "persistence": _NUM, "n_periods": {"type": "integer"}, "band_hz": {"type": ["array", "null"], "items": _NUM},
    "reason": {"type": "string"}}, "required": ["oscillating", "period_s", "reason"]}
_ROBUST = {"type": ["object", "null"], "properties": {
    "dnl": _NUM, "threshold": _NUM, "p_value": _NUM, "n_surrogates": {"type": "integer"},
    "band_hz": {"type": "array", "items": _NUM}}, "required": ["dnl", "threshold", "p_value"]}
_RESULT = {
    "title": "loopwatch.WindowResult", "type": "object",
    "description": "What the pipeline said about one window (gate, IMFs, DNL/TDNL, verdict).",
    "properties": {
        "timestamp": _TIME, "loop": {"type": "string"}, "seq": {"type": "integer", "minimum": 0},
        "verdict": {"enum": ["nonlinear", "linear", "uncertain", "not_oscillating", "invalid"]},
        "reason": {"type": "string"}, "method": {"enum": ["robust", "paper"]},
        "tdnl": _NUM, "dnl": _NUMS, "imfs_kept": {"type": "array", "items": {"type": "integer"}},
        "lambdas": _NUMS, "imf_frequencies_hz": _NUMS, "n_filled": {"type": "integer"},
        "guards": {"type": "array", "items": {"type": "string"}},
        "gate": _GATE, "robust": _ROBUST, "amplitude": _NUM, "period_s": _NUM,
        "n_missing": {"type": "integer", "minimum": 0},
    },
    "required": ["timestamp", "loop", "seq", "verdict", "reason", "method", "tdnl", "dnl", "gate",
                 "amplitude", "period_s", "n_missing"],
}
_ALERT = {
    "title": "loopwatch.Alert", "type": "object",
    "description": "An alert transition; timestamp/level/message/name as in foxglove.Log.",
    "properties": {
        "timestamp": _TIME, "level": {"type": "integer", "description": "foxglove.LogLevel: 2 INFO, 3 WARNING"},
        "message": {"type": "string"}, "name": {"type": "string"}, "seq": {"type": "integer", "minimum": 0},
        "loop": {"type": "string"}, "state": {"enum": ["raised", "cleared"]}, "verdict": {"type": "string"},
        "tdnl": _NUM, "dnl": _NUMS, "threshold": {"type": "number"}, "period_s": _NUM, "amplitude": _NUM,
        "signal": {"type": "string"},
        "window": {"type": "object", "properties": {"start_t": {"type": "number"}, "end_t": {"type": "number"},
                                                    "seq": {"type": "integer"}},
                   "required": ["start_t", "end_t", "seq"]},
        "consecutive_windows": {"type": "integer"}, "evidence": {"type": "string"},
    },
    "required": ["timestamp", "seq", "level", "message", "name", "loop", "state", "verdict", "tdnl", "dnl",
                 "threshold", "window", "consecutive_windows", "evidence"],
}
_LOOP_CONFIG = {
    "title": "loopwatch.LoopConfig", "type": "object",
    "description": "How the loop's windows are analysed (the full DiagnosisConfig).",
    "properties": {"timestamp": _TIME, "loop": {"type": "string"}, "signal": {"enum": ["pv", "op", "error"]},
                   "sample_time_s": {"type": "number"}, "length": {"type": "integer"},
                   "hop": {"type": "integer", "minimum": 1,
                           "description": "samples between window starts (absent in recordings before it was kept)"},
                   "diagnosis": {"type": "object"}},
    "required": ["timestamp", "loop", "signal", "diagnosis"],
}
_RUN_CONFIG = {
    "title": "loopwatch.RunConfig", "type": "object",
    "description": "The configuration the monitor ran with.",
    "properties": {"timestamp": _TIME, "instance": {"type": "string"},
                   "run_id": {"type": "string", "description": "one monitor run; alert states start afresh"},
                   "alerts": {
        "type": "object", "properties": {"raise_after": {"type": "integer", "minimum": 1},
                                         "clear_after": {"type": "integer", "minimum": 1}},
        "required": ["raise_after", "clear_after"]}, "settings": {"type": "object"}},
    "required": ["timestamp", "instance", "alerts"],
}

#: kind -> JSON Schema (``config`` is the per-loop one, ``run`` the monitor's)
SCHEMAS: dict[str, dict] = {"window": _WINDOW, "result": _RESULT, "alert": _ALERT, "config": _LOOP_CONFIG,
                            "run": _RUN_CONFIG}


def loop_topic(loop_id: str, kind: str) -> str:
    return f"/loopwatch/{loop_id}/{kind}"


def parse_topic(topic: str) -> tuple[str, str] | None:
    """``(loop_id, kind)`` of a loop topic; ``None`` for other topics (e.g. :data:`RUN_TOPIC`)."""
    if not topic.startswith("/loopwatch/") or topic == RUN_TOPIC:
        return None
    loop_id, _, kind = topic[len("/loopwatch/"):].rpartition("/")
    return (loop_id, kind) if loop_id and kind in _KINDS else None


# ---------------------------------------------------------------------------- numbers and times


def seconds_to_ns(t: np.ndarray | float) -> np.ndarray | int:
    """Unix seconds (float64) to integer nanoseconds, exact to the float's own resolution
    (``t * 1e9`` would round to 256 ns at today's times; whole seconds are split off first)."""
    a = np.asarray(t, dtype=np.float64)
    sec = np.floor(a)
    ns = sec.astype(np.int64) * 1_000_000_000 + np.rint((a - sec) * 1e9).astype(np.int64)
    return int(ns) if ns.ndim == 0 else ns


def ns_to_seconds(ns: np.ndarray | int) -> np.ndarray | float:
    a = np.asarray(ns, dtype=np.int64)
    s = (a // 1_000_000_000).astype(np.float64) + (a % 1_000_000_000) / 1e9
    return float(s) if s.ndim == 0 else s


def _stamp(ns: int) -> dict[str, int]:
    return {"sec": ns // 1_000_000_000, "nsec": ns % 1_000_000_000}


def _b64(x: np.ndarray, dtype: str) -> bytes:
    return base64.b64encode(np.ascontiguousarray(x, dtype=dtype).tobytes())


def decode_f64(s: str, n: int | None = None, *, dtype: str = "<f8", what: str = "array") -> np.ndarray:
    try:
        a = np.frombuffer(base64.b64decode(s, validate=True), dtype=dtype)
    except (ValueError, TypeError) as exc:
        raise RecordingFormatError(f"{what}: not base64 of {dtype} ({exc})") from None
    if n is not None and a.size != n:
        raise RecordingFormatError(f"{what}: {a.size} values where the window has {n}")
    return a.astype(np.float64 if dtype == "<f8" else np.int64)


def to_json(obj: Any) -> Any:
    """Dataclasses, tuples, numpy scalars -> JSON values; non-finite floats -> ``null``."""
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return {f.name: to_json(getattr(obj, f.name)) for f in dataclasses.fields(obj)}
    if isinstance(obj, dict):
        return {str(k): to_json(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [to_json(v) for v in obj]
    if isinstance(obj, (bool, np.bool_)):
        return bool(obj)
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        return json_number(obj)
    return obj


def from_json(tp: Any, v: Any) -> Any:
    """Inverse of :func:`to_json` for a (frozen) dataclass type ``tp``, driven by its type hints:
    ``null`` is ``None`` where the hint allows it, else NaN for a float."""
    origin = get_origin(tp)
    if origin in (Union, types.UnionType):
        args = get_args(tp)
        if v is None and type(None) in args:
            return None
        rest = [a for a in args if a is not type(None)]
        return from_json(rest[0], v)
    if v is None and tp is float:
        return math.nan
    if dataclasses.is_dataclass(tp):
        if not isinstance(v, dict):
            raise RecordingFormatError(f"{tp.__name__}: expected an object, got {type(v).__name__}")
        hints = typing.get_type_hints(tp)
        kw = {f.name: from_json(hints[f.name], v[f.name]) for f in dataclasses.fields(tp) if f.name in v}
        return tp(**kw)
    if origin is tuple:
        args = get_args(tp)
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(from_json(args[0], e) for e in v)
        return tuple(from_json(a, e) for a, e in zip(args, v))
    if tp is float:
        return float(v)
    if tp is int:
        return int(v)
    if tp is bool:
        return bool(v)
    if origin is Literal or tp is str:
        return v
    return v


def dumps(msg: dict) -> bytes:
    return json.dumps(msg, separators=(",", ":"), allow_nan=False).encode()


# ---------------------------------------------------------------------------- encode


def encode_window(window: Any, t_ns: np.ndarray) -> bytes:
    """The ``loopwatch.Window`` message (JSON bytes) of a window (duck-typed: ``loop_id, seq,
    index0, t, sample_time_s, signals, t_offset``); ``t_ns`` = :func:`seconds_to_ns` of ``window.t``.

    The base64 fields are spliced into the JSON text as they are (base64 needs no escaping):
    ``json.dumps`` would scan every one of their characters, which costs more than the encoding.
    """
    head = {"timestamp": _stamp(int(t_ns[-1])), "loop": window.loop_id, "seq": int(window.seq),
            "index0": int(window.index0), "n": int(window.t.size), "sample_time_s": float(window.sample_time_s)}
    parts = [dumps(head)[:-1], b',"t":"', _b64(window.t, "<f8"), b'","signals":{']
    for i, (name, v) in enumerate(window.signals.items()):
        parts += [b"," if i else b"", json.dumps(name).encode(), b':{"v":"', _b64(v, "<f8"), b'"']
        off = window.t_offset.get(name)
        if off is not None:
            parts += [b',"t_ns":"', _b64(t_ns + np.rint(off * 1e9).astype(np.int64), "<i8"), b'"']
        parts.append(b"}")
    parts.append(b"}}")
    return b"".join(parts)


def encode_result(loop_id: str, seq: int, end_ns: int, result: Any) -> dict:
    """The ``loopwatch.WindowResult`` message (``result``: diagnosis, amplitude, period_s, n_missing)."""
    msg = {"timestamp": _stamp(end_ns), "loop": loop_id, "seq": int(seq)}
    msg.update(to_json(result.diagnosis))
    msg.update(amplitude=json_number(result.amplitude), period_s=json_number(result.period_s), n_missing=int(result.n_missing))
    return msg


def encode_alert(alert: Any, end_ns: int, instance: str) -> dict:
    """The ``loopwatch.Alert`` message: ``alert.to_json()`` plus the foxglove.Log fields."""
    body = alert.to_json()
    raised = body["state"] == "raised"
    return {"timestamp": _stamp(end_ns), "seq": body["window"]["seq"], "level": 3 if raised else 2,
            "name": f"loopwatch.{instance}", "message": f"{body['loop']}: alert {body['state']} ({body['verdict']}): {body['evidence']}", **body}


def encode_loop_config(loop_id: str, window: Any, end_ns: int) -> dict:
    """The ``loopwatch.LoopConfig`` message from a window's analysis config and grid."""
    msg = {"timestamp": _stamp(end_ns), "loop": loop_id, "signal": window.analysis.signal,
           "sample_time_s": float(window.sample_time_s), "length": int(window.t.size),
           "diagnosis": to_json(window.analysis.diagnosis)}
    if getattr(window, "hop", None) is not None:
        msg["hop"] = int(window.hop)
    return msg


def encode_run_config(run_config: dict, now_ns: int) -> dict:
    msg = {"timestamp": _stamp(now_ns), "instance": "main", "alerts": {"raise_after": 3, "clear_after": 3}}
    msg.update(to_json(run_config))
    return msg


# ---------------------------------------------------------------------------- decode


@dataclasses.dataclass(frozen=True)
class WindowRecord:
    """A decoded ``loopwatch.Window``; ``times_ns[name]`` are the data's own time stamps."""

    loop_id: str
    seq: int
    index0: int
    t: np.ndarray
    sample_time_s: float
    signals: dict[str, np.ndarray]
    times_ns: dict[str, np.ndarray]
    log_time: int


def decode_window(msg: dict, log_time: int) -> WindowRecord:
    try:
        n = int(msg["n"])
        loop = msg["loop"]
        t = decode_f64(msg["t"], n, what=f"{loop} window {msg['seq']} t")
        signals, times = {}, {}
        grid_ns = None
        for name, d in msg["signals"].items():
            signals[name] = decode_f64(d["v"], n, what=f"{loop} window {msg['seq']} {name}")
            if "t_ns" in d:
                times[name] = decode_f64(d["t_ns"], n, dtype="<i8", what=f"{loop} window {msg['seq']} {name} t_ns")
            else:
                grid_ns = seconds_to_ns(t) if grid_ns is None else grid_ns
                times[name] = grid_ns
        return WindowRecord(loop, int(msg["seq"]), int(msg["index0"]), t, float(msg["sample_time_s"]), signals,
                            times, log_time)
    except (KeyError, TypeError) as exc:
        raise RecordingFormatError(f"window message lacks field {exc}") from None


def decode_diagnosis(msg: dict) -> tuple[WindowDiagnosis, float, float, int]:
    """``(diagnosis, amplitude, period_s, n_missing)`` of a ``loopwatch.WindowResult``."""
    try:
        diag = from_json(WindowDiagnosis, msg)
        return diag, from_json(float, msg["amplitude"]), from_json(float, msg["period_s"]), int(msg["n_missing"])
    except (KeyError, TypeError) as exc:
        raise RecordingFormatError(f"result message lacks field {exc}") from None


def decode_diagnosis_config(msg: dict) -> DiagnosisConfig:
    try:
        return from_json(DiagnosisConfig, msg["diagnosis"])
    except (KeyError, TypeError) as exc:
        raise RecordingFormatError(f"loop config message lacks field {exc}") from None
