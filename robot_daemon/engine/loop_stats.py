"""Per-tick timing statistics of the motion loop: period, bus time, overruns, and the alarm
when the computer cannot keep up (``status.loop.overloaded``)."""

from __future__ import annotations

import time
from array import array
from collections.abc import Callable
from typing import Any

import numpy as np

# Sustained overruns: judged over windows this long; the alarm rises when at least
# OVERLOAD_PCT of a window's ticks overran and falls after a window under CLEAR_PCT.
OVERLOAD_WINDOW_S = 2.0
OVERLOAD_PCT = 5.0
CLEAR_PCT = 1.0

Emit = Callable[..., None]  # emit(kind, message, **data): the daemon's event stream


class LoopStats:
    """A rolling window of tick periods and bus times (seconds), plus running counters.

    The windows are rings of doubles (``array``), written in place each tick, and their
    percentiles are picked by numpy's selection on the ring's memory when status asks: sorting
    three windows of 1 000 Python floats cost ~1 M instructions on the robot's Python (i386),
    twice a second (``tick_count.py daemon``), a numpy partition of each ~65 k."""

    def __init__(self, tick_s: float, window: int = 1000, emit: Emit | None = None) -> None:
        self.tick_s = tick_s
        self.emit = emit
        self.overloaded = False
        self.overrun_pct = 0.0  # of the last full window
        self._size = window
        self._periods = array("d", bytes(8 * window))
        self._bus = array("d", bytes(8 * window))
        self._work = array("d", bytes(8 * window))
        self._periods_n = 0  # periods written (the ring holds the last ``window``)
        self._at = 0  # where the next bus and work times go (one of each a tick)
        self.ticks = 0
        self.overruns = 0  # ticks whose work ran past the next deadline
        self.skipped = 0  # deadlines given up to catch up after an overrun
        self._last_start: float | None = None
        self._cached: dict[str, Any] | None = None
        self._cached_at = 0.0
        self._win_t0: float | None = None  # when the window began (the loop's clock)
        self._win_ticks = self._win_overruns = 0

    def tick(self, start: float, bus_s: float, work_s: float) -> None:
        size = self._size
        if self._last_start is not None:
            self._periods[self._periods_n % size] = start - self._last_start
            self._periods_n += 1
        self._last_start = start
        at = self._at
        self._bus[at] = bus_s
        self._work[at] = work_s
        self._at = at + 1 if at + 1 < size else 0
        self.ticks += 1
        # Windows of the loop's own clock, not of ticks: an overloaded loop ticks less often.
        self._win_ticks += 1
        if self._win_t0 is None:
            self._win_t0 = start
        elif start - self._win_t0 >= OVERLOAD_WINDOW_S:
            self._win_t0 = start
            self._judge()

    def overrun(self, skipped: int) -> None:
        self.overruns += 1
        self.skipped += skipped
        self._win_overruns += 1

    def _judge(self) -> None:
        pct = 100.0 * self._win_overruns / self._win_ticks
        self.overrun_pct = pct
        self._win_ticks = self._win_overruns = 0
        was = self.overloaded
        if not was and pct >= OVERLOAD_PCT:
            self.overloaded = True
        elif was and pct < CLEAR_PCT:
            self.overloaded = False
        if self.overloaded == was or self.emit is None:
            return
        tick_ms = self.tick_s * 1000.0
        if self.overloaded:
            self.emit(
                "loop_overloaded",
                f"the computer cannot keep the {tick_ms:g} ms motion loop: {pct:.0f} % of the "
                f"ticks in the last {OVERLOAD_WINDOW_S:g} s overran; lighten its load: fewer "
                "servo reads a tick, a lower telemetry rate, nothing else on the robot's "
                "computer (docs/troubleshooting.md#overloaded)",
                overrun_pct=round(pct, 1),
                tick_ms=tick_ms,
            )
        else:
            self.emit(
                "loop_recovered",
                f"the motion loop keeps its {tick_ms:g} ms tick again ({pct:.1f} % overruns)",
                overrun_pct=round(pct, 1),
                tick_ms=tick_ms,
            )

    def reset_period(self) -> None:
        """Forget the last start (after a pause such as a port reopen)."""
        self._last_start = None

    def summary(self, max_age: float = 0.5, now: float | None = None) -> dict[str, Any]:
        """The figures, recomputed at most every ``max_age`` s of the loop's clock (``now``;
        the percentiles over the window are the costly part); counters are always current."""
        now = time.monotonic() if now is None else now
        if self._cached is None or now - self._cached_at >= max_age:
            self._cached, self._cached_at = self._compute(), now
        return {
            **self._cached,
            "ticks": self.ticks,
            "overruns": self.overruns,
            "overloaded": self.overloaded,
            "overrun_pct": round(self.overrun_pct, 1),
        }

    def _compute(self) -> dict[str, Any]:
        size, ticks = self._size, min(self.ticks, self._size)
        period_p50, period_p99, period_max = _pcts(
            self._periods, min(self._periods_n, size), (50, 99, 100)
        )
        bus_p50, bus_p99 = _pcts(self._bus, ticks, (50, 99))
        (work_p99,) = _pcts(self._work, ticks, (99,))
        return {
            "tick_ms": self.tick_s * 1000.0,
            "period_p50_ms": period_p50,
            "period_p99_ms": period_p99,
            "period_max_ms": period_max,
            "bus_p50_ms": bus_p50,
            "bus_p99_ms": bus_p99,
            "work_p99_ms": work_p99,
            "skipped": self.skipped,
        }


def _rank(n: int, q: float) -> int:
    """Where the q-th percentile (nearest rank) of n ordered values is."""
    return min(n - 1, round(q / 100.0 * (n - 1)))


def _pcts(ring: array[float], n: int, qs: tuple[float, ...]) -> list[float]:
    """The q-th percentiles (nearest rank; 100: the largest) of the first ``n`` values of a
    ring of seconds, in ms: the values a sort would put at those ranks, picked by one
    partition (tests/unit/test_bus_loop_stats.py checks them against ``sorted``)."""
    if n == 0:
        return [0.0] * len(qs)
    ranks = [_rank(n, q) for q in qs]
    picked = np.partition(np.frombuffer(ring, dtype=np.float64, count=n), ranks)
    return [float(picked[k]) * 1000.0 for k in ranks]
