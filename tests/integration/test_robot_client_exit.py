"""A script that uses `Robot` and forgets `close()` still exits, and the robot is left safe: its
lease ends with the client. `wait_ready` waits for the first messages and, when none come, says
which did not arrive. (Run against a real `darwin up`, the script in its own interpreter.)"""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import pytest

from clients.robot import Robot
from schemas.errors import ClientError, CommandTimeoutError
from tests.fixtures.system import REPO, RunningSystem

# A hang detector, not a speed limit: the script takes about a second.
HANG = 120.0

FORGETFUL = textwrap.dedent(
    """
    from clients import Robot

    robot = Robot(name="forgets close")
    state = robot.wait_ready()
    robot.subscribe("imu", lambda msg: None)   # one more subscriber thread
    robot.acquire()                            # and the lease, renewed from a thread
    print("joints:", len(state.joints.position), flush=True)
    """
)


def run_script(system: RunningSystem, source: str) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "DARWIN_ENDPOINT": system.endpoint, "DARWIN_ROBOT": system.robot}
    return subprocess.run(
        [sys.executable, "-c", source], cwd=REPO, env=env, capture_output=True, text=True,
        timeout=HANG,
    )


def test_a_script_that_forgets_close_exits_and_frees_the_lease(
    robot_system: RunningSystem,
) -> None:
    with robot_system.robot_client(name="watcher") as watcher:
        try:
            run = run_script(robot_system, FORGETFUL)
        except subprocess.TimeoutExpired as exc:
            pytest.fail(f"the script did not exit: {exc.stdout!r} {exc.stderr!r}")
        assert run.returncode == 0, run.stderr
        assert run.stdout == "joints: 20\n"
        assert "Traceback" not in run.stderr
        # It held the lease when it ended; closing at exit released it.
        watcher.wait_for("status", lambda s: s.lease is None, timeout=10.0, fresh=False)


def test_wait_ready_returns_the_first_state(robot_system: RunningSystem) -> None:
    with Robot(robot_system.endpoint, robot_system.robot, name="ready") as robot:
        state = robot.wait_ready()
        assert state.joints is not None and len(state.joints.position) == 20
        assert state.imu is not None and state.status is not None
    with pytest.raises(ClientError, match="closed"):
        robot.halt()


def test_wait_ready_names_what_did_not_arrive(robot_system: RunningSystem) -> None:
    with (
        Robot(robot_system.endpoint, "nosuchrobot", name="lost") as robot,
        pytest.raises(CommandTimeoutError) as info,
    ):
        robot.wait_ready(timeout=0.5)
    message = str(info.value)
    assert "no joints, imu, status message from robot 'nosuchrobot'" in message
    assert robot_system.endpoint in message and "troubleshooting" in message
