"""textual-serve's server on a socket we bind first, printing our address line once it serves."""

from __future__ import annotations

import asyncio
import logging
import signal
import socket
from typing import Any

from aiohttp import web
from textual_serve.server import Server

from schemas.errors import ConfigError


class WebServer(Server):
    def initialize_logging(self) -> None:
        # textual-serve would install a rich handler on stdout; stdout carries only our
        # address line, the rest goes to the `darwin` logging on stderr.
        logging.getLogger("textual-serve").setLevel(logging.WARNING)

    async def on_startup(self, app: Any) -> None:
        print(f"web: {self.public_url}", flush=True)

    def serve_on(self, sock: socket.socket) -> None:
        """``Server.serve`` on an already bound socket (so a busy port is reported before
        anything is printed, and port 0 becomes the real port)."""
        self.initialize_logging()
        loop = asyncio.new_event_loop()
        asyncio.set_event_loop(loop)
        for sig in (signal.SIGINT, signal.SIGTERM):
            loop.add_signal_handler(sig, self.request_exit)
        web.run_app(
            self._make_app(), sock=sock, handle_signals=False, loop=loop, print=lambda *a: None
        )


def bind(host: str, port: int) -> socket.socket:
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    try:
        return socket.create_server((host, port), family=family)
    except OSError as exc:
        raise ConfigError(
            f"cannot serve the web UI on {host}:{port}: {exc.strerror or exc}; "
            "choose another --listen"
        ) from None


def serve(command: str, host: str, port: int, title: str) -> None:
    sock = bind(host, port)
    server = WebServer(command, host=host, port=sock.getsockname()[1], title=title)
    server.serve_on(sock)
