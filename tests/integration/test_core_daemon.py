"""The daemon of the core install, with every extra's package refusing to import
(tests/no_extras.py: no OpenCV, no cryptography, …), drives the emulator through a real pty:
a client reads the joints and walks the robot, and ball play answers in one line that it needs
the `vision` extra; with TLS and logins (certificates made elsewhere) it needs no cryptography."""

from __future__ import annotations

import contextlib
import subprocess
import sys
import uuid
from collections.abc import Iterator
from pathlib import Path

import pytest

from clients.robot import Robot
from schemas.errors import UnavailableError
from schemas.roles import Role
from schemas.session import Credentials, free_tcp_port
from tests.fixtures.emulator import start_emulator_process, stop_process
from tests.fixtures.system import run_darwin
from tests.integration.test_auth import PASSWORDS, make_users

REPO = Path(__file__).resolve().parents[2]
WAIT = 30.0
SIM = ("--no-wire-timing", "--power-on-delay", "0")


@contextlib.contextmanager
def core_daemon(tmp_path: Path, port: str, *args: str) -> Iterator[str]:
    """``darwin daemon`` without any extra on ``port``: yields its robot name once it listens."""
    robot_name = f"core{uuid.uuid4().hex[:8]}"
    log_path = tmp_path / "daemon.log"
    with log_path.open("w") as log:
        daemon = subprocess.Popen(
            [sys.executable, str(REPO / "tests" / "no_extras.py"), "darwin", "daemon",
             "--port", port, "--robot", robot_name, "--camera", "none", *args],
            stdout=subprocess.PIPE, stderr=log, text=True, cwd=REPO,
        )
        try:
            assert daemon.stdout is not None
            lines = [daemon.stdout.readline() for _ in range(3)]
            assert lines[-1].startswith("zenoh: "), (lines, log_path.read_text())
            yield robot_name
        finally:
            stop_process(daemon)
    assert "Traceback" not in log_path.read_text()


def test_the_core_daemon_walks_and_ball_play_names_the_vision_extra(tmp_path: Path) -> None:
    with start_emulator_process(*SIM, link_dir=tmp_path) as sim:
        endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
        with (
            core_daemon(tmp_path, sim.port, "--listen", endpoint) as robot_name,
            Robot(endpoint, robot_name, name="core test", timeout=10.0) as robot,
        ):
            robot.wait_for("joints", lambda j: all(j.online), WAIT)
            with robot.control():
                robot.walk(x=0.03)
                robot.wait_for(
                    "status", lambda s: s.motion.get("walking", {}).get("steps", 0) >= 2, WAIT
                )
                robot.walk_stop()
                with pytest.raises(UnavailableError) as err:
                    robot.playball("red")
        assert str(err.value).endswith(
            "ball finding: needs the 'vision' extra: pip install -e '.[vision]' in the project's "
            "clone "
            "(on the robot: apt-get install python3-opencv)"
        )


def test_the_core_daemon_serves_tls_and_logins_without_cryptography(tmp_path: Path) -> None:
    # The certificates are made where the security extra is (a laptop); the robot only serves.
    certs = tmp_path / "certs"
    done = run_darwin("certs", "--dir", str(certs), "--host", "127.0.0.1")
    assert done.returncode == 0, done.stderr
    users = make_users(tmp_path)
    endpoint = f"tls/127.0.0.1:{free_tcp_port()}"
    creds = Credentials("op", PASSWORDS["op"], ca=str(certs / "ca.pem"))
    with (
        start_emulator_process(*SIM, link_dir=tmp_path) as sim,
        core_daemon(tmp_path, sim.port, "--secure", "--certs", str(certs), "--auth", str(users),
                    "--listen", endpoint) as robot_name,
        Robot(endpoint, robot_name, credentials=creds, timeout=10.0) as robot,
    ):
        assert robot.role == Role.OPERATOR
        robot.wait_for("joints", lambda j: all(j.online), WAIT)
