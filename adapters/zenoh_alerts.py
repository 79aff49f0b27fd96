"""Alert sink: each alert transition is put as JSON on ``{alert_prefix}/{loop_id}``."""

from __future__ import annotations

import json

import zenoh

__all__ = ["ZenohAlertSink"]


class ZenohAlertSink:
    """Publishes :class:`service.monitor.Alert` objects (anything with ``loop_id`` and ``to_json()``).

    The JSON carries the instance name; puts use ``CongestionControl.BLOCK`` (an alert is never
    dropped under load) and ``Encoding.APPLICATION_JSON``.
    """

    def __init__(self, session: zenoh.Session, alert_prefix: str, instance: str) -> None:
        self.session = session
        self.alert_prefix = alert_prefix.rstrip("/")
        self.instance = instance
        self.published = 0

    def publish(self, alert) -> None:
        body = alert.to_json()
        body["instance"] = self.instance
        self.session.put(f"{self.alert_prefix}/{alert.loop_id}", json.dumps(body),
                         encoding=zenoh.Encoding.APPLICATION_JSON,
                         congestion_control=zenoh.CongestionControl.BLOCK)
        self.published += 1
