"""`darwin scan` lists every device on a real pty served by the emulator, and refuses a port
that another process holds."""

from __future__ import annotations

import json
import subprocess
from collections.abc import Callable

from robot_daemon.bus.port import BlockingPortHandler
from robot_daemon.emulator import Emulator
from tests.fixtures.system import run_darwin


def scan(*args: str) -> subprocess.CompletedProcess[str]:
    return run_darwin("scan", *args)


def test_scan_lists_every_device(emulator: Emulator) -> None:
    out = scan("--port", emulator.port, "--json")
    assert out.returncode == 0, out.stderr
    devices = [json.loads(line) for line in out.stdout.splitlines()]
    assert [d["id"] for d in devices] == [*range(1, 21), 200]
    servo = devices[0]
    assert servo["model"] == "MX-28" and servo["return_delay_us"] == 0
    assert {"firmware", "position", "goal", "voltage", "temperature", "pid"} <= set(servo)
    assert devices[-1]["model"] == "CM-730" and devices[-1]["power"] is True


def test_lost_replies_are_asked_again_so_no_device_goes_missing(
    emulator_factory: Callable[..., Emulator],
) -> None:
    emulator = emulator_factory(drop=0.3)
    out = scan("--port", emulator.port, "--json", "--tries", "10")
    assert out.returncode == 0, out.stderr
    assert [json.loads(line)["id"] for line in out.stdout.splitlines()] == [*range(1, 21), 200]
    assert emulator.stats["dropped"] > 0  # the scan really met lost replies


def test_scan_of_a_held_port_names_the_holder(emulator: Emulator) -> None:
    holder = BlockingPortHandler(emulator.port)
    holder.open(1_000_000)
    try:
        out = scan("--port", emulator.port)
    finally:
        holder.close()
    assert out.returncode == 1
    assert "in use by PID" in out.stderr


def test_scan_of_a_missing_port_says_so(tmp_path: object) -> None:
    out = scan("--port", f"{tmp_path}/ttyUSB7")
    assert out.returncode == 1
    assert "does not exist" in out.stderr
