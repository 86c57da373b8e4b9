"""A legacy client's use of the control lease: taken on demand before a command that needs
it, released after ``lease_idle_timeout`` without commands, as :class:`AdapterCore` decides
on the event loop's clock. Each :class:`~gateway.connection.Connection` has one; it sees only
the connection's name, the idle timeout and how to run a blocking call."""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Awaitable, Callable
from typing import TYPE_CHECKING, Any

from clients.adapter_core import Action, AdapterCore
from schemas.errors import DarwinError

if TYPE_CHECKING:
    from clients.commander import Commander

log = logging.getLogger("gateway.connection")

BlockingCall = Callable[..., Awaitable[Any]]


class LeaseTimer:
    def __init__(self, peer: str, idle_timeout: float, call: BlockingCall) -> None:
        self.peer = peer
        self.idle_timeout = idle_timeout
        self.core = AdapterCore(idle_release=idle_timeout)
        self._call = call  # runs a blocking Commander call off the event loop
        self._commander: Commander | None = None
        self._idle: asyncio.TimerHandle | None = None
        self._releasing: asyncio.Task[None] | None = None

    def before_command(self, now: float, needs_lease: bool) -> bool:
        """Whether the lease must be taken before this command."""
        return self.core.before_command(now, needs_lease)

    def lost(self) -> None:
        """The daemon says the lease is gone (its idle timeout, or another client's)."""
        self.core.lost()

    async def acquire(self, commander: Commander) -> None:
        await self._call(commander.acquire)
        self._commander = commander
        if self.core.acquired(asyncio.get_running_loop().time()):
            log.info("%s took the control lease", self.peer)

    def touch(self) -> None:
        """A command was applied: the idle release counts from now (see AdapterCore)."""
        loop = asyncio.get_running_loop()
        self.core.active(loop.time())
        self._arm_idle(loop)

    def cancel(self) -> None:
        """The connection closes: no release is due any more (its commander's liveliness
        token goes with it, and the arbiter releases the lease)."""
        if self._idle is not None:
            self._idle.cancel()
            self._idle = None

    def _arm_idle(self, loop: asyncio.AbstractEventLoop) -> None:
        self.cancel()
        due = self.core.next_due()
        if due is not None:
            self._idle = loop.call_at(due, self._idle_due)

    def _idle_due(self) -> None:
        self._idle = None
        loop = asyncio.get_running_loop()
        if Action.RELEASE in self.core.tick(loop.time()):
            self._releasing = asyncio.create_task(self._release(), name=f"release {self.peer}")
        else:
            self._arm_idle(loop)  # woken a little early, or activity since: look again then

    async def _release(self) -> None:
        if not self.core.released() or self._commander is None:
            return
        try:
            await self._call(self._commander.release)
            log.info("%s was idle for %g s: lease released", self.peer, self.idle_timeout)
        except DarwinError as exc:
            log.warning("%s: releasing the lease failed: %s", self.peer, exc)
