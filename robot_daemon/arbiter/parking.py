"""Throttled answers held back until their retry time.

A client that retries on every answer then paces itself, instead of costing the daemon a query
per answer as fast as it can send. Only a bounded number is held; the rest is answered at once.
"""

from __future__ import annotations

import heapq
import threading
import time
from collections.abc import Callable

import zenoh

from robot_daemon.arbiter.registry import Reject
from schemas.query import error_payload

MAX_PARKED = 256
MAX_PARK_S = 1.0


class ParkedAnswers:
    def __init__(self, finish: Callable[[zenoh.Query, bool, bytes], None]) -> None:
        self._finish = finish  # answers a query: (query, ok, payload)
        self._parked: list[tuple[float, int, zenoh.Query, bytes]] = []  # heap by due time
        self._park_seq = 0
        self._lock = threading.Lock()

    def hold(self, query: zenoh.Query, verb_name: str, r: Reject) -> None:
        """Answer a throttled command when its wait is over rather than at once."""
        wait = min(r.retry_after or 0.0, MAX_PARK_S)
        with self._lock:
            if wait > 0 and len(self._parked) < MAX_PARKED:
                r = Reject(r.code, r.message + " (this answer was held that long)", r.field, 0.0)
                self._park_seq += 1
                heapq.heappush(
                    self._parked,
                    (time.monotonic() + wait, self._park_seq, query, error_payload(verb_name, r)),
                )
                return
        self._finish(query, False, error_payload(verb_name, r))

    def release(self, now: float) -> float:
        """Answer the parked queries that are due; returns the seconds until the next one."""
        due = []
        with self._lock:
            while self._parked and self._parked[0][0] <= now:
                due.append(heapq.heappop(self._parked))
            nxt = self._parked[0][0] - now if self._parked else 0.25
        for _, _, query, payload in due:
            self._finish(query, False, payload)
        return max(0.001, min(0.25, nxt))
