"""Open a zenoh session on loopback-safe defaults (multicast scouting off, explicit endpoints)."""

from __future__ import annotations

import json
from collections.abc import Sequence

import zenoh

from .errors import AdapterError

__all__ = ["ZenohSetupError", "make_config", "open_session"]


class ZenohSetupError(AdapterError):
    """The zenoh session cannot be configured or opened; the message names the endpoint."""


def make_config(mode: str = "peer", *, listen: Sequence[str] = (), connect: Sequence[str] = (),
                gossip: bool = False) -> zenoh.Config:
    """A zenoh config with multicast scouting off and exactly the given endpoints.

    Parameters
    ----------
    mode : ``peer``, ``client`` or ``router``.
    listen : endpoints to listen on, e.g. ``["tcp/127.0.0.1:7447"]`` (nothing else is bound:
        the zenoh default would listen on every interface).
    connect : endpoints to connect to.
    gossip : gossip scouting (peers learning about each other through a common peer).
    """
    conf = zenoh.Config()
    try:
        conf.insert_json5("mode", json.dumps(mode))
        conf.insert_json5("scouting/multicast/enabled", "false")
        conf.insert_json5("scouting/gossip/enabled", json.dumps(bool(gossip)))
        conf.insert_json5("listen/endpoints", json.dumps(list(listen)))
        conf.insert_json5("connect/endpoints", json.dumps(list(connect)))
    except Exception as exc:  # zenoh.ZError
        raise ZenohSetupError(f"zenoh config (mode {mode!r}, listen {list(listen)}, connect {list(connect)}): {exc}") from None
    return conf


def open_session(mode: str = "peer", *, listen: Sequence[str] = (), connect: Sequence[str] = (),
                 gossip: bool = False) -> zenoh.Session:
    """Open a session (see :func:`make_config`); errors name the endpoints."""
    conf = make_config(mode, listen=listen, connect=connect, gossip=gossip)
    try:
        return zenoh.open(conf)
    except Exception as exc:  # zenoh.ZError: e.g. address in use, nothing to connect to
        raise ZenohSetupError(f"cannot open zenoh session (mode {mode!r}, listen {list(listen)}, "
                              f"connect {list(connect)}): {exc}") from None
