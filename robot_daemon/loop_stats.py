"""Per-tick timing statistics of the motion loop: period, bus time, overruns."""

from __future__ import annotations

import time
from collections import deque
from typing import Any


class LoopStats:
    """A rolling window of tick periods and bus times (seconds), plus running counters."""

    def __init__(self, tick_s: float, window: int = 1000) -> None:
        self.tick_s = tick_s
        self.periods: deque[float] = deque(maxlen=window)
        self.bus_times: deque[float] = deque(maxlen=window)
        self.work_times: deque[float] = deque(maxlen=window)
        self.ticks = 0
        self.overruns = 0  # ticks whose work ran past the next deadline
        self.skipped = 0  # deadlines given up to catch up after an overrun
        self._last_start: float | None = None
        self._cached: dict[str, Any] | None = None
        self._cached_at = 0.0

    def tick(self, start: float, bus_s: float, work_s: float) -> None:
        if self._last_start is not None:
            self.periods.append(start - self._last_start)
        self._last_start = start
        self.bus_times.append(bus_s)
        self.work_times.append(work_s)
        self.ticks += 1

    def overrun(self, skipped: int) -> None:
        self.overruns += 1
        self.skipped += skipped

    def reset_period(self) -> None:
        """Forget the last start (after a pause such as a port reopen)."""
        self._last_start = None

    def summary(self, max_age: float = 0.5) -> dict[str, Any]:
        """The figures, recomputed at most every ``max_age`` s (percentiles over the window
        are the costly part); counters are always current."""
        now = time.monotonic()
        if self._cached is None or now - self._cached_at >= max_age:
            self._cached, self._cached_at = self._compute(), now
        return {**self._cached, "ticks": self.ticks, "overruns": self.overruns}

    def _compute(self) -> dict[str, Any]:
        periods = sorted(self.periods)
        bus = sorted(self.bus_times)
        work = sorted(self.work_times)
        return {
            "tick_ms": self.tick_s * 1000.0,
            "period_p50_ms": _pct(periods, 50),
            "period_p99_ms": _pct(periods, 99),
            "period_max_ms": periods[-1] * 1000.0 if periods else 0.0,
            "bus_p50_ms": _pct(bus, 50),
            "bus_p99_ms": _pct(bus, 99),
            "work_p99_ms": _pct(work, 99),
            "skipped": self.skipped,
        }


def _pct(ordered: list[float], q: float) -> float:
    """The q-th percentile (nearest rank) of sorted seconds, in ms."""
    if not ordered:
        return 0.0
    return ordered[min(len(ordered) - 1, round(q / 100.0 * (len(ordered) - 1)))] * 1000.0
