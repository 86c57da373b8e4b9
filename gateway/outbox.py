"""What a connection sends, and the one task that writes it.

Replies (errors, orchestrate/playball status) are queued in order and never dropped. A monitor
message is not queued at all: a period coming due only marks it due, and it is built from the
newest values when the socket can take it. A client that does not read therefore holds at most
one pending monitor message (the newest); every period that passes meanwhile is counted as a
dropped stale message, and neither other clients nor the robot wait for it.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections import deque
from collections.abc import Callable

from schemas.errors import SlowReaderError

log = logging.getLogger(__name__)


class Outbox:
    def __init__(
        self,
        writer: asyncio.StreamWriter,
        build_monitor: Callable[[], bytes | None],
        max_pending_replies: int,
    ) -> None:
        self._writer = writer
        self._build_monitor = build_monitor
        self._max_pending = max_pending_replies
        self._replies: deque[bytes] = deque()
        self._monitor_due = False
        self._wake = asyncio.Event()
        self.sent_monitor = 0
        self.dropped_monitor = 0
        self.sent_replies = 0

    def reply(self, data: bytes) -> None:
        if len(self._replies) >= self._max_pending:
            raise SlowReaderError(
                f"{len(self._replies)} replies are waiting for this client to read them"
            )
        self._replies.append(data)
        self._wake.set()

    def monitor_due(self) -> bool:
        """Mark a monitor message due; False when the last one is still unsent (dropped)."""
        if self._monitor_due:
            self.dropped_monitor += 1
            return False
        self._monitor_due = True
        self._wake.set()
        return True

    @property
    def idle(self) -> bool:
        return not self._replies and not self._monitor_due

    async def run(self) -> None:
        """Write until cancelled or the connection breaks (then the caller closes it)."""
        while True:
            await self._wake.wait()
            self._wake.clear()
            while self._replies or self._monitor_due:
                if self._replies:
                    data: bytes | None = self._replies.popleft()
                    self.sent_replies += 1
                else:
                    self._monitor_due = False
                    data = self._build_monitor()
                    if data is not None:
                        self.sent_monitor += 1
                if data:
                    self._writer.write(data)
                    await self._writer.drain()

    async def flush(self, timeout: float) -> None:
        """Write the queued replies and wait (bounded) for them to leave; call it after the
        ``run`` task is cancelled, before closing the connection."""
        while self._replies:
            self._writer.write(self._replies.popleft())
            self.sent_replies += 1
        with contextlib.suppress(TimeoutError, ConnectionError):
            await asyncio.wait_for(self._writer.drain(), timeout)
