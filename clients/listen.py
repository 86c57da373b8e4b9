"""``--listen HOST:PORT`` for the servers that are clients of the key space (foxglove, web,
gateway)."""

from __future__ import annotations

import argparse

from schemas.errors import ConfigError
from schemas.session import add_target_arguments


def add_server_arguments(parser: argparse.ArgumentParser, default: str, who: str) -> None:
    """``--connect``/``--robot`` of the key space, and ``--listen`` (``who`` connects there)."""
    add_target_arguments(parser)
    parser.add_argument(
        "--listen",
        metavar="HOST:PORT",
        default=default,
        help=f"where {who} (default {default}; port 0 picks a free one)",
    )


def parse_listen(listen: str, what: str, example: str) -> tuple[str, int]:
    host, sep, port = listen.rpartition(":")
    if not sep or not host or not port.isdigit() or int(port) > 65535:
        raise ConfigError(
            f"{what} listen address {listen!r} is not HOST:PORT (e.g. {example}; "
            "port 0 picks a free one)"
        )
    return host.strip("[]"), int(port)
