"""Status and health: a queryable ``loopwatch/{instance}/status`` and a liveliness token
``loopwatch/{instance}/alive``.

A ``get`` on the status key answers the provider's status as JSON; the selector parameter
``loop=<loop_id>`` restricts the answer to that loop (useful with many loops).
"""

from __future__ import annotations

import json
import logging
from collections.abc import Callable
from typing import Any

import zenoh

__all__ = ["ZenohStatus", "status_key", "alive_key"]

log = logging.getLogger("loopwatch.zenoh_status")


def status_key(instance: str) -> str:
    return f"loopwatch/{instance}/status"


def alive_key(instance: str) -> str:
    return f"loopwatch/{instance}/alive"


class ZenohStatus:
    """Declare the status queryable and the liveliness token; :meth:`close` undeclares both."""

    def __init__(self, session: zenoh.Session, instance: str,
                 provider: Callable[[str | None], dict[str, Any]]) -> None:
        self.key = status_key(instance)
        self.provider = provider
        self._qbl = session.declare_queryable(self.key, self._on_query)
        self._token = session.liveliness().declare_token(alive_key(instance))

    def _on_query(self, query: zenoh.Query) -> None:
        try:
            loop = query.parameters.get("loop")
            body = self.provider(loop)
            query.reply(self.key, json.dumps(body), encoding=zenoh.Encoding.APPLICATION_JSON)
        except Exception as exc:  # noqa: BLE001 - answer with an error, keep serving
            log.error("status query failed: %r", exc)
            try:
                query.reply_err(json.dumps({"error": repr(exc)}), encoding=zenoh.Encoding.APPLICATION_JSON)
            except Exception:  # noqa: BLE001
                pass

    def close(self) -> None:
        for ent in (self._token, self._qbl):
            try:
                ent.undeclare()
            except Exception:  # noqa: BLE001
                pass
