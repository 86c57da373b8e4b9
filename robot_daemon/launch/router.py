"""`darwin router`: a Zenoh router (a real router session, in this process) that robots and
clients join, so a fleet shares one key space and clients need only this one address.

Prints ``router: ENDPOINT`` once per address it listens on (flushed), then routes until Ctrl-C
or SIGTERM. Robots join with ``darwin up --router ENDPOINT``; clients connect to ENDPOINT
(``--connect``, ``DARWIN_ENDPOINT``) and name the robot (``--robot``).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import sys
import threading
from typing import Any

import zenoh

from config.loader import load_all
from robot_daemon.engine.fleet_join import stable_router_id
from robot_daemon.launch.endpoints import resolve_listen
from robot_daemon.security.acl import Security, check_listen
from robot_daemon.security.options import (
    add_security_arguments,
    secure_listen,
    security_from_args,
)
from schemas.errors import ConfigError, DarwinError
from schemas.session import open_session, server_config
from schemas.signals import on_stop_signals

DEFAULT_LISTEN = "tcp/127.0.0.1:7447"


class RouterError(DarwinError):
    """The router cannot listen where it was told to."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--listen",
        action="append",
        metavar="ENDPOINT",
        help=f"where robots and clients connect (repeatable; config router.listen, default "
        f"{DEFAULT_LISTEN}); port 0 picks a free one",
    )
    parser.add_argument("--config", help="user config file (TOML) on top of the shipped one")
    add_security_arguments(parser)


def listen_endpoints(
    args: argparse.Namespace, settings: dict[str, Any], security: Security | None = None
) -> list[str]:
    """The endpoints to listen on, checked, port 0 replaced by a free port (``tls/`` ones with
    ``--secure``)."""
    wanted = args.listen or list(settings.get("router", {}).get("listen", [DEFAULT_LISTEN]))
    try:
        listen = resolve_listen(secure_listen(wanted, security, explicit=bool(args.listen)))
    except ValueError as exc:  # a malformed endpoint names itself
        raise ConfigError(f"{exc} (--listen)") from None
    for warning in check_listen(listen, security):
        print(f"darwin router: {warning}", file=sys.stderr, flush=True)
    return listen


def router_config(listen: list[str], settings: dict[str, Any]) -> zenoh.Config:
    """The router session's configuration. Authentication, TLS and access control are added
    here (from the ``--auth``/``--secure`` options) by the security work."""
    rcfg = settings.get("router", {})
    zcfg = settings.get("zenoh", {})
    lease = int(rcfg.get("link_lease_ms", zcfg.get("link_lease_ms", 3000)))
    conf = server_config(listen, lease, mode="router")
    # The same ID after a restart: robots that protect their own endpoint trust their router
    # by it (``robot_daemon.engine.fleet_join``), so a restarted router is let in again.
    conf.insert_json5("id", json.dumps(stable_router_id(listen)))
    return conf


def open_router(listen: list[str], conf: zenoh.Config) -> zenoh.Session:
    def fix(reason: str) -> str:
        if "in use" in reason:
            return (
                "is another router or `darwin up` using it? Stop it, or pass --listen "
                "tcp/127.0.0.1:0 for any free port"
            )
        return "pass an address of this machine (tcp/0.0.0.0:7447 for all its interfaces)"

    return open_session(conf, f"cannot listen on {', '.join(listen)}", fix, RouterError)


def run(args: argparse.Namespace) -> int:
    settings = load_all(args.config)
    try:
        security = security_from_args(args)
    except ValueError as exc:
        raise ConfigError(str(exc)) from None
    listen = listen_endpoints(args, settings, security)
    conf = router_config(listen, settings)
    # The router enforces the roles for everyone who goes through it: robots (role robot)
    # and every client of the fleet (docs/security.md).
    if security is not None:
        security.apply(conf)
    stop = threading.Event()
    on_stop_signals(lambda _signum: stop.set())
    try:
        session = open_router(listen, conf)
    finally:
        if security is not None:
            security.close()  # Zenoh read the dictionary while opening
    try:
        for ep in listen:
            print(f"router: {ep}", flush=True)
        stop.wait()
        return 0
    finally:
        with contextlib.suppress(Exception):
            session.close()
        sys.stdout.flush()
