"""``--listen HOST:PORT`` for the servers that are clients of the key space (foxglove, web)."""

from __future__ import annotations

from schemas.errors import ConfigError


def parse_listen(listen: str, what: str, example: str) -> tuple[str, int]:
    host, sep, port = listen.rpartition(":")
    if not sep or not host or not port.isdigit() or int(port) > 65535:
        raise ConfigError(
            f"{what} listen address {listen!r} is not HOST:PORT (e.g. {example}; "
            "port 0 picks a free one)"
        )
    return host.strip("[]"), int(port)
