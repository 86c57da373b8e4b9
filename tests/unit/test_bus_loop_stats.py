"""Loop statistics: percentiles over the window, counters always current."""

from __future__ import annotations

import pytest

from robot_daemon.engine.loop_stats import LoopStats


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


def test_sustained_overruns_raise_the_alarm_once_and_a_clean_window_clears_it() -> None:
    events: list[tuple[str, dict[str, object]]] = []
    stats = LoopStats(0.008, emit=lambda kind, message, **data: events.append((kind, data)))
    t = 0.0

    def window(overrun_every: int) -> None:
        nonlocal t
        for i in range(251):  # a little over OVERLOAD_WINDOW_S of 8 ms ticks
            stats.tick(t, 0.003, 0.004)
            if overrun_every and i % overrun_every == 0:
                stats.overrun(0)
            t += 0.008

    window(0)
    window(1000)  # one overrun in 250 ticks (0.4 %): no alarm
    assert not stats.summary()["overloaded"] and events == []
    window(10)  # 10 %
    window(10)
    s = stats.summary()
    assert s["overloaded"] and s["overrun_pct"] >= 5.0
    assert [k for k, _ in events] == ["loop_overloaded"]
    assert events[0][1]["tick_ms"] == 8.0
    window(50)  # 2 %: not yet clear (hysteresis)
    assert stats.summary()["overloaded"]
    window(0)
    window(0)
    assert not stats.summary()["overloaded"]
    assert [k for k, _ in events] == ["loop_overloaded", "loop_recovered"]
