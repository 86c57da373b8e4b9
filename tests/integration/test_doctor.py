"""`darwin doctor` against the emulator with faults injected (broken chain, hot servo, low
voltage, old firmware, a second holder of the port, a 16 ms latency timer, the wrong baud rate)
and against a running daemon."""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from robot_daemon.bus.tables import MX28
from robot_daemon.doctor import checks as C
from robot_daemon.emulator import Emulator
from schemas.session import free_tcp_port
from tests.fixtures.system import REPO, RunningSystem, darwin_command


def doctor(*args: str) -> tuple[int, str]:
    out = subprocess.run(
        darwin_command("doctor", *args), capture_output=True, text=True, timeout=120, cwd=REPO
    )
    assert "Traceback" not in out.stderr, out.stderr
    return out.returncode, out.stdout


def no_daemon() -> list[str]:
    return ["--connect", f"tcp/127.0.0.1:{free_tcp_port()}"]


def by_name(stdout: str) -> dict[str, dict[str, Any]]:
    report = json.loads(stdout)
    return {c["name"]: c for c in report["checks"]}


def test_a_healthy_robot_passes_every_check(emulator: Emulator) -> None:
    code, out = doctor("--port", emulator.port, *no_daemon())
    assert code == 0, out
    lines = out.splitlines()
    assert any(line.startswith("OK    servos: 20/20 MX-28 with firmware ≥ 27") for line in lines)
    assert any(line.startswith("OK    bus: 21 device(s) answer at 1000000 bps") for line in lines)
    assert not [line for line in lines if line.startswith("FAIL")]


def test_faults_are_each_named_with_their_fix(emulator_factory: Callable[..., Emulator]) -> None:
    emu = emulator_factory(broken_after=[11], overheat_ids=[5], voltage=10.2)
    emu.bus.servo(8).table[MX28.FIRMWARE_VERSION] = 26
    code, out = doctor("--port", emu.port, "--json", *no_daemon())
    assert code == 1
    report = json.loads(out)
    assert report["ok"] is False and report["source"] == "bus"
    checks = by_name(out)
    chain = checks["chain right leg"]
    assert chain["status"] == "fail"
    assert chain["detail"].startswith("ID 13 does not answer, nor the 2 behind it (15, 17)")
    assert "servo 13" in chain["fix"]
    assert "chain left leg" not in checks  # the other branches still answer
    assert (
        checks["servo 8"]["status"] == "fail" and "firmware 26 < 27" in checks["servo 8"]["detail"]
    )
    assert checks["temperature"]["status"] == "fail" and "ID 5" in checks["temperature"]["detail"]
    assert checks["voltage"]["status"] == "fail" and "battery" in checks["voltage"]["fix"]
    assert checks["servos"]["detail"].startswith("16/20")


def test_another_holder_of_the_port_is_named_by_pid(emulator: Emulator) -> None:
    holder = subprocess.Popen(
        [
            sys.executable,
            "-c",
            f"import os,sys; fd=os.open({emulator.port!r}, os.O_RDWR); "
            "print('held', flush=True); sys.stdin.read()",
        ],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert holder.stdout is not None and holder.stdout.readline().strip() == "held"
        code, out = doctor("--port", emulator.port, *no_daemon())
        assert code == 1
        line = next(x for x in out.splitlines() if "port holder" in x)
        assert (
            line.startswith("FAIL") and f"PID {holder.pid}" in line and f"kill {holder.pid}" in line
        )
    finally:
        holder.kill()
        holder.communicate()


def test_a_16_ms_latency_timer_fails_with_the_sysfs_fix(emulator: Emulator, tmp_path: Path) -> None:
    # The sysfs of a real FTDI chip is outside our world: a directory shaped like it.
    dev = Path(emulator.port).resolve().name
    timer = tmp_path / "bus" / "usb-serial" / "devices" / dev / "latency_timer"
    timer.parent.mkdir(parents=True)
    timer.write_text("16\n")
    code, out = doctor("--port", emulator.port, "--sysfs", str(tmp_path), *no_daemon())
    line = next(x for x in out.splitlines() if "latency timer" in x)
    assert code == 1 and line.startswith("FAIL  latency timer: 16 ms") and f"tee {timer}" in line
    timer.write_text("1\n")
    assert C.latency_timer(emulator.port, tmp_path).status == C.OK


def test_the_wrong_baud_rate_names_the_one_that_answers(emulator: Emulator) -> None:
    code, out = doctor("--port", emulator.port, "--baud", "57600", *no_daemon())
    assert code == 1
    assert "FAIL  bus: devices answer at 1000000 bps, not at the configured 57600" in out


def test_a_missing_port_fails_in_one_line_with_its_fix(tmp_path: Path) -> None:
    code, out = doctor("--port", str(tmp_path / "ttyUSB9"), *no_daemon())
    assert code == 1
    assert f"FAIL  serial: {tmp_path / 'ttyUSB9'} does not exist — fix: plug in" in out


def test_with_the_daemon_running_it_asks_the_daemon(robot_system: RunningSystem) -> None:
    # The session's system: the doctor only reads a running daemon (a process of its own is
    # not what this is about; tests/integration/test_daemon_up.py is).
    system = robot_system
    with system.robot_client() as robot:
        robot.wait_for("joints")
    code, out = doctor(
        "--json",
        "--connect",
        system.endpoint,
        "--robot",
        system.robot,
        "--port",
        "/nonexistent/tty",
    )
    assert code == 0, out
    checks = by_name(out)
    assert json.loads(out)["source"] == "daemon"
    assert checks["servos"]["status"] == "ok", checks["servos"]
    assert checks["servos"]["detail"].startswith("20/20")
    assert checks["zenoh"]["status"] == "ok" and system.robot in checks["zenoh"]["detail"]
    assert checks["loop"]["status"] in ("ok", "warn") and "p99 work" in checks["loop"]["detail"]
