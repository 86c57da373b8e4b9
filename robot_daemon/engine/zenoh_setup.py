"""The daemon's Zenoh session: its configuration (listen, router or peers, credentials, TLS and
access control) and the errors that opening it can end in, told in words a user can act on."""

from __future__ import annotations

import json
from typing import Any

import zenoh

from robot_daemon.engine.fleet_join import ROUTER_CONNECT_TIMEOUT_MS, join_router
from robot_daemon.security.acl import Security
from schemas.errors import DarwinError
from schemas.session import MAX_MESSAGE_BYTES, Credentials, server_config, zenoh_reason


class ListenError(DarwinError):
    """The daemon cannot listen on its Zenoh endpoint."""


def open_session(
    listen: list[str],
    zcfg: dict[str, Any],
    *,
    router: str | None,
    connect: list[str],
    credentials: Credentials | None,
    security: Security | None,
) -> zenoh.Session:
    """Open the daemon's session on ``listen``, joining ``router`` (or the ``connect`` peers);
    raises :class:`ListenError` when it cannot."""
    conf = server_config(
        listen,
        int(zcfg.get("link_lease_ms", 3000)),
        max_message_bytes=int(zcfg.get("max_message_bytes", MAX_MESSAGE_BYTES)),
        mode=str(zcfg.get("mode", "peer")),
    )
    if router:
        join_router(conf, router, connect)
        if credentials is not None:
            credentials.apply(conf)
    elif connect:
        conf.insert_json5("connect/endpoints", json.dumps(connect))
    if security is not None:
        security.apply(conf)
    try:
        return zenoh.open(conf)
    except zenoh.ZError as exc:
        if router and "connect" in str(exc).lower():
            wait = ROUTER_CONNECT_TIMEOUT_MS / 1000
            raise ListenError(
                f"cannot reach the router at {router}: nothing answered within "
                f"{wait:g} s; start it first (`darwin router --listen ENDPOINT`) or fix "
                "--router"
            ) from None
        raise ListenError(
            f"cannot listen on {', '.join(listen)}: {zenoh_reason(exc)}; is "
            "another daemon or `darwin up` using it? Stop it, or pass --listen "
            "tcp/127.0.0.1:0 for any free port"
        ) from None
    finally:
        if security is not None:
            # Zenoh read the plaintext dictionary while opening: it need not stay on disk.
            security.close()
