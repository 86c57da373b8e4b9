"""The daemon of the core install, with every extra's package refusing to import
(tests/no_extras.py: no OpenCV, no cryptography, …), drives the emulator through a real pty:
a client reads the joints and walks the robot, and ball play answers in one line that it needs
the `vision` extra, without moving a servo."""

from __future__ import annotations

import subprocess
import sys
import uuid
from pathlib import Path

import pytest

from clients.robot import Robot
from schemas.errors import UnavailableError
from schemas.session import free_tcp_port
from tests.fixtures.emulator import start_emulator_process, stop_process

REPO = Path(__file__).resolve().parents[2]
WAIT = 30.0


def test_the_core_daemon_walks_and_ball_play_names_the_vision_extra(tmp_path: Path) -> None:
    with start_emulator_process("--power-on-delay", "0", link_dir=tmp_path) as sim:
        endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
        robot_name = f"core{uuid.uuid4().hex[:8]}"
        log = (tmp_path / "daemon.log").open("w")
        daemon = subprocess.Popen(
            [
                sys.executable,
                str(REPO / "tests" / "no_extras.py"),
                "darwin",
                "daemon",
                "--port",
                sim.port,
                "--listen",
                endpoint,
                "--robot",
                robot_name,
                "--camera",
                "none",
            ],
            stdout=subprocess.PIPE,
            stderr=log,
            text=True,
            cwd=REPO,
        )
        try:
            assert daemon.stdout is not None
            lines = [daemon.stdout.readline() for _ in range(3)]
            assert lines[-1].startswith("zenoh: "), (lines, (tmp_path / "daemon.log").read_text())
            with Robot(endpoint, robot_name, name="core test", timeout=10.0) as robot:
                joints = robot.wait_for("joints", timeout=WAIT)
                assert all(joints.online)
                with robot.control():
                    robot.walk(x=0.03)
                    robot.wait_for(
                        "status", lambda s: s.motion.get("walking", {}).get("steps", 0) >= 2, WAIT
                    )
                    robot.walk_stop()
                    with pytest.raises(UnavailableError) as err:
                        robot.playball("red")
            assert str(err.value).endswith(
                "ball finding: needs the 'vision' extra: pip install 'darwin-zenoh[vision]'"
            )
        finally:
            stop_process(daemon)
            log.close()
    assert "Traceback" not in (tmp_path / "daemon.log").read_text()
