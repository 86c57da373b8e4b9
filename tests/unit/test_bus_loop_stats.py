"""Loop statistics: percentiles over the window, counters always current."""

from __future__ import annotations

import random

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


def _sorted_pct(values: list[float], q: float) -> float:
    """The definition: the q-th percentile (nearest rank) of the values sorted, in ms."""
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, round(q / 100.0 * (len(ordered) - 1)))] * 1000.0


@pytest.mark.parametrize("ticks", [1, 2, 7, 99, 100, 101, 250, 1234])
def test_percentiles_are_those_of_the_sorted_window(ticks: int) -> None:
    # The window is a ring picked by numpy's partition: the same values as sorting the last
    # `window` of each series, before the ring is full, when it just wrapped and long after;
    # ties and a reset period (no period for that tick) included.
    rng = random.Random(ticks)
    stats = LoopStats(0.008, window=100)
    periods: list[float] = []
    bus: list[float] = []
    work: list[float] = []
    t, last = 0.0, None
    for i in range(ticks):
        if i == ticks // 2:
            stats.reset_period()
            last = None
        b, w = rng.choice([0.002, rng.random() * 0.01]), rng.random() * 0.02
        stats.tick(t, b, w)
        if last is not None:
            periods.append(t - last)
        last = t
        bus.append(b)
        work.append(w)
        t += 0.008 + rng.choice([0.0, rng.random() * 0.01])
    s = stats.summary()
    p, b100, w100 = periods[-100:], bus[-100:], work[-100:]
    want = {
        "period_p50_ms": _sorted_pct(p, 50) if p else 0.0,
        "period_p99_ms": _sorted_pct(p, 99) if p else 0.0,
        "period_max_ms": max(p) * 1000.0 if p else 0.0,
        "bus_p50_ms": _sorted_pct(b100, 50),
        "bus_p99_ms": _sorted_pct(b100, 99),
        "work_p99_ms": _sorted_pct(w100, 99),
    }
    assert {k: s[k] for k in want} == want  # the same floats, not approximately
