"""A legacy client's use of the control lease: taken on demand before a command that needs
it, released after ``lease_idle_timeout`` without commands, as :class:`AdapterCore` decides
on the event loop's clock.

A mixin of :class:`~gateway.connection.Connection` (which provides the commander, the settings
and the core); kept apart so the connection's framing and dispatch stay readable.
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from clients.adapter_core import Action, AdapterCore
from schemas.errors import DarwinError

if TYPE_CHECKING:
    from clients.commander import Commander
    from gateway.settings import GatewaySettings

log = logging.getLogger("gateway.connection")


class LeaseUse:
    # The Connection's, set in its __init__.
    peer: str
    settings: GatewaySettings
    commander: Commander | None
    lease: AdapterCore
    _idle: asyncio.TimerHandle | None
    _releasing: asyncio.Task[None] | None

    if TYPE_CHECKING:

        async def call(self, fn: Callable[..., Any], *args: Any, **kwargs: Any) -> Any: ...

    async def _acquire(self, commander: Commander) -> None:
        await self.call(commander.acquire)
        if self.lease.acquired(asyncio.get_running_loop().time()):
            log.info("%s took the control lease", self.peer)

    def _touch(self) -> None:
        """A command was applied: the idle release counts from now (see AdapterCore)."""
        loop = asyncio.get_running_loop()
        self.lease.active(loop.time())
        self._arm_idle(loop)

    def _arm_idle(self, loop: asyncio.AbstractEventLoop) -> None:
        if self._idle is not None:
            self._idle.cancel()
            self._idle = None
        due = self.lease.next_due()
        if due is not None:
            self._idle = loop.call_at(due, self._idle_due)

    def _idle_due(self) -> None:
        self._idle = None
        loop = asyncio.get_running_loop()
        if Action.RELEASE in self.lease.tick(loop.time()):
            self._releasing = asyncio.create_task(self._release(), name=f"release {self.peer}")
        else:
            self._arm_idle(loop)  # woken a little early, or activity since: look again then

    async def _release(self) -> None:
        if not self.lease.released() or self.commander is None:
            return
        try:
            await self.call(self.commander.release)
            log.info(
                "%s was idle for %g s: lease released", self.peer, self.settings.lease_idle_timeout
            )
        except DarwinError as exc:
            log.warning("%s: releasing the lease failed: %s", self.peer, exc)
