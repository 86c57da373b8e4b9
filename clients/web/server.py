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
    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._tabs: set[asyncio.Task[Any]] = set()

    async def handle_websocket(self, request: web.Request) -> web.WebSocketResponse:
        task = asyncio.current_task()
        assert task is not None
        self._tabs.add(task)
        try:
            return await super().handle_websocket(request)
        finally:
            self._tabs.discard(task)

    async def on_shutdown(self, app: web.Application) -> None:
        # Each open tab ends its UI (textual-serve tells the app to quit) instead of keeping
        # the server's graceful shutdown waiting on a websocket that never closes.
        for task in list(self._tabs):
            task.cancel()

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
            self._make_app(),
            sock=sock,
            handle_signals=False,
            loop=loop,
            print=lambda *a: None,
            shutdown_timeout=5.0,
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
