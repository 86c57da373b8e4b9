"""Rate limits: a token bucket for what a client sends, and logging that cannot flood."""

from __future__ import annotations

import logging
import time
from collections.abc import Callable


class TokenBucket:
    """``rate`` messages per second on average, ``burst`` at once. ``take()`` returns how long
    to wait before the message may be handled (0 when a token is there); the token is spent."""

    def __init__(self, rate: float, burst: int, clock: Callable[[], float] = time.monotonic):
        self.rate = rate
        self.burst = float(burst)
        self._clock = clock
        self._tokens = float(burst)
        self._stamp = clock()

    def take(self) -> float:
        now = self._clock()
        self._tokens = min(self.burst, self._tokens + (now - self._stamp) * self.rate)
        self._stamp = now
        self._tokens -= 1.0
        if self._tokens >= 0:
            return 0.0
        return -self._tokens / self.rate


class RateLimitedLog:
    """Log at most ``burst`` lines per ``key`` every ``interval`` seconds; the next line says how
    many were held back, so a client sending garbage in a loop cannot fill the disk."""

    def __init__(
        self,
        logger: logging.Logger,
        interval: float,
        burst: int = 1,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self._log = logger
        self.interval = interval
        self.burst = burst
        self._clock = clock
        self._window: dict[str, tuple[float, int]] = {}  # key → (window start, lines logged)
        self._held: dict[str, int] = {}

    def __call__(
        self, key: str, level: int, msg: str, *args: object, exc_info: bool = False
    ) -> bool:
        now = self._clock()
        start, count = self._window.get(key, (now, 0))
        if now - start >= self.interval:
            start, count = now, 0
        if count >= self.burst:
            self._held[key] = self._held.get(key, 0) + 1
            return False
        self._window[key] = (start, count + 1)
        held = self._held.pop(key, 0)
        if held:
            msg += f" ({held} similar lines held back)"
        self._log.log(level, msg, *args, exc_info=exc_info)
        return True
