"""`darwin up` stops every child it started when it gets SIGTERM or Ctrl-C (SIGINT)."""

from __future__ import annotations

import os
import signal
import time

import pytest

from tests.fixtures.system import start_system


def group_alive(pgid: int) -> bool:
    try:
        os.killpg(pgid, 0)
    except ProcessLookupError:
        return False
    return True


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_up_leaves_no_child_behind(sig: signal.Signals) -> None:
    with start_system(gateway=False) as system:
        with system.robot_client() as robot:
            assert robot.wait_for("status", timeout=10).state in ("running", "degraded")
        pgid = system.process.pid  # `darwin up` leads its own process group
        os.kill(system.process.pid, sig)  # only `darwin up` itself, not the group
        assert system.process.wait(timeout=30) == 0
        deadline = time.monotonic() + 20
        while group_alive(pgid) and time.monotonic() < deadline:
            time.sleep(0.1)  # children exit on their own; polling their group is all there is
        assert not group_alive(pgid), "a child of `darwin up` outlived it"
