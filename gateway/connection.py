"""One legacy client: its framing, monitor set and period, commands and control lease."""

from __future__ import annotations

import asyncio
import contextlib
import functools
import logging
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from clients.commander import Commander
from gateway.framing import Frame, FrameDecoder, FramingError, encode_frame, parse_frame
from gateway.lease_timer import LeaseTimer
from gateway.limits import TokenBucket
from gateway.messages import (
    MessageError,
    Monitor,
    Orchestrate,
    OrchestrateStop,
    Playball,
    Request,
    error_message,
    status_message,
)
from gateway.monitor import MonitorView
from gateway.outbox import Outbox, SlowReaderError
from gateway.translate import Command, request_command
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
        self.decoder = FrameDecoder(self.settings.max_incoming, self.settings.body_limits)
        self.view = MonitorView()
        self.period = self.settings.monitor_period
        self.bucket = TokenBucket(self.settings.max_rate, self.settings.burst)
        self.outbox = Outbox(writer, self._monitor_bytes, self.settings.max_pending_replies)
        self.commander: Commander | None = None
        self.lease = LeaseTimer(self.peer, self.settings.lease_idle_timeout, self.call)
        self._ticker: asyncio.Task[None] | None = None
        self._camera = False
        self._camera_fits = True
        self.closed = asyncio.Event()
        # The idle watchdog (idle_timeout): armed at connect and at every message completed.
        self._reading: asyncio.Task[None] | None = None
        self._watchdog: asyncio.TimerHandle | None = None
        self._handling = False  # messages are being handled: the client waits for us
        self._farewell: dict[str, Any] | None = None  # the error to send when the watchdog closes

    # -- life ----------------------------------------------------------------------------------
    async def serve(self) -> None:
        transport = self.writer.transport
        transport.set_write_buffer_limits(high=self.settings.write_buffer)
        writer_task = asyncio.create_task(self._write(), name=f"write {self.peer}")
        self._reading = asyncio.create_task(self._read(), name=f"read {self.peer}")
        self._arm_watchdog()
        try:
            await asyncio.wait([self._reading])
            if self._reading.cancelled() and self._farewell is not None:
                await self._say_goodbye(self._farewell)
            else:
                self._reading.result()  # a bug in reading: the gateway logs it
        finally:
            self._reading.cancel()
            if self._watchdog is not None:
                self._watchdog.cancel()
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
            started = self.decoder.buffered == 0
            try:
                frames = self.decoder.feed(data)
            except FramingError as exc:
                await self._framing_failed(exc)
                return
            if not frames:
                if started and self.decoder.buffered and self._served():
                    # A client served while quiet starts a message: it has the whole timeout.
                    self._arm_watchdog()
                continue
            self._handling = True
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
                await self.handle(frame)
                if self.writer.transport.is_closing():
                    return
            self._handling = False
            self._arm_watchdog()  # progress: a message completed (and was handled)
            if self.decoder.error is not None:
                # Good frames before the break were handled; now the break itself.
                await self._framing_failed(self.decoder.error)
                return

    async def _framing_failed(self, exc: FramingError) -> None:
        self.gw.ratelog("reject", logging.WARNING, "%s: %s (closing)", self.peer, exc.message)
        await self._say_goodbye(error_message(exc.code, f"{exc.message}; closing the connection"))

    async def _say_goodbye(self, message: dict[str, Any]) -> None:
        """Send a last error reply before the connection is closed (bounded wait)."""
        if self._watchdog is not None:
            self._watchdog.cancel()  # the connection ends anyway: no second farewell
        self.send(message)
        await self.outbox.flush(timeout=1.0)

    # -- idle watchdog -------------------------------------------------------------------------
    # Progress is a completed message, never a byte: a client that dribbles a message a byte at
    # a time (slow loris) or connects and says nothing is closed after idle_timeout. A client
    # that is being served (monitor streams on, an orchestrate list of its own playing) may
    # stay quiet for ever, but once it starts a message it has idle_timeout to finish it.
    def _served(self) -> bool:
        return self.view.active or self in self.gw.orchestrator.runs

    def _arm_watchdog(self) -> None:
        timeout = self.settings.idle_timeout
        if timeout <= 0:
            return
        if self._watchdog is not None:
            self._watchdog.cancel()
        self._watchdog = asyncio.get_running_loop().call_later(timeout, self._watchdog_due)

    def _watchdog_due(self) -> None:
        self._watchdog = None
        partial = self.decoder.buffered
        if self._handling or (not partial and self._served()):
            self._arm_watchdog()  # look again later: the service may end
            return
        timeout = self.settings.idle_timeout
        if partial:
            code = ErrorCode.INVALID
            reason = f"message incomplete after {timeout:g} s ({partial} bytes of it arrived)"
        else:
            code = ErrorCode.REFUSED
            reason = f"no message for {timeout:g} s and no monitor stream on"
        self.gw.ratelog("idle", logging.INFO, "%s: %s (idle_timeout): closing", self.peer, reason)
        self._farewell = error_message(code, f"{reason}: closing the connection (idle_timeout)")
        if self._reading is not None:
            self._reading.cancel()

    async def _close(self) -> None:
        self._stop_ticker()
        if self._camera:
            self._camera = False
            self.gw.hub.unwatch_camera()
        self.lease.cancel()
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
    async def handle(self, frame: Frame) -> None:
        try:
            req = parse_frame(frame)
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
        elif isinstance(req, OrchestrateStop):
            await self.gw.orchestrator.stop(self)
        elif isinstance(req, Orchestrate):
            await self.gw.orchestrator.play(self, req)
        else:
            cmd = request_command(req, self.settings)
            assert cmd is not None, req
            applied = await self.run(cmd)
            if isinstance(req, Playball) and applied is not None:
                self.send(status_message("playball", 1 if req.start else 0))

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
                    role=self.gw.role,
                )
            )
        return self.commander

    async def call(self, fn: Callable[..., Any], *args: Any, **kwargs: Any) -> Any:
        return await self.gw.blocking(functools.partial(fn, *args, **kwargs))

    async def run(self, cmd: Command) -> dict[str, Any] | None:
        """Send one command, taking the lease first when it needs it. Returns the applied map,
        or None after answering the client an error (nothing was applied)."""
        commander = await self._commander()
        now = asyncio.get_running_loop().time
        try:
            if self.lease.before_command(now(), cmd.needs_lease):
                await self.lease.acquire(commander)
            try:
                applied = await self.call(commander.command, cmd.verb, **cmd.fields)
            except NoLeaseError:
                # The daemon dropped our lease (its own idle timeout): take it again, once.
                self.lease.lost()
                if not cmd.needs_lease:
                    raise
                await self.lease.acquire(commander)
                applied = await self.call(commander.command, cmd.verb, **cmd.fields)
        except LeaseBusyError as exc:
            self.lease.lost()
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
        self.lease.touch()
        return applied
