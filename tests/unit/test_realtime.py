"""Real-time scheduling of the motion thread: asked for, refused with the fix, never inherited."""

from __future__ import annotations

import os
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from robot_daemon.realtime import check_priority, current_policy, enter_realtime
from schemas.errors import ConfigError

pytestmark = pytest.mark.skipif(
    not hasattr(os, "sched_setscheduler"), reason="no POSIX real-time scheduling here"
)


def in_thread(fn: Callable[[], Any]) -> Any:
    """Run ``fn`` in a thread of its own: scheduling is per thread, and the test runner's
    own thread must never become real-time."""
    out: list[Any] = []
    t = threading.Thread(target=lambda: out.append(fn()))
    t.start()
    t.join(timeout=10)
    return out[0]


def test_zero_leaves_the_thread_as_it_is() -> None:
    assert in_thread(lambda: (enter_realtime(0), current_policy())) == (None, "other")


@pytest.mark.parametrize("priority", [-1, 100, 1000])
def test_a_priority_out_of_range_is_refused_naming_the_setting(priority: int) -> None:
    with pytest.raises(ConfigError, match="realtime_priority"):
        enter_realtime(priority)
    with pytest.raises(ConfigError, match=r"daemon\.realtime_priority"):
        check_priority(priority, "daemon.realtime_priority")


def test_real_time_when_allowed_else_a_warning_with_the_fix() -> None:
    warning, policy = in_thread(lambda: (enter_realtime(10), current_policy()))
    if warning is None:
        assert policy == "fifo"
    else:
        assert policy == "other"
        assert "rtprio" in warning and "realtime_priority = 0" in warning


def test_threads_started_by_the_real_time_thread_run_normally() -> None:
    def start_child() -> tuple[str | None, str, str]:
        warning = enter_realtime(10)
        mine = current_policy()
        child = in_thread(current_policy)
        return warning, mine, child

    warning, mine, child = in_thread(start_child)
    if warning is not None:
        pytest.skip(f"real-time scheduling not permitted here: {warning}")
    assert (mine, child) == ("fifo", "other")


def test_cpu_latency_is_written_and_held(tmp_path: Path) -> None:
    """The PM QoS request is the latency as a 32-bit int, held while the descriptor is open."""
    from robot_daemon.realtime import hold_cpu_latency

    qos = tmp_path / "cpu_dma_latency"
    qos.write_bytes(b"")
    fd, warning = hold_cpu_latency(50, str(qos))
    assert warning is None and fd is not None
    os.close(fd)
    assert qos.read_bytes() == (50).to_bytes(4, "little")
    assert hold_cpu_latency(-1, str(qos)) == (None, None)


def test_cpu_latency_without_permission_is_one_warning(tmp_path: Path) -> None:
    from robot_daemon.realtime import check_latency, hold_cpu_latency

    fd, warning = hold_cpu_latency(50, str(tmp_path / "missing"))
    assert fd is None and warning is not None and "\n" not in warning
    assert "cpu_dma_latency_us = -1" in warning
    with pytest.raises(ConfigError, match=r"daemon\.cpu_dma_latency_us"):
        check_latency("50", "daemon.cpu_dma_latency_us")


def test_the_emulators_bus_and_physics_threads_run_at_their_own_priorities() -> None:
    # The physics thread real-time too, below the bus: starved by a busy machine, its rounds
    # came late and caught up in one go under one set of goals, and a walking robot in MuJoCo
    # fell (tests/physics/test_up.py beside busy loops).
    import time

    from robot_daemon.emulator.emulator import Emulator
    from robot_daemon.emulator.settings import EmulatorSettings

    with pytest.raises(ConfigError, match="emulator physics_priority"):
        Emulator(physics_priority=100)
    shipped = EmulatorSettings.load(None)  # config/emulator.toml
    assert 0 < shipped.physics_priority < shipped.realtime_priority
    if in_thread(lambda: enter_realtime(10)) is not None:
        pytest.skip("real-time scheduling not permitted here")  # as the tests above
    emulator = Emulator(shipped).start()
    try:
        threads = {"bus": emulator._thread, "physics": emulator._physics_thread}
        want = {
            "bus": (os.SCHED_FIFO, shipped.realtime_priority),
            "physics": (os.SCHED_FIFO, shipped.physics_priority),
        }
        deadline = time.monotonic() + 10.0

        def seen() -> dict[str, tuple[int, int]]:
            # Each thread sets its own scheduling as it starts: read it off its kernel task.
            out = {}
            for name, thread in threads.items():
                assert thread is not None and thread.native_id is not None
                policy = os.sched_getscheduler(thread.native_id) & ~os.SCHED_RESET_ON_FORK
                out[name] = (policy, os.sched_getparam(thread.native_id).sched_priority)
            return out

        # Nothing announces that a thread has set its scheduling: poll, with a deadline.
        while seen() != want and time.monotonic() < deadline:
            time.sleep(0.01)
        assert seen() == want
    finally:
        emulator.stop()
