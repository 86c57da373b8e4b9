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

# How often the holder renews: the daemon's heartbeat_timeout (1.5 s) then allows a client that
# is stalled for 1.25 s (a loaded machine, a busy UI in the same process) and ~5 lost renewals.
RENEW_PERIOD = 0.25
# Renewals awaiting their reply at once: each is sent on time even while earlier ones wait (a
# slow reply never holds back the next renewal); past this many the link is down anyway.
IN_FLIGHT = 4
# How long ``drop`` waits for renewals still awaiting their reply (each ends by its command
# timeout, 3 s by default, or at once when the session closes).
DRAIN_S = 5.0


class LeaseKeeper:
    def __init__(self, renew: Callable[[], object], name: str, period: float = RENEW_PERIOD):
        self._renew = renew  # sends `lease` op=renew with the token
        self._name = name
        self.period = period
        self._token: str | None = None
        self._lock = threading.Lock()
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._in_flight = 0
        self._idle = threading.Condition(self._lock)  # notified when a renewal ends
        self._renewing = threading.local()  # .here in a renewal's own thread
        self._warned = False  # the loss is logged once

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
            self._warned = False
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
            self._warned = True  # a renewal still on its way may be refused now: not a loss
            t, self._thread = self._thread, None
        if t is not None and t is not threading.current_thread():
            t.join(timeout=2.0)
        # Renewals still waiting for their reply are waited for too: a script that ends right
        # after closing would otherwise finalize Python while one sits inside Zenoh's query, and
        # a thread that comes back into Python then is ended by pthread_exit through Zenoh's
        # Rust frames, which aborts the process ("FATAL: exception not rethrown", exit -6; seen
        # at the end of docs/owner.md's script on a loaded machine). Not from a renewal itself.
        if not getattr(self._renewing, "here", False):
            with self._idle:
                self._idle.wait_for(lambda: self._in_flight == 0, timeout=DRAIN_S)

    def _loop(self, stop: threading.Event) -> None:
        # A fixed rate, and each renewal in a thread of its own: on a slow link (busy Wi-Fi) or
        # a loaded machine a reply that takes most of a second would otherwise hold back the
        # next renewal, the gap would grow past the daemon's heartbeat_timeout, and the lease
        # would end while the holder is there.
        next_t = time.monotonic()
        while True:
            next_t = max(next_t + self.period, time.monotonic())
            if stop.wait(max(0.0, next_t - time.monotonic())):
                return
            if self._token is None:
                return
            with self._lock:
                if self._in_flight >= IN_FLIGHT:
                    continue
                self._in_flight += 1
            threading.Thread(
                target=self._renew_once, args=(stop,), name=f"lease-renewal-{self._name}",
                daemon=True,
            ).start()  # fmt: skip

    def _renew_once(self, stop: threading.Event) -> None:
        self._renewing.here = True
        try:
            self._renew()
        except (NoLeaseError, LeaseBusyError) as exc:
            # The command forgot the secret (lost()), which ends the loop; say it once.
            with self._lock:
                first, self._warned = not self._warned, True
            if first:
                log.warning("the control lease was lost: %s", exc.message)
        except CommandError as exc:
            log.debug("lease renewal refused: %s", exc)
        except ClientError as exc:
            log.debug("lease renewal failed: %s", exc)  # the next one may get through
        finally:
            with self._lock:
                self._in_flight -= 1
                self._idle.notify_all()
