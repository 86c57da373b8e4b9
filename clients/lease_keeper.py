"""The lease secret of one client, and the thread that renews the lease with it.

The daemon returns the secret only to the client that acquired the lease; every command that
needs the lease carries it, and the holder must renew at least every ``heartbeat_timeout``
(1.5 s) or the daemon ends the lease with a safe stop. A client that is killed, frozen or cut
off therefore stops the robot, whoever keeps a liveliness token with its id alive.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable

from schemas.errors import ClientError, CommandError, LeaseBusyError, NoLeaseError

log = logging.getLogger(__name__)

# How often the holder renews; the daemon's heartbeat_timeout (1.5 s) allows ~3 misses.
RENEW_PERIOD = 0.4


class LeaseKeeper:
    def __init__(self, renew: Callable[[], object], name: str, period: float = RENEW_PERIOD):
        self._renew = renew  # sends `lease` op=renew with the token
        self._name = name
        self.period = period
        self._token: str | None = None
        self._lock = threading.Lock()
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()

    @property
    def token(self) -> str | None:
        return self._token

    def hold(self, token: str) -> None:
        """We hold the lease with this secret: keep it and renew it."""
        with self._lock:
            self._token = token
            if self._thread is not None and self._thread.is_alive():
                return
            self._stop = threading.Event()
            self._thread = threading.Thread(
                target=self._loop, args=(self._stop,), name=f"lease-renew-{self._name}", daemon=True
            )
            self._thread.start()

    def lost(self, token: str) -> None:
        """The daemon said this token no longer holds the lease."""
        with self._lock:
            if self._token == token:
                self._token = None
                self._stop.set()

    def drop(self) -> None:
        """Forget the secret and stop renewing (released, or the client closes)."""
        with self._lock:
            self._token = None
            self._stop.set()
            t, self._thread = self._thread, None
        if t is not None and t is not threading.current_thread():
            t.join(timeout=2.0)

    def _loop(self, stop: threading.Event) -> None:
        # A fixed rate, not a pause after each reply: on a slow link (busy Wi-Fi) a reply that
        # takes most of a second would otherwise stretch the gap between renewals past the
        # daemon's heartbeat_timeout, and the lease would end while the holder is there.
        next_t = time.monotonic()
        while True:
            next_t = max(next_t + self.period, time.monotonic())
            if stop.wait(max(0.0, next_t - time.monotonic())):
                return
            if self._token is None:
                return
            try:
                self._renew()
            except (NoLeaseError, LeaseBusyError) as exc:
                log.warning("the control lease was lost: %s", exc.message)
                return
            except CommandError as exc:
                log.debug("lease renewal refused: %s", exc)
            except ClientError as exc:
                log.debug("lease renewal failed: %s", exc)  # the next one may get through
