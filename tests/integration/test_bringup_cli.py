"""`darwin daemon` on a robot that is not ready for it (issue 25): a 16 ms USB latency timer,
another program holding the port, a servo with old firmware. Each is refused in one line that
names the fix, through the real CLI against the emulator on a real pty."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest

from robot_daemon.bus.tables import CM730, MX28
from robot_daemon.emulator import Emulator
from tests.fixtures.system import REPO, darwin_command
from tests.integration.test_cli_failures import failure_line


def fake_ftdi(root: Path, port: str, timer_ms: int) -> None:
    """A sysfs tree in which ``port`` is an FTDI adapter with this latency timer (the edge of
    the world: a real FTDI chip's sysfs)."""
    dev = root / "bus" / "usb-serial" / "devices" / os.path.basename(os.path.realpath(port))
    dev.mkdir(parents=True)
    (dev / "latency_timer").write_text(f"{timer_ms}\n")


def test_a_16_ms_latency_timer_is_refused_naming_the_fix(
    emulator: Emulator, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    fake_ftdi(tmp_path, emulator.port, 16)
    monkeypatch.setenv("DARWIN_SYSFS_ROOT", str(tmp_path))
    line = failure_line("daemon", "--port", emulator.port, "--listen", "tcp/127.0.0.1:0")
    assert "latency timer" in line and "16 ms" in line and "torque refused" in line
    assert "echo 1 | sudo tee /sys/bus/usb-serial/devices/" in line and "udev" in line
    assert emulator.bus.cm730.table[CM730.DXL_POWER] == 0  # DXL power never switched on


def test_a_1_ms_latency_timer_is_accepted(
    emulator: Emulator, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    fake_ftdi(tmp_path, emulator.port, 1)
    monkeypatch.setenv("DARWIN_SYSFS_ROOT", str(tmp_path))
    with running_daemon(emulator.port) as daemon:
        assert daemon.poll() is None


def test_another_process_holding_the_port_is_refused_naming_it(emulator: Emulator) -> None:
    # ROBOTIS's demo opens the port with a plain open(): no lock file, no flock.
    holder = subprocess.Popen(
        [
            sys.executable,
            "-c",
            "import os, sys; os.open(sys.argv[1], os.O_RDWR | os.O_NOCTTY); print('held', "
            "flush=True); sys.stdin.read()",
            emulator.port,
        ],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert holder.stdout is not None and holder.stdout.readline().strip() == "held"
        line = failure_line("daemon", "--port", emulator.port, "--listen", "tcp/127.0.0.1:0")
    finally:
        holder.kill()
        holder.communicate()
    assert f"held open by PID {holder.pid}" in line and "python" in line
    assert f"sudo kill {holder.pid}" in line and "/etc/rc.local" in line


def test_a_servo_with_old_firmware_gets_no_torque_and_one_line(
    emulator_factory: Callable[..., Emulator],
) -> None:
    emulator = emulator_factory(old_firmware_ids=[7])
    with running_daemon(emulator.port) as daemon:
        lines = stderr_until(daemon, "firmware 26")
        line = lines[-1]
        assert "servo 7" in line and "27 (0x1B)" in line and "firmware_installer" in line
        assert len([x for x in lines if "firmware" in x]) == 1
        emulator.wait_quiet()
        assert emulator.bus.servo(7).table[MX28.TORQUE_ENABLE] == 0
        assert emulator.bus.servo(8).table[MX28.TORQUE_ENABLE] == 1


def stderr_until(daemon: subprocess.Popen[str], text: str) -> list[str]:
    """The daemon's log lines up to the first that contains ``text``."""
    assert daemon.stderr is not None
    lines = []
    for raw in daemon.stderr:
        lines.append(raw)
        if text in raw:
            return lines
    raise AssertionError(f"the daemon ended without saying {text!r}: {lines}")


class running_daemon:
    """``darwin daemon --port PORT`` until the block ends (SIGTERM: it halts and holds)."""

    def __init__(self, port: str) -> None:
        env = dict(os.environ, PYTHONUNBUFFERED="1")
        env.pop("DARWIN_CONFIG", None)
        args = darwin_command("daemon", "--port", port, "--listen", "tcp/127.0.0.1:0")
        self.proc = subprocess.Popen(
            args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=REPO, env=env
        )

    def __enter__(self) -> subprocess.Popen[str]:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:  # its addresses: the bus is up, torque on
            if line.startswith("zenoh:"):
                break
        else:
            raise AssertionError(f"the daemon ended: {self.proc.stderr.read()}")  # type: ignore[union-attr]
        return self.proc

    def __exit__(self, *exc: object) -> None:
        self.proc.send_signal(signal.SIGTERM)
        try:
            self.proc.wait(timeout=30)
        finally:
            if self.proc.poll() is None:
                self.proc.kill()
            self.proc.communicate()  # waits and closes its pipes


def test_two_servos_answering_one_id_are_left_offline_with_one_line(
    emulator_factory: Callable[..., Emulator],
) -> None:
    emulator = emulator_factory()
    with emulator.lock:
        emulator.bus.servo(8).set_position(1500)
        emulator.bus.set_id(8, 7)  # a replaced servo given servo 7's ID
    with running_daemon(emulator.port) as daemon:
        line = stderr_until(daemon, "two servos answer")[-1]
        assert "servo 7" in line and "ID 7" in line and "torque refused" in line
        emulator.wait_quiet()
        # Neither the hip nor the servo wrongly given its ID gets torque or a goal.
        assert emulator.bus.servo(7).table[MX28.TORQUE_ENABLE] == 0
        assert emulator.bus.servo(8).table[MX28.TORQUE_ENABLE] == 0
        assert emulator.bus.servo(9).table[MX28.TORQUE_ENABLE] == 1
