"""Ports of the monitor: the small interfaces the core talks to, implemented in :mod:`adapters`.

The monitor core (:mod:`service.monitor`) only knows these Protocols; the composition root
(:mod:`service.composition`) wires the real zenoh adapters, tests wire in-memory fakes.
Recorders (MCAP, rerun) are further :class:`WindowSink` / :class:`AlertSink` implementations.

Sink lifecycle and health: a sink may also implement :class:`Closeable` (the monitor calls
``close()`` once, after the last window) and :class:`SinkHealth` (``status()`` is shown under
``status["sinks"][name]``).  A sink must never stop the monitor: the monitor catches and counts
exceptions of ``on_window`` / ``publish``, but a sink that can fail for a long time (a recorder
on a full disk) should degrade instead -- drop and count, report it in ``status()``, retry later.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

if TYPE_CHECKING:
    from .monitor import Alert, WindowResult, WindowSamples

__all__ = ["AlertSink", "WindowSink", "Closeable", "SinkHealth", "MessageHandler", "StatusProvider", "Clock"]


@runtime_checkable
class AlertSink(Protocol):
    """Receives every alert transition (``raised`` / ``cleared``), in window order per loop."""

    def publish(self, alert: "Alert") -> None: ...


@runtime_checkable
class WindowSink(Protocol):
    """Receives every analysed window: its raw samples and what the pipeline said about it.

    Called in window order per loop, after the alert state machine has seen the window
    (``alert`` is the transition it caused, or ``None``).
    """

    def on_window(self, loop_id: str, window: "WindowSamples", result: "WindowResult",
                  alert: "Alert | None") -> None: ...


@runtime_checkable
class Closeable(Protocol):
    """A sink holding resources (files, threads): ``close()`` flushes and releases them; called once."""

    def close(self) -> None: ...


@runtime_checkable
class SinkHealth(Protocol):
    """A sink that reports its health: ``name`` (key under ``status["sinks"]``) and a JSON-ready
    ``status()`` dict (e.g. ``{"state": "ok" | "degraded", ...}``)."""

    name: str

    def status(self) -> dict[str, Any]: ...


class MessageHandler(Protocol):
    """What a sample source calls for every message it receives (key, payload, encoding, attachment)."""

    def __call__(self, key: str, payload: bytes, encoding: str, attachment: bytes | None) -> None: ...


class StatusProvider(Protocol):
    """Something that can describe its state as a JSON-ready dict (optionally for one loop)."""

    def status(self, loop: str | None = None) -> dict[str, Any]: ...


class Clock(Protocol):
    """A monotonic clock in seconds; injected where the service needs time (log rate, latency)."""

    def __call__(self) -> float: ...
