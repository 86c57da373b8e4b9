"""A client's watch on the daemon's announced versions (``status.version``/``status.protocol``):
every status is checked by the one check, :func:`schemas.versions.check_daemon`; a minor skew is
logged once per announcement, a major one is kept and refuses every later command. A UI
listens for both (:meth:`~ProtocolWatch.listen`): a daemon's first status can come later than any
wait at connect on a loaded machine, and its upgrade may announce another version later."""

from __future__ import annotations

import contextlib
import logging
import threading
from collections.abc import Callable, Mapping
from typing import Any

import zenoh

from schemas.errors import IncompatibleProtocolError, ProtocolError
from schemas.keys import Keys
from schemas.messages import decode_dict
from schemas.versions import announcement, check_daemon

log = logging.getLogger(__name__)


class ProtocolWatch:
    def __init__(self, program: str, *, log_skew: bool = True) -> None:
        """``log_skew``: log a skew as it is seen (a long-lived client learns so of a daemon
        that changed under it); a program that checks once and says it in its own line does
        not (the log record could come after that line, from Zenoh's thread)."""
        self.program = program
        self.log_skew = log_skew
        self.warning: str | None = None
        self.error: IncompatibleProtocolError | None = None
        self._seen: Any = None  # the last announcement checked
        self._cond = threading.Condition()
        self._listeners: list[Callable[[str | None, IncompatibleProtocolError | None], None]] = []

    def listen(
        self, callback: Callable[[str | None, IncompatibleProtocolError | None], None]
    ) -> None:
        """``callback(warning, error)`` for the announcement already seen (if any) and each new
        one, on the thread that saw it."""
        with self._cond:
            self._listeners.append(callback)
            seen, warning, error = self._seen is not None, self.warning, self.error
        if seen:
            callback(warning, error)

    def observe(self, payload: bytes | Mapping[str, Any]) -> None:
        """A status arrived: decoded (its fields), or the raw payload (a daemon of another major
        may not decode)."""
        if isinstance(payload, bytes):
            try:
                status: Mapping[str, Any] = decode_dict(payload)
            except ProtocolError:
                return
        else:
            status = payload
        if status.get("type", "status") != "status":
            # Another message is no announcement: an IMU sample that Zenoh delivered to the
            # status subscription (twice in ~30 runs of the lossy-link test) had been taken
            # for a daemon of protocol 1.0, and commands were refused until the next status.
            return
        seen = (announcement(status), status.get("robot"))
        if seen == self._seen:
            return
        warning, error = None, None
        try:
            warning = check_daemon(status, self.program)
        except IncompatibleProtocolError as exc:
            error = exc
        # Logged before a waiter is woken: a program that refuses in one line on the main
        # thread then prints its line last.
        if warning and self.log_skew:
            log.warning("%s", warning)
        if error and self.log_skew:
            log.error("%s", error)
        with self._cond:
            self._seen, self.warning, self.error = seen, warning, error
            self._cond.notify_all()
            listeners = list(self._listeners)
        for callback in listeners:
            callback(warning, error)

    def refuse(self) -> None:
        if self.error is not None:
            raise self.error

    def wait(self, timeout: float) -> str | None:
        """Wait up to ``timeout`` for the first announcement; raise on an incompatible one, else
        the warning (None: compatible, or no daemon answered yet)."""
        with self._cond:
            self._cond.wait_for(lambda: self._seen is not None, timeout)
        self.refuse()
        return self.warning


def check_at(session: zenoh.Session, keys: Keys, program: str, timeout: float = 3.0) -> str | None:
    """:meth:`ProtocolWatch.wait` on a session of a client that has no ``Robot`` (a recorder),
    which says what it returns or raises in its own line."""
    watch = ProtocolWatch(program, log_skew=False)
    sub = session.declare_subscriber(keys.status, lambda s: watch.observe(s.payload.to_bytes()))
    try:
        return watch.wait(timeout)
    finally:
        with contextlib.suppress(Exception):
            sub.undeclare()
