"""Loop statistics: percentiles over the window, counters always current."""

from __future__ import annotations

import pytest

from robot_daemon.loop_stats import LoopStats


def test_periods_bus_time_and_overruns() -> None:
    stats = LoopStats(0.008, window=100)
    t = 0.0
    for i in range(101):
        stats.tick(t, bus_s=0.005, work_s=0.006)
        t += 0.008 if i % 10 else 0.012  # one long period in ten
    stats.overrun(2)
    s = stats.summary()
    assert s["ticks"] == 101 and s["overruns"] == 1 and s["skipped"] == 2
    assert s["period_p50_ms"] == pytest.approx(8.0)
    assert s["period_max_ms"] == pytest.approx(12.0)
    assert s["bus_p50_ms"] == pytest.approx(5.0)
    stats.tick(t, 0.005, 0.006)
    assert stats.summary()["ticks"] == 102  # counters do not wait for the cache


def test_empty_window_reports_zeros() -> None:
    s = LoopStats(0.008).summary()
    assert s["period_p99_ms"] == 0.0 and s["ticks"] == 0
