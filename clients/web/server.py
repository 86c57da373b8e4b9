"""textual-serve's server, printing our address line and logging through ours."""

from __future__ import annotations

import logging
from typing import Any

from textual_serve.server import Server

from schemas.errors import ConfigError


class WebServer(Server):
    def initialize_logging(self) -> None:
        # textual-serve would install a rich handler on stdout; stdout carries only our
        # address line, the rest goes to the `darwin` logging on stderr.
        logging.getLogger("textual-serve").setLevel(logging.WARNING)

    async def on_startup(self, app: Any) -> None:
        print(f"web: {self.public_url}", flush=True)


def serve(command: str, host: str, port: int, title: str) -> None:
    server = WebServer(command, host=host, port=port, title=title)
    try:
        server.serve()
    except OSError as exc:
        raise ConfigError(
            f"cannot serve the web UI on {host}:{port}: {exc.strerror or exc}; "
            "choose another --listen"
        ) from None
