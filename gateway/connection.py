"""One legacy client: its framing, monitor set and period, commands and control lease."""

from __future__ import annotations

import asyncio
import contextlib
import functools
import logging
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from clients.robot import Commander
from gateway.framing import FrameDecoder, FramingError, encode_frame
from gateway.limits import TokenBucket
from gateway.messages import (
    Led,
    MessageError,
    Monitor,
    Operate,
    Orchestrate,
    OrchestrateStop,
    Playball,
    Request,
    Walk,
    error_message,
    parse_message,
    status_message,
)
from gateway.monitor import MonitorView
from gateway.outbox import Outbox, SlowReaderError
from gateway.translate import (
    Command,
    led_command,
    operate_command,
    playball_command,
    walk_command,
)
from schemas.errors import (
    ClientError,
    CommandError,
    DarwinError,
    ErrorCode,
    LeaseBusyError,
    NoLeaseError,
)

if TYPE_CHECKING:
    from gateway.server import Gateway

log = logging.getLogger(__name__)

READ_CHUNK = 65536


class Connection:
    def __init__(
        self, gateway: Gateway, reader: asyncio.StreamReader, writer: asyncio.StreamWriter
    ) -> None:
        self.gw = gateway
        self.settings = gateway.settings
        self.reader = reader
        self.writer = writer
        peer = writer.get_extra_info("peername") or ("?", 0)
        self.peer = f"{peer[0]}:{peer[1]}"
        self.decoder = FrameDecoder(self.settings.max_message)
        self.view = MonitorView()
        self.period = self.settings.monitor_period
        self.bucket = TokenBucket(self.settings.max_rate, self.settings.burst)
        self.outbox = Outbox(writer, self._monitor_bytes, self.settings.max_pending_replies)
        self.commander: Commander | None = None
        self.has_lease = False
        self._ticker: asyncio.Task[None] | None = None
        self._idle: asyncio.TimerHandle | None = None
        self._releasing: asyncio.Task[None] | None = None
        self._camera = False
        self._camera_fits = True
        self.closed = asyncio.Event()

    # -- life ----------------------------------------------------------------------------------
    async def serve(self) -> None:
        transport = self.writer.transport
        transport.set_write_buffer_limits(high=self.settings.write_buffer)
        writer_task = asyncio.create_task(self._write(), name=f"write {self.peer}")
        try:
            await self._read()
        finally:
            writer_task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await writer_task
            await self._close()

    async def _write(self) -> None:
        try:
            await self.outbox.run()
        except (ConnectionError, OSError):
            pass
        except Exception:
            log.exception("writing to %s failed: closing it", self.peer)
        # The connection cannot be written to any more: end the reader too.
        self.writer.transport.abort()

    async def _read(self) -> None:
        while True:
            try:
                data = await self.reader.read(READ_CHUNK)
            except (ConnectionError, OSError):
                return
            if not data:
                return
            try:
                frames = self.decoder.feed(data)
            except FramingError as exc:
                await self._framing_failed(exc)
                return
            for frame in frames:
                wait = self.bucket.take()
                if wait > 0:
                    self.gw.ratelog(
                        "throttle",
                        logging.WARNING,
                        "%s sends faster than %g messages/s: slowed down",
                        self.peer,
                        self.settings.max_rate,
                    )
                    await asyncio.sleep(wait)
                await self.handle(frame.value)
                if self.writer.transport.is_closing():
                    return
            if self.decoder.error is not None:
                # Good frames before the break were handled; now the break itself.
                await self._framing_failed(self.decoder.error)
                return

    async def _framing_failed(self, exc: FramingError) -> None:
        self.gw.ratelog("reject", logging.WARNING, "%s: %s (closing)", self.peer, exc.message)
        self.send(error_message(exc.code, f"{exc.message}; closing the connection"))
        await self.outbox.flush(timeout=1.0)

    async def _close(self) -> None:
        self._stop_ticker()
        if self._camera:
            self._camera = False
            self.gw.hub.unwatch_camera()
        if self._idle is not None:
            self._idle.cancel()
        self.gw.orchestrator.detach(self)
        with contextlib.suppress(Exception):
            self.writer.close()
        if self.commander is not None:
            # Our liveliness token goes with the commander: the arbiter releases the lease and
            # brings the robot to a safe stop if this client held it.
            await self.gw.blocking(self.commander.close)
        self.closed.set()

    # -- sending -------------------------------------------------------------------------------
    def send(self, message: dict[str, Any]) -> None:
        """Queue a reply (errors, status): never dropped. A client that lets too many pile up
        is disconnected instead."""
        try:
            data = encode_frame(message, self.decoder.reply_convention(), self.settings.max_message)
        except FramingError as exc:
            data = encode_frame(
                error_message(exc.code, exc.message), self.decoder.reply_convention()
            )
        try:
            self.outbox.reply(data)
        except SlowReaderError as exc:
            log.warning("closing %s: %s", self.peer, exc)
            self.writer.transport.abort()

    def error(self, code: ErrorCode | str, message: str) -> None:
        self.gw.ratelog("reject", logging.INFO, "%s: rejected: %s", self.peer, message)
        self.send(error_message(code, message))

    def _monitor_bytes(self) -> bytes | None:
        if not self.view.active:
            return None
        conv = self.decoder.reply_convention()
        message = self.view.build(self.gw.hub.snapshot(), camera=self._camera_fits)
        try:
            return encode_frame(message, conv, self.settings.max_message)
        except FramingError as exc:
            # An image too big for this client's framing (4 ASCII digits say at most 9999
            # bytes) or the maximum: from now on send the rest, and say once why.
            self._camera_fits = False
            message["monitor"].pop("camera", None)
            self.gw.ratelog("camera-fit", logging.INFO, "%s: camera left out: %s", self.peer, exc)
            self.send(error_message(exc.code, f"camera images left out: {exc.message}"))
            try:
                return encode_frame(message, conv, self.settings.max_message)
            except FramingError:
                return None

    # -- monitor -------------------------------------------------------------------------------
    def _start_ticker(self) -> None:
        if self._ticker is None or self._ticker.done():
            self._ticker = asyncio.create_task(self._tick(), name=f"monitor {self.peer}")

    def _stop_ticker(self) -> None:
        if self._ticker is not None:
            self._ticker.cancel()
            self._ticker = None

    async def _tick(self) -> None:
        loop = asyncio.get_running_loop()
        due = loop.time()
        while True:
            due += self.period
            # Fixed-rate schedule; after a stall skip the missed periods instead of bursting.
            now = loop.time()
            if due < now:
                due = now + self.period
            await asyncio.sleep(due - now)
            if not self.outbox.monitor_due():
                self.gw.ratelog(
                    "drop",
                    logging.INFO,
                    "%s does not keep up: stale monitor messages dropped (%d so far)",
                    self.peer,
                    self.outbox.dropped_monitor,
                )

    def monitor(self, req: Monitor) -> None:
        if req.period_ms is not None:
            self.period = req.period_ms / 1000.0
        self.view.update(req.streams)
        wants_camera = "camera" in self.view.streams
        if wants_camera != self._camera:
            self._camera = wants_camera
            (self.gw.hub.watch_camera if wants_camera else self.gw.hub.unwatch_camera)()
        if self.view.active:
            if req.period_ms is not None:
                self._stop_ticker()
            self._start_ticker()
        else:
            self._stop_ticker()

    # -- messages ------------------------------------------------------------------------------
    async def handle(self, value: Any) -> None:
        try:
            req = parse_message(value)
        except MessageError as exc:
            self.error(exc.code, exc.message)
            return
        try:
            await self._dispatch(req)
        except DarwinError as exc:
            code = getattr(exc, "code", ErrorCode.INTERNAL)
            self.error(code, str(exc))

    async def _dispatch(self, req: Request) -> None:
        if isinstance(req, Monitor):
            self.monitor(req)
        elif isinstance(req, Operate):
            await self.run(operate_command(req, self.settings.operate_all_duration))
        elif isinstance(req, Led):
            await self.run(led_command(req))
        elif isinstance(req, Walk):
            await self.run(walk_command(req, self.settings.walk))
        elif isinstance(req, Playball):
            if await self.run(playball_command(req)) is not None:
                self.send(status_message("playball", 1 if req.start else 0))
        elif isinstance(req, OrchestrateStop):
            await self.gw.orchestrator.stop(self)
        elif isinstance(req, Orchestrate):
            await self.gw.orchestrator.play(self, req)

    # -- commands ------------------------------------------------------------------------------
    async def _commander(self) -> Commander:
        if self.commander is None:
            self.commander = await self.gw.blocking(
                functools.partial(
                    Commander,
                    self.gw.target.endpoint,
                    self.gw.target.robot,
                    name=f"legacy {self.peer}",
                    timeout=self.settings.command_timeout,
                    session=self.gw.session,
                )
            )
        return self.commander

    async def call(self, fn: Callable[..., Any], *args: Any, **kwargs: Any) -> Any:
        return await self.gw.blocking(functools.partial(fn, *args, **kwargs))

    async def run(self, cmd: Command) -> dict[str, Any] | None:
        """Send one command, taking the lease first when it needs it. Returns the applied map,
        or None after answering the client an error (nothing was applied)."""
        commander = await self._commander()
        try:
            if cmd.needs_lease and not self.has_lease:
                await self._acquire(commander)
            try:
                applied = await self.call(commander.command, cmd.verb, **cmd.fields)
            except NoLeaseError:
                # The daemon dropped our lease (its own idle timeout): take it again, once.
                self.has_lease = False
                if not cmd.needs_lease:
                    raise
                await self._acquire(commander)
                applied = await self.call(commander.command, cmd.verb, **cmd.fields)
        except LeaseBusyError as exc:
            self.has_lease = False
            self.error(
                ErrorCode.BUSY,
                f"{cmd.verb}: not applied, another client controls the robot ({exc.message})",
            )
            return None
        except CommandError as exc:
            where = f" (field {exc.field!r})" if exc.field else ""
            self.error(exc.code, f"{cmd.verb}: not applied: {exc.message}{where}")
            return None
        except ClientError as exc:
            self.error(ErrorCode.UNAVAILABLE, f"{cmd.verb}: not applied: {exc}")
            return None
        self._touch()
        return applied

    async def _acquire(self, commander: Commander) -> None:
        await self.call(commander.acquire)
        if not self.has_lease:
            log.info("%s took the control lease", self.peer)
        self.has_lease = True

    def _touch(self) -> None:
        if not self.has_lease:
            return
        if self._idle is not None:
            self._idle.cancel()
        timeout = self.settings.lease_idle_timeout
        if timeout > 0:
            loop = asyncio.get_running_loop()
            self._idle = loop.call_later(timeout, self._idle_expired)

    def _idle_expired(self) -> None:
        self._releasing = asyncio.create_task(self._release(), name=f"release {self.peer}")

    async def _release(self) -> None:
        if not self.has_lease or self.commander is None:
            return
        self.has_lease = False
        try:
            await self.call(self.commander.release)
            log.info(
                "%s was idle for %g s: lease released", self.peer, self.settings.lease_idle_timeout
            )
        except DarwinError as exc:
            log.warning("%s: releasing the lease failed: %s", self.peer, exc)
