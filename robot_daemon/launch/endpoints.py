"""Where the robot listens, which router it joins and whether its login needs one: what
``darwin up``, ``darwin daemon`` and ``darwin router`` decide before starting anything. Kept apart
from the daemon's modules so that the launcher and the router decide it without importing the
engine (a start-up cost)."""

from __future__ import annotations

import argparse
from typing import Any

from schemas.errors import ConfigError
from schemas.session import check_endpoint, endpoint_host_port, free_tcp_port


def resolve_listen(listen: list[str]) -> list[str]:
    """The endpoints checked, each port 0 replaced by a free port now (so it can be printed
    and passed on before anything listens)."""
    out = []
    for ep in listen:
        check_endpoint(ep)
        host, port = endpoint_host_port(ep)
        if port == 0:
            ep = f"{ep.split('/', 1)[0]}/{host}:{free_tcp_port(host)}"
        out.append(ep)
    return out


def router_of(args: argparse.Namespace, settings: dict[str, Any]) -> str | None:
    """The router to join (``--router``, else config ``zenoh.router``), checked; None: none."""
    router = args.router or str(settings.get("zenoh", {}).get("router", "") or "") or None
    if router is not None:
        try:
            check_endpoint(router)
        except ValueError as exc:
            raise ConfigError(f"{exc} (--router)") from None
    return router


def check_login_needs_router(args: object, router: str | None) -> None:
    """``--user``/``--password-file``/``--cert``/``--key``/``--ca`` on a robot say who it is to
    a router: without one they would be ignored, so they are refused (the variables
    ``DARWIN_USER``… are a person's client login and stay unread)."""
    given = [f"--{o.replace('_', '-')}" for o in ("user", "password_file", "cert", "key", "ca")
             if getattr(args, o, None)]
    # Without --router, `darwin up --tui`'s --user… are the login of the person at the UI.
    if given and not router and not getattr(args, "tui", False):
        raise ValueError(
            f"{'/'.join(given)} log this robot in to a router: add --router ENDPOINT, or drop "
            "them (to require logins at this robot's own endpoint, use --auth FILE or --secure; "
            "with --tui they are the UI's login)"
        )
