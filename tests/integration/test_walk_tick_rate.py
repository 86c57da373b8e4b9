"""A slower motion tick (``[daemon] tick_ms`` 10 or 16, for a computer that cannot keep 8 ms)
walks with the same step timing and the same speed, on the simulated robot (daemon bus code,
emulator, kinematic world: :class:`SimRig`, simulated time)."""

from __future__ import annotations

import copy
import functools

import pytest

from config.loader import load_all
from tests.fixtures.sim_rig import SimRig

SECONDS = 4.8  # eight gait periods of 600 ms


@functools.cache
def walk(tick_ms: float) -> tuple[list[float], float, float]:
    """Walk forward for SECONDS: (simulated time of every step, distance, period in s)."""
    settings = copy.deepcopy(load_all())
    settings["daemon"] = {**settings.get("daemon", {}), "tick_ms": tick_ms}
    rig = SimRig(seed=3, settings=settings)
    assert rig.tick_s == pytest.approx(tick_ms / 1000)
    walking = rig.manager.module("walking")
    # Gyro feedback answers the emulated IMU, which depends on the tick: the gait's own timing.
    walking.params.balance_enable = False
    walking.start(0.08, 0.0, 0.0)
    rig.run_until(lambda r: walking.steps >= 2, timeout=10)
    x0, steps, times = rig.world.body.state().x, walking.steps, []
    end = rig.time + SECONDS
    while rig.time < end - 1e-9:
        rig.step()
        if walking.steps != steps:
            steps = walking.steps
            times.append(rig.time)
    return times, rig.world.body.state().x - x0, walking.params.period_time / 1000


@pytest.mark.parametrize("tick_ms", [10.0, 16.0])
def test_a_slower_tick_keeps_the_step_timing_and_the_speed(tick_ms: float) -> None:
    ref_times, ref_dist, period = walk(8.0)
    times, dist = walk(tick_ms)[:2]
    half = period / 2
    assert len(ref_times) == pytest.approx(SECONDS / half, abs=1)
    assert len(times) == len(ref_times)
    # Every step lands on the half-period grid, give or take the tick it falls in: no drift
    # over eight periods (608 ms periods at 16 ms would drift 64 ms, four ticks, by the end).
    late = [t - k * half for k, t in enumerate(times)]
    assert max(late) - min(late) <= tick_ms / 1000 + 1e-9, late
    assert dist == pytest.approx(ref_dist, rel=0.05)
    assert dist > 0.3 * 0.08 * SECONDS  # it walks
