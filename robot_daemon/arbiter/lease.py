"""The control lease: one holder at a time, bound to a secret only the holder has.

``acquire`` makes a random token and the arbiter returns it in the acquirer's reply alone (it is
never published: ``status`` shows the client id and name). Every command that needs the lease,
``release`` and ``renew`` must carry it, so a client that reuses the holder's public id can
neither command nor release. The holder renews at least every ``heartbeat_timeout`` seconds; a
holder that falls silent loses the lease ("holder silent") even if someone keeps a liveliness
token with its id alive. The lease also ends when the holder's liveliness token goes, on release,
and after ``idle_timeout`` without a command. Pure state: the arbiter feeds it clock and token
changes.
"""

from __future__ import annotations

import hmac
import secrets
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

from config.loader import refuse_unknown
from schemas.commands import TOKEN_BYTES
from schemas.errors import ErrorCode, Reject

SILENT = "holder silent"


@dataclass(frozen=True)
class Holder:
    """The client that holds the control lease, and when it was last heard."""

    client: str
    name: str
    since: float  # wall clock, for people
    last_seen: float  # monotonic, for the idle timeout (commands)
    token: str = field(default="", repr=False)  # the secret: never in to_dict() or a log
    last_renew: float = 0.0  # monotonic, for the heartbeat timeout

    def to_dict(self) -> dict[str, Any]:
        return {"client": self.client, "name": self.name, "since": self.since}


class Lease:
    """Thread-safe lease state. ``on_change(old, new, reason)`` is called on every change
    (outside the lock), so the daemon can publish an event and bring the robot to a safe stop."""

    def __init__(
        self,
        idle_timeout: float = 60.0,
        on_change: Callable[[Holder | None, Holder | None, str], None] | None = None,
        clock: Callable[[], float] = time.monotonic,
        heartbeat_timeout: float = 1.5,
    ) -> None:
        self.idle_timeout = idle_timeout
        self.heartbeat_timeout = heartbeat_timeout
        self._on_change = on_change
        self._clock = clock
        self._holder: Holder | None = None
        self._lock = threading.Lock()

    @classmethod
    def from_config(
        cls,
        section: dict[str, Any],
        on_change: Callable[[Holder | None, Holder | None, str], None] | None = None,
    ) -> Lease:
        """From ``[daemon.lease]``: ``idle_timeout`` and ``heartbeat_timeout`` (s, 0 = off)."""
        refuse_unknown(section, ("idle_timeout", "heartbeat_timeout"), "daemon.lease")
        return cls(
            float(section.get("idle_timeout", 60.0)),
            on_change,
            heartbeat_timeout=float(section.get("heartbeat_timeout", 1.5)),
        )

    @property
    def holder(self) -> Holder | None:
        with self._lock:
            return self._holder

    def status(self) -> dict[str, Any] | None:
        h = self.holder
        return h.to_dict() if h else None

    def _set(self, expect: Holder | None, new: Holder | None, reason: str) -> bool:
        """Replace ``expect`` by ``new``; False (nothing done) if the holder changed meanwhile."""
        with self._lock:
            cur = self._holder
            same = cur is None if expect is None else cur is not None and cur.token == expect.token
            if not same:
                return False
            self._holder = new
        if self._on_change is not None:
            self._on_change(cur, new, reason)
        return True

    @staticmethod
    def _owns(h: Holder | None, client: str, token: str | None) -> bool:
        return (
            h is not None
            and h.client == client
            and isinstance(token, str)
            and hmac.compare_digest(h.token.encode(), token.encode())
        )

    def _busy(self, h: Holder, extra: str = "") -> Reject:
        return Reject(
            ErrorCode.BUSY,
            f"busy: the control lease is held by {h.name!r} (client {h.client}) since "
            f"{time.strftime('%H:%M:%S', time.localtime(h.since))}{extra}; wait for it to be "
            "released, or `halt` the robot (always allowed; docs/troubleshooting.md#lease-refused)",
            "client",
        )

    def acquire(self, client: str, name: str, token: str | None = None) -> Holder:
        """Take the lease (or, for the holder with its token, rename it). Returns the holder,
        whose ``token`` goes back to this caller alone."""
        now = self._clock()
        with self._lock:
            h = self._holder
            if h is not None:
                if not self._owns(h, client, token):
                    extra = (
                        " (this request reuses the holder's id without its lease token)"
                        if h.client == client
                        else ""
                    )
                    raise self._busy(h, extra)
                self._holder = replace(h, name=name or h.name, last_seen=now, last_renew=now)
                return self._holder
        token = secrets.token_urlsafe(TOKEN_BYTES)
        new = Holder(client, name or client, time.time(), now, token, now)
        if not self._set(None, new, "acquired"):
            return self.acquire(client, name, token)  # someone else got there first
        return new

    def release(self, client: str, token: str | None) -> bool:
        """Release if the caller holds the lease (id and token); True when it did."""
        h = self.holder
        if not self._owns(h, client, token):
            return False
        return self._set(h, None, "released")

    def renew(self, client: str, token: str | None) -> Holder:
        """The holder's heartbeat; raises ``Reject`` for anyone else. Does not count as a
        command for the idle timeout."""
        with self._lock:
            h = self._holder
            if self._owns(h, client, token):
                assert h is not None
                self._holder = replace(h, last_renew=self._clock())
                return self._holder
        self._refuse(h, client)
        raise AssertionError("unreachable")

    def check(self, client: str, token: str | None) -> None:
        """Raise ``Reject`` unless the caller holds the lease; refresh its idle clock."""
        with self._lock:
            h = self._holder
            if self._owns(h, client, token):
                assert h is not None
                self._holder = replace(h, last_seen=self._clock())
                return
        self._refuse(h, client)

    def _refuse(self, h: Holder | None, client: str) -> None:
        if h is None:
            raise Reject(
                ErrorCode.NO_LEASE,
                "this command needs the control lease: acquire it first (`lease` op=acquire, "
                "or `with robot.control():`)",
                "client",
            )
        if h.client == client:
            raise Reject(
                ErrorCode.BUSY,
                f"busy: the control lease of client {h.client} is bound to the session that "
                "took it, and this request does not carry its lease_token",
                "lease_token",
            )
        raise self._busy(h)

    def client_gone(self, client: str) -> bool:
        """The client's liveliness token vanished: drop its lease."""
        h = self.holder
        if h is None or h.client != client:
            return False
        return self._set(h, None, "holder vanished")

    def excuse(self, seconds: float) -> None:
        """The daemon itself did not run for ``seconds`` (its loop stalled: a loaded computer,
        a swap storm): renewals sent meanwhile wait unread in its queue, so that time is not the
        holder's silence. A holder that really fell silent loses the lease ``heartbeat_timeout``
        of the daemon's own running time after its last renewal, as always."""
        if seconds <= 0:
            return
        with self._lock:
            h = self._holder
            if h is not None:
                later = min(self._clock(), h.last_renew + seconds)
                self._holder = replace(h, last_renew=max(h.last_renew, later))

    def expire(self) -> bool:
        """Drop the lease if its holder stopped renewing or has been idle too long; True when
        it did."""
        h = self.holder
        if h is None:
            return False
        now = self._clock()
        if self.heartbeat_timeout > 0 and now - h.last_renew > self.heartbeat_timeout:
            return self._set(h, None, SILENT)
        if self.idle_timeout > 0 and now - h.last_seen >= self.idle_timeout:
            return self._set(h, None, f"idle for {self.idle_timeout:.0f} s")
        return False
