"""The telemetry rate gate (``[daemon] telemetry_hz``): every tick by default, else the tick
nearest each multiple of the period, with an exact average rate and no burst after a stall."""

from __future__ import annotations

import itertools

import pytest

from robot_daemon.engine.telemetry_rate import RateGate, check_rate
from schemas.errors import ConfigError

TICK = 0.008


def opened(gate: RateGate, times: list[float]) -> list[float]:
    return [t for t in times if gate.open(t)]


def test_zero_opens_on_every_tick() -> None:
    times = [k * TICK for k in range(100)]
    assert opened(RateGate(0.0, TICK), times) == times


def test_the_average_rate_is_exact_and_each_interval_within_a_tick() -> None:
    times = [k * TICK for k in range(1250)]  # 10 s at 125 Hz
    out = opened(RateGate(50.0, TICK), times)
    assert len(out) in (500, 501)
    gaps = {round((b - a) / TICK) for a, b in itertools.pairwise(out)}
    assert gaps == {2, 3}  # 16 and 24 ms around 20


def test_a_rate_that_divides_the_tick_rate_is_regular() -> None:
    times = [k * TICK for k in range(500)]
    out = opened(RateGate(25.0, TICK), times)
    assert {round((b - a) / TICK) for a, b in itertools.pairwise(out)} == {5}


def test_a_stall_opens_once_then_keeps_the_rate() -> None:
    gate = RateGate(50.0, TICK)
    times = [k * TICK for k in range(10)] + [1.0 + k * TICK for k in range(50)]
    out = opened(gate, times)
    after = [t for t in out if t >= 1.0]
    assert after[0] == 1.0
    assert all(b - a >= 2 * TICK - 1e-9 for a, b in itertools.pairwise(after))  # no catching up


def test_a_rate_faster_than_the_tick_opens_every_tick() -> None:
    times = [k * TICK for k in range(100)]
    assert opened(RateGate(1000.0, TICK), times) == times


@pytest.mark.parametrize("value", [-1, "50", True, float("nan"), float("inf")])
def test_a_bad_rate_is_refused_naming_the_setting(value: object) -> None:
    with pytest.raises(ConfigError, match=r"daemon\.telemetry_hz"):
        check_rate(value, "daemon.telemetry_hz")


def test_a_whole_number_is_taken() -> None:
    assert check_rate(50, "daemon.telemetry_hz") == 50.0
