"""Sample source: one wildcard subscriber on ``{prefix}/**`` that hands every message to a handler.

The handler (:class:`service.ports.MessageHandler`, in practice ``Monitor.on_message``) gets the
key, the payload bytes, the encoding string and the attachment bytes; decoding and validation
happen there, so that rejections are counted per loop.  An exception in the handler is logged
and swallowed: one bad message never stops the subscription.
"""

from __future__ import annotations

import logging
from collections.abc import Callable

import zenoh

__all__ = ["ZenohSampleSource"]

log = logging.getLogger("loopwatch.zenoh_source")


class ZenohSampleSource:
    """Subscribe to ``{prefix}/**`` on ``session`` and call ``handler(key, payload, encoding, attachment)``."""

    def __init__(self, session: zenoh.Session, prefix: str,
                 handler: Callable[[str, bytes, str, bytes | None], None]) -> None:
        self.prefix = prefix.rstrip("/")
        self.handler = handler
        self.errors = 0
        self._sub = session.declare_subscriber(f"{self.prefix}/**", self._on_sample)

    def _on_sample(self, sample: zenoh.Sample) -> None:
        try:
            if sample.kind != zenoh.SampleKind.PUT:
                return
            att = sample.attachment
            self.handler(str(sample.key_expr), sample.payload.to_bytes(), str(sample.encoding),
                         att.to_bytes() if att is not None else None)
        except Exception as exc:  # noqa: BLE001 - never let one message kill the subscriber
            self.errors += 1
            log.error("message on %s not handled: %r", sample.key_expr, exc)

    def close(self) -> None:
        try:
            self._sub.undeclare()
        except Exception:  # noqa: BLE001 - session already closed
            pass
