"""The messages a client has received, by topic, with a wait that tests each one in turn.

``Robot.wait_for`` waits here. A waiting thread that only looked at the newest message when it
woke would miss one followed at once by another (a refusal then the loop's timing event); this
keeps the last ``RECENT`` of each topic and counts them, so a wait tests every message that
arrived since the moment it started from."""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable
from typing import Any

from schemas.errors import CommandTimeoutError

# More than arrive on a topic between two wake-ups of a waiting thread.
RECENT = 64


class Arrivals:
    def __init__(self) -> None:
        self._cond = threading.Condition()
        self._count: dict[str, int] = {}
        self._recent: dict[str, deque[Any]] = {}

    def add(self, topic: str, msg: Any) -> None:
        with self._cond:
            self._count[topic] = self._count.get(topic, 0) + 1
            self._recent.setdefault(topic, deque(maxlen=RECENT)).append(msg)
            self._cond.notify_all()

    def count(self, topic: str) -> int:
        """How many messages of ``topic`` have arrived: a moment to wait from."""
        with self._cond:
            return self._count.get(topic, 0)

    def wait(
        self,
        topic: str,
        predicate: Callable[[Any], bool],
        timeout: float,
        since: int | None = None,
    ) -> Any:
        """The first message of ``topic`` after the ``since``-th (default: from now) that
        satisfies ``predicate``; ``CommandTimeoutError`` when none does within ``timeout``."""
        deadline = time.monotonic() + timeout
        with self._cond:
            seen = self._count.get(topic, 0) if since is None else since
            while True:
                count = self._count.get(topic, 0)
                if count > seen:
                    recent = self._recent.get(topic, ())
                    arrived = list(recent)[max(0, len(recent) - (count - seen)) :]
                    seen = count
                    for msg in arrived:
                        if predicate(msg):
                            return msg
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    raise CommandTimeoutError(
                        f"no {topic!r} message matching the condition within {timeout:.1f} s"
                    )
                self._cond.wait(remaining)
