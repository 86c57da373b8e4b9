"""``--auth FILE`` / ``--secure`` / ``--mtls`` / ``--certs DIR``: the same for every program that
listens for clients (``darwin daemon``, ``darwin up``, ``darwin router``)."""

from __future__ import annotations

import argparse
from pathlib import Path

from robot_daemon.security.acl import Security, check_listen, default_certs_dir
from robot_daemon.security.users import default_users_file


def add_security_arguments(parser: argparse.ArgumentParser) -> None:
    group = parser.add_argument_group("security (docs/security.md)")
    group.add_argument(
        "--auth",
        metavar="FILE",
        help="log clients in with the identities in FILE (`darwin users`) and enforce their "
        "roles with Zenoh access control",
    )
    group.add_argument(
        "--secure",
        action="store_true",
        help=f"TLS + authentication + access control (identities: --auth, default "
        f"{default_users_file()}; certificates: --certs)",
    )
    group.add_argument(
        "--mtls",
        action="store_true",
        help="with --secure: clients log in with certificates (`darwin certs --client NAME`) "
        "instead of passwords",
    )
    group.add_argument(
        "--certs",
        metavar="DIR",
        help=f"certificates of `darwin certs` (default {default_certs_dir()})",
    )


def security_from_args(args: argparse.Namespace) -> Security | None:
    secure = bool(getattr(args, "secure", False))
    auth = getattr(args, "auth", None)
    if getattr(args, "mtls", False) and not secure:
        raise ValueError("--mtls needs --secure (client certificates travel over TLS)")
    if not secure and not auth:
        return None
    certs = getattr(args, "certs", None)
    return Security(
        users_file=Path(auth) if auth else default_users_file(),
        tls=secure,
        mtls=bool(getattr(args, "mtls", False)),
        certs_dir=Path(certs) if certs else default_certs_dir(),
    )


def secure_listen(listen: list[str], security: Security | None, explicit: bool) -> list[str]:
    """With TLS the shipped default endpoints become ``tls/`` (an explicit ``tcp/`` is an
    error); returns the endpoints and prints the open-address warnings."""
    if security is not None and security.tls and not explicit:
        listen = [f"tls/{ep.split('/', 1)[1]}" if ep.startswith("tcp/") else ep for ep in listen]
    return listen


def listen_warnings(listen: list[str], security: Security | None) -> list[str]:
    return check_listen(listen, security)
