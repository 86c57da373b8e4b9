"""The asyncio TCP server: accepts any number of legacy clients on one shared Zenoh session.

Zenoh has no asyncio API: subscription callbacks reach the loop through the hub
(``call_soon_threadsafe``), and blocking arbiter queries run in a thread pool (``blocking``).
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import socket
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from typing import TypeVar

import zenoh

from clients.robot import Robot
from gateway.connection import Connection
from gateway.framing import DEFAULT_CONVENTION, encode_frame
from gateway.hub import Hub, HubRobot
from gateway.limits import RateLimitedLog
from gateway.messages import error_message
from gateway.orchestrate import Orchestrator
from gateway.settings import GatewaySettings
from schemas.errors import ErrorCode
from schemas.roles import Role
from schemas.session import Target, connect

log = logging.getLogger(__name__)
T = TypeVar("T")


class Gateway:
    def __init__(self, settings: GatewaySettings, target: Target) -> None:
        self.settings = settings
        self.target = target
        self.ratelog = RateLimitedLog(log, settings.log_interval)
        # Connects and disconnects are all worth a line, until someone opens hundreds.
        self.connlog = RateLimitedLog(log, settings.log_interval, burst=50)
        self.connections: set[Connection] = set()
        self.pool = ThreadPoolExecutor(settings.workers, thread_name_prefix="gateway-query")
        self.session: zenoh.Session | None = None
        self.hub: Hub = None  # type: ignore[assignment]  # set in start()
        self.orchestrator = Orchestrator(self)
        self.role: Role | None = None  # --role: the most this gateway may do (None: its identity's)
        self._server: asyncio.Server | None = None
        self._hub_robot: Robot | None = None

    async def blocking(self, fn: Callable[[], T]) -> T:
        """Run a blocking call (a Zenoh query) in the pool, off the event loop."""
        return await asyncio.get_running_loop().run_in_executor(self.pool, fn)

    async def start(self) -> tuple[str, int]:
        """Open the Zenoh session and listen; returns the real (host, port)."""
        loop = asyncio.get_running_loop()
        failed = f"gateway cannot open a Zenoh session to {self.target.endpoint}"
        self.session = await self.blocking(lambda: connect(self.target, failed))
        session = self.session
        self._hub_robot = hub_robot = await self.blocking(
            lambda: HubRobot(
                self.target.endpoint,
                self.target.robot,
                name="gateway",
                timeout=self.settings.command_timeout,
                session=session,
                role=self.role,
            )
        )
        # The daemon's versions against ours: another protocol major refuses to start.
        await self.blocking(lambda: hub_robot.check_protocol(3.0))
        self.hub = Hub(self._hub_robot, loop)
        host, port = self.settings.host_port
        self._server = await asyncio.start_server(self._accept, host, port, reuse_address=True)
        sock = self._server.sockets[0].getsockname()
        return sock[0], sock[1]

    async def _accept(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        if len(self.connections) >= self.settings.max_connections:
            await self._refuse(writer)
            return
        sock = writer.get_extra_info("socket")
        if sock is not None:
            with contextlib.suppress(OSError):
                sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
                if self.settings.socket_send_buffer > 0:
                    sock.setsockopt(
                        socket.SOL_SOCKET, socket.SO_SNDBUF, self.settings.socket_send_buffer
                    )
        conn = Connection(self, reader, writer)
        self.connections.add(conn)
        self.hub.join()
        self.connlog(
            "connect", logging.INFO, "%s connected (%d clients)", conn.peer, len(self.connections)
        )
        try:
            await conn.serve()
        except Exception as exc:
            # A bug must cost one connection, never the gateway, nor fill the disk with logs.
            self.ratelog(
                "failed", logging.ERROR, "connection %s failed: %r", conn.peer, exc, exc_info=True
            )
        finally:
            self.connections.discard(conn)
            self.hub.leave()
            self.connlog(
                "disconnect",
                logging.INFO,
                "%s disconnected (%d clients; %d monitor messages sent, %d stale dropped)",
                conn.peer,
                len(self.connections),
                conn.outbox.sent_monitor,
                conn.outbox.dropped_monitor,
            )

    async def _refuse(self, writer: asyncio.StreamWriter) -> None:
        """One error reply (in the default framing: the client has said nothing yet), then
        close: the gateway is full."""
        peer = writer.get_extra_info("peername") or ("?", 0)
        limit = self.settings.max_connections
        self.ratelog(
            "full",
            logging.WARNING,
            "%s:%s refused: %d clients connected (max_connections)",
            peer[0],
            peer[1],
            limit,
        )
        message = error_message(
            ErrorCode.BUSY,
            f"the gateway serves at most {limit} clients at once (max_connections): "
            "try again later",
        )
        with contextlib.suppress(Exception):
            writer.write(encode_frame(message, DEFAULT_CONVENTION))
            writer.close()
            await asyncio.wait_for(writer.wait_closed(), 1.0)
        writer.transport.abort()

    async def serve_forever(self) -> None:
        assert self._server is not None
        async with self._server:
            await self._server.serve_forever()

    async def close(self) -> None:
        if self._server is not None:
            self._server.close()
            for conn in list(self.connections):
                with contextlib.suppress(Exception):
                    conn.writer.close()
            with contextlib.suppress(Exception):
                await asyncio.wait_for(self._server.wait_closed(), 2.0)
        for conn in list(self.connections):
            with contextlib.suppress(Exception):
                await asyncio.wait_for(conn.closed.wait(), 2.0)
        if self.hub is not None:
            self.hub.close()
        if self._hub_robot is not None:
            self._hub_robot.close()
        if self.session is not None:
            with contextlib.suppress(Exception):
                self.session.close()
        self.pool.shutdown(wait=False, cancel_futures=True)
