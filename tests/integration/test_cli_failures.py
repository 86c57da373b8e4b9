"""Every expected failure of a `darwin` command is one line naming the cause and the fix, with
a non-zero exit status, never a traceback."""

from __future__ import annotations

import os
import socket
import subprocess
from collections.abc import Iterator
from pathlib import Path

import pytest

from robot_daemon.bus.port import PortLock
from robot_daemon.emulator import Emulator
from schemas.session import free_tcp_port
from tests.fixtures.system import REPO, darwin_command


def run_darwin(*args: str, timeout: float = 120) -> tuple[int, str, str]:
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    env.pop("DARWIN_CONFIG", None)
    out = subprocess.run(
        darwin_command(*args), capture_output=True, text=True, timeout=timeout, cwd=REPO, env=env
    )
    return out.returncode, out.stdout, out.stderr


def failure_line(command: str, *args: str) -> str:
    """Run ``darwin COMMAND ARGS``; check it failed cleanly; return its one failure line."""
    code, stdout, stderr = run_darwin(command, *args)
    assert code != 0, (stdout, stderr)
    assert "Traceback" not in stdout + stderr, stderr
    mine = [line for line in stderr.splitlines() if line.startswith(f"darwin {command}:")]
    assert len(mine) == 1, stderr
    assert ".rs:" not in mine[0]  # no source paths of the libraries underneath
    return mine[0]


@pytest.fixture
def busy_port() -> Iterator[int]:
    """A TCP port somebody else listens on."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        yield s.getsockname()[1]


def test_zenoh_port_in_use(busy_port: int) -> None:
    line = failure_line("up", "--no-gateway", "--listen", f"tcp/127.0.0.1:{busy_port}")
    assert f"tcp/127.0.0.1:{busy_port}" in line and "already in use" in line
    assert "--listen tcp/127.0.0.1:0" in line  # the fix


def test_router_port_in_use(busy_port: int) -> None:
    line = failure_line("router", "--listen", f"tcp/127.0.0.1:{busy_port}")
    assert f"cannot listen on tcp/127.0.0.1:{busy_port}" in line and "already in use" in line
    assert "another router" in line and "--listen tcp/127.0.0.1:0" in line  # the fix


def test_gateway_port_in_use(busy_port: int) -> None:
    line = failure_line(
        "up", "--listen", "tcp/127.0.0.1:0", "--gateway-listen", f"127.0.0.1:{busy_port}"
    )
    assert "gateway" in line and "already in use" in line and "--gateway-listen" in line


def test_serial_port_missing(tmp_path: Path) -> None:
    missing = tmp_path / "ttyUSB9"
    line = failure_line("daemon", "--port", str(missing), "--listen", "tcp/127.0.0.1:0")
    assert str(missing) in line and "does not exist" in line and "darwin sim" in line


def test_serial_port_locked(emulator: Emulator) -> None:
    lock = PortLock(emulator.port)
    lock.acquire()
    try:
        line = failure_line("daemon", "--port", emulator.port, "--listen", "tcp/127.0.0.1:0")
    finally:
        lock.release()
    assert f"in use by PID {os.getpid()}" in line and "--port" in line


@pytest.mark.parametrize("command", ["tui", "record"])
def test_no_daemon_at_the_endpoint(command: str, tmp_path: Path) -> None:
    endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
    extra = ["-o", str(tmp_path / "out.mcap")] if command == "record" else []
    line = failure_line(command, "--connect", endpoint, *extra)
    assert endpoint in line and "darwin up" in line


@pytest.mark.parametrize(
    ("text", "words"),
    [("robot = [\n", "not valid TOML"), ('[daemon]\ntick_ms = "fast"\n', "not usable")],
)
def test_bad_config_file(text: str, words: str, tmp_path: Path) -> None:
    config = tmp_path / "bad.toml"
    config.write_text(text)
    line = failure_line(
        "up", "--no-gateway", "--listen", "tcp/127.0.0.1:0", "--config", str(config)
    )
    assert str(config) in line and words in line


@pytest.mark.parametrize(
    ("text", "words"),
    [
        ("[daemon]\ntelemetry_hz = -5\n", ["daemon.telemetry_hz", "-5"]),
        ("[daemon]\ntelemetry_rate = 50\n", ["'telemetry_rate'", "nearest known: 'telemetry_hz'"]),
    ],
)
def test_a_bad_daemon_setting_is_named(text: str, words: list[str], tmp_path: Path) -> None:
    config = tmp_path / "daemon.toml"
    config.write_text(text)
    line = failure_line(
        "up", "--no-gateway", "--listen", "tcp/127.0.0.1:0", "--config", str(config)
    )
    assert all(w in line for w in words), line
