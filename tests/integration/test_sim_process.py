"""``darwin sim`` as its own process: the port line, the stock SDK, control ops over Zenoh,
the port vanishing and coming back, and a clean exit on SIGTERM."""

from __future__ import annotations

import os
import signal
import termios
from pathlib import Path

import pytest
import serial
from dynamixel_sdk import COMM_RX_TIMEOUT, COMM_SUCCESS

from robot_daemon.bus.tables import CM730, CM730_ID, CM730_MODEL, MX28, MX28_MODEL, SERVO_IDS
from schemas.errors import CommandError, InvalidCommandError
from schemas.session import open_client
from schemas.sim_control import SimControl
from tests.fixtures.emulator import (
    SimProcess,
    open_sdk,
    start_emulator_process,
    stop_process,
    wait_until,
)
from tests.fixtures.system import run_darwin
from tests.integration.test_sim_sdk import sensor_bulk_read


@pytest.fixture
def control(emulator_process: SimProcess):
    with open_client(emulator_process.endpoint) as session:
        yield SimControl(session, emulator_process.robot)


def test_sdk_pings_and_bulk_reads_through_the_link(emulator_process: SimProcess) -> None:
    assert os.path.islink(emulator_process.port)
    port, ph = open_sdk(emulator_process.port)
    try:
        assert ph.ping(port, CM730_ID)[:2] == (CM730_MODEL, COMM_SUCCESS)
        assert all(ph.ping(port, i)[:2] == (MX28_MODEL, COMM_SUCCESS) for i in SERVO_IDS)
        assert sensor_bulk_read(port, ph).txRxPacket() == COMM_SUCCESS
    finally:
        port.closePort()


def test_control_ops_inject_faults_and_report_state(
    emulator_process: SimProcess, control: SimControl
) -> None:
    port, ph = open_sdk(emulator_process.port)
    try:
        assert control.call("faults", silent_ids=[5])["silent_ids"] == [5]
        assert ph.ping(port, 5)[1] == COMM_RX_TIMEOUT
        control.call("clear_faults")
        assert ph.ping(port, 5)[1] == COMM_SUCCESS

        control.call("button", name="mode")
        assert ph.read1ByteTxRx(port, CM730_ID, CM730.BUTTON.reg.address)[0] == 1
        control.call("voltage", volts=11.1)
        assert ph.read1ByteTxRx(port, CM730_ID, CM730.VOLTAGE.reg.address)[0] == 111

        ph.write1ByteTxRx(port, 3, MX28.TORQUE_ENABLE.reg.address, 1)
        state = control.call("state")
        assert state["dxl_power"] is True and state["servos"]["3"]["torque"] is True
        assert state["stats"]["frames"] > 0
    finally:
        port.closePort()


def test_bad_control_requests_get_errors_naming_the_field(control: SimControl) -> None:
    with pytest.raises(InvalidCommandError) as err:
        control.call("faults", drop=1.5)
    assert "drop" in str(err.value)
    with pytest.raises(InvalidCommandError) as err:
        control.call("overheat", id="seven")
    assert err.value.field == "id"
    with pytest.raises(InvalidCommandError) as err:
        control.call("silence", id=99)
    assert "99" in err.value.message
    with pytest.raises(CommandError) as err:
        control.call("no_such_op")
    assert err.value.code == "unknown" and "faults" in err.value.message


def test_the_port_vanishes_and_comes_back_at_the_same_path(
    emulator_process: SimProcess, control: SimControl
) -> None:
    path = emulator_process.port
    port, ph = open_sdk(path)
    assert ph.ping(port, 1)[1] == COMM_SUCCESS
    control.call("vanish")
    assert not os.path.lexists(path)
    # As when a USB adapter is pulled: the serial layer fails (pyserial, termios), not the SDK.
    with pytest.raises((OSError, termios.error, serial.SerialException)):
        ph.ping(port, 1)
    port.closePort()
    assert control.call("reappear")["port"] == path
    port, ph = open_sdk(path)  # the same path, a new pty: power was kept by the CM-730
    try:
        assert ph.ping(port, 1)[1] == COMM_SUCCESS
    finally:
        port.closePort()


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT])
def test_a_signal_exits_zero_and_removes_the_link(tmp_path: Path, signum: int) -> None:
    with start_emulator_process("--no-wire-timing", link_dir=tmp_path, control=False) as sim:
        assert os.path.islink(sim.port)
        sim.proc.send_signal(signum)
        assert sim.proc.wait(10) == 0
        assert not os.path.lexists(sim.port)
    assert stop_process(sim.proc) == 0


def test_bad_options_are_refused_with_a_clear_message(tmp_path: Path) -> None:
    out = run_darwin("sim", "--drop", "2", "--link", str(tmp_path / "x"))
    assert out.returncode == 2
    assert "probability 2.0 is outside 0..1" in out.stderr
    out = run_darwin("sim", "--overheat", "33", "--link", str(tmp_path / "x"))
    assert out.returncode == 2
    assert "no servo with ID 33" in out.stderr
    assert wait_until(lambda: not (tmp_path / "x").exists(), timeout=1)


def test_faults_from_the_command_line(tmp_path: Path) -> None:
    args = ("--no-wire-timing", "--power-on-delay", "0", "--silent-ids", "7,8", "--overheat", "9")
    with start_emulator_process(*args, link_dir=tmp_path, control=False) as sim:
        port, ph = open_sdk(sim.port)
        try:
            assert ph.ping(port, 7)[1] == COMM_RX_TIMEOUT
            assert ph.ping(port, 8)[1] == COMM_RX_TIMEOUT
            assert ph.ping(port, 9)[2] & 0x04  # overheating
            assert ph.ping(port, 10)[1:] == (COMM_SUCCESS, 0)
        finally:
            port.closePort()
