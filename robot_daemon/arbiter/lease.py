"""The control lease: one holder at a time, lost explicitly, with the holder's liveliness token,
or after an idle timeout. Pure state: the arbiter feeds it clock and token changes."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from robot_daemon.arbiter.registry import Reject
from schemas.errors import ErrorCode


@dataclass(frozen=True)
class Holder:
    client: str
    name: str
    since: float  # wall clock, for people
    last_seen: float  # monotonic, for the idle timeout

    def to_dict(self) -> dict[str, Any]:
        return {"client": self.client, "name": self.name, "since": self.since}


class Lease:
    """Thread-safe lease state. ``on_change(holder_or_None, reason)`` is called on every change
    (outside the lock), so the daemon can publish an event and bring the robot to a safe stop."""

    def __init__(
        self,
        idle_timeout: float = 60.0,
        on_change: Callable[[Holder | None, Holder | None, str], None] | None = None,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.idle_timeout = idle_timeout
        self._on_change = on_change
        self._clock = clock
        self._holder: Holder | None = None
        self._lock = threading.Lock()

    @property
    def holder(self) -> Holder | None:
        with self._lock:
            return self._holder

    def status(self) -> dict[str, Any] | None:
        h = self.holder
        return h.to_dict() if h else None

    def _set(self, new: Holder | None, reason: str) -> None:
        with self._lock:
            old, self._holder = self._holder, new
        changed = (old is None) != (new is None) or (
            old is not None and new is not None and old.client != new.client
        )
        if changed and self._on_change is not None:
            self._on_change(old, new, reason)

    def acquire(self, client: str, name: str) -> Holder:
        now = self._clock()
        with self._lock:
            h = self._holder
            if h is not None and h.client != client:
                raise Reject(
                    ErrorCode.BUSY,
                    f"busy: the control lease is held by {h.name!r} (client {h.client}) since "
                    f"{time.strftime('%H:%M:%S', time.localtime(h.since))}; wait for it to be "
                    "released, or `halt` the robot (always allowed)",
                    "client",
                )
            if h is not None:
                self._holder = Holder(h.client, name or h.name, h.since, now)
                return self._holder
        new = Holder(client, name or client, time.time(), now)
        self._set(new, "acquired")
        return new

    def release(self, client: str) -> bool:
        """Release if ``client`` holds the lease; True when it did."""
        h = self.holder
        if h is None or h.client != client:
            return False
        self._set(None, "released")
        return True

    def check(self, client: str) -> None:
        """Raise ``Reject`` unless ``client`` holds the lease; refresh its idle clock."""
        with self._lock:
            h = self._holder
            if h is not None and h.client == client:
                self._holder = Holder(h.client, h.name, h.since, self._clock())
                return
        if h is None:
            raise Reject(
                ErrorCode.NO_LEASE,
                "this command needs the control lease: acquire it first (`lease` op=acquire, "
                "or `with robot.control():`)",
                "client",
            )
        raise Reject(
            ErrorCode.BUSY,
            f"busy: the control lease is held by {h.name!r} (client {h.client})",
            "client",
        )

    def client_gone(self, client: str) -> bool:
        """The client's liveliness token vanished: drop its lease."""
        h = self.holder
        if h is None or h.client != client:
            return False
        self._set(None, "holder vanished")
        return True

    def expire(self) -> bool:
        """Drop the lease if its holder has been idle too long; True when it did."""
        if self.idle_timeout <= 0:
            return False
        h = self.holder
        if h is None or self._clock() - h.last_seen < self.idle_timeout:
            return False
        self._set(None, f"idle for {self.idle_timeout:.0f} s")
        return True
