"""Nothing moves unless someone asked (issue 35), on the emulator through a real pty:

* another master polling the bus (ROBOTIS's demo, as root: invisible in /proc to a daemon that
  is not root) is heard before the daemon says anything, and refused in one line; one that
  opens the port while the daemon runs halts the motion;

* a servo in alarm shutdown (TORQUE_LIMIT 0, as the MX-28 does) survives a daemon restart
  without being re-armed, is reported, and `torque` refuses it however often it is asked;
* a servo found holding a far goal (a previous program's, crept towards at a slow speed) holds
  where it is instead of rushing there when the RAM reset lifts the speed.
"""

from __future__ import annotations

import contextlib
import math
import os
import subprocess
import sys
import threading
import uuid
from collections.abc import Iterator
from pathlib import Path

import pytest

from clients.robot import Robot
from robot_daemon.bus.tables import MX28
from schemas import units
from schemas.errors import CommandError
from schemas.session import free_tcp_port, open_client
from schemas.sim_control import SimControl
from tests.fixtures.emulator import (
    darwin_command,
    open_sdk,
    start_emulator_process,
    stop_process,
    wait_until,
)
from tests.integration.test_motion_system import Events

WAIT = 30.0
SIM = ("--no-wire-timing", "--power-on-delay", "0")
KNEE = 13  # r_knee: a leg servo that shuts down on overload
PAN = 19  # head_pan: a servo left creeping towards a far goal
WHEEL = 7  # r_hip_pitch: left in wheel mode (angle limits 0/0)
NARROW = 8  # l_hip_pitch: its own angle limits narrower than the joint's range
TILT = 20  # head_tilt: torque turned on by a raw register write
GREEN = units.rgb_to_color_word(0, 255, 0)


@contextlib.contextmanager
def daemon(tmp_path: Path, port: str, *extra: str) -> Iterator[Robot]:
    """``darwin daemon`` on ``port`` (and ``extra`` options) with a client connected once it
    listens."""
    name = f"pw{uuid.uuid4().hex[:8]}"
    endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
    log_path = tmp_path / f"daemon-{name}.log"
    with log_path.open("w") as log:
        proc = subprocess.Popen(
            darwin_command(
                "daemon", "--port", port, "--robot", name, "--camera", "none", "--listen", endpoint,
                *extra,
            ),
            stdout=subprocess.PIPE,
            stderr=log,
            text=True,
        )
    try:
        assert proc.stdout is not None
        line = ""
        while not line.startswith("zenoh: "):
            line = proc.stdout.readline()
            assert line, log_path.read_text()
        with Robot(endpoint, name, name="power test", timeout=10.0) as robot:
            yield robot
    finally:
        stop_process(proc)


def test_an_alarmed_servo_survives_a_restart_without_re_arming_and_a_far_goal_is_not_chased(
    tmp_path: Path,
) -> None:
    with (
        start_emulator_process(*SIM, link_dir=tmp_path) as sim,
        open_client(sim.endpoint) as session,
    ):
        control = SimControl(session, sim.robot)
        # What a previous program left, DXL power on: the knee torqued and overloaded (the
        # MX-28 shuts down: TORQUE_LIMIT 0), the head pan torqued at 0.114 rpm towards a goal
        # 90° away.
        port, ph = open_sdk(sim.port)
        try:
            for dxl_id in (KNEE, PAN):
                ph.write1ByteTxRx(port, dxl_id, MX28.TORQUE_ENABLE.reg.address, 1)
            ph.write2ByteTxRx(port, PAN, MX28.MOVING_SPEED.reg.address, 1)
            start_raw = ph.read2ByteTxRx(port, PAN, MX28.PRESENT_POSITION.reg.address)[0]
            ph.write2ByteTxRx(port, PAN, MX28.GOAL_POSITION.reg.address, start_raw + 1024)
            for dxl_id, cw, ccw in ((WHEEL, 0, 0), (NARROW, 1900, 2200)):
                ph.write2ByteTxRx(port, dxl_id, MX28.CW_ANGLE_LIMIT.reg.address, cw)
                ph.write2ByteTxRx(port, dxl_id, MX28.CCW_ANGLE_LIMIT.reg.address, ccw)
        finally:
            port.closePort()
        control.call("load", id=KNEE, fraction=1.0)
        wait_until(
            lambda: control.call("state")["servos"][str(KNEE)]["torque_limit"] == 0,
            timeout=WAIT,
            what="the knee's overload shutdown in the emulator",
        )
        start = control.call("state")["servos"][str(PAN)]["position"]

        with daemon(tmp_path, sim.port) as robot:
            events = Events(robot)
            try:
                status = robot.wait_for(
                    "status", lambda s: s.state in ("running", "degraded"), WAIT
                )
                assert any(a["id"] == KNEE for a in status.alarms)
                assert KNEE in status.bus["torque_off"]
                warnings = status.bus["warnings"]
                assert any(f"servo {KNEE} " in w and "alarm shutdown" in w for w in warnings)
                # The scan reads the servos' own angle limits: wheel mode refused, narrowed said.
                assert WHEEL in status.bus["offline"]
                assert any(f"servo {WHEEL} " in w and "wheel mode" in w for w in warnings)
                assert any(
                    f"servo {NARROW} " in w and "limits its own angle" in w for w in warnings
                )
                # A flood of `torque` on the knee re-arms nothing.
                with robot.control():
                    for _ in range(20):
                        with pytest.raises(CommandError) as err:
                            robot.torque(True, [KNEE])
                    assert "alarm" in str(err.value) and "not enabled" in str(err.value)
                    tick = robot.wait_for("status", timeout=WAIT).loop["ticks"]
                    robot.wait_for("status", lambda s: s.loop["ticks"] > tick + 125, WAIT)
                state = control.call("state")["servos"]
                assert state[str(KNEE)]["torque_limit"] == 0
                assert KNEE in robot.wait_for("status", timeout=WAIT).bus["torque_off"]
                # The head pan holds where it was found, torque on: it crept (0.7 °/s) until
                # the daemon started, but never rushed on towards the goal 90° away.
                pan = state[str(PAN)]
                assert pan["torque"]
                assert abs(pan["goal"] - pan["position"]) < math.radians(1.0)
                assert abs(pan["position"] - start) < math.radians(30.0)
                # Torque on by a raw register write holds where the joint is (goal = present
                # first), not at whatever goal it had before it was pushed.
                with robot.control():
                    robot.torque(False, [TILT])
                    # The write went out on the pty; the emulator applies it as it arrives (a
                    # push over the control link before that would be fought by the motor).
                    wait_until(
                        lambda: not control.call("state")["servos"][str(TILT)]["torque"],
                        timeout=WAIT,
                        what="the head tilt's torque off in the emulator",
                    )
                    moved = state[str(TILT)]["position"] + 0.3
                    control.call("set_position", id=TILT, rad=moved)
                    robot.registers(TILT, MX28.TORQUE_ENABLE.reg.address, data=[1])
                tilt = control.call("state")["servos"][str(TILT)]
                assert tilt["torque"] and abs(tilt["goal"] - moved) < math.radians(1.0)
            finally:
                events.close()
        # The daemon gone, the head LED is green (ROBOTIS's CM730::Disconnect), not orange.
        assert control.call("state")["leds"]["head"] == GREEN


PING_CM730 = bytes((0xFF, 0xFF, 200, 0x02, 0x01, (~(200 + 0x02 + 0x01)) & 0xFF))


def test_a_second_master_polling_the_bus_is_refused_before_the_daemon_talks(
    tmp_path: Path,
) -> None:
    blind = tmp_path / "proc"  # what a daemon that is not root sees of a root demo: nothing
    blind.mkdir()
    with start_emulator_process(*SIM, link_dir=tmp_path) as sim:
        port, _ph = open_sdk(sim.port, power=False)
        stop = threading.Event()

        sent = []

        def poll() -> None:  # the demo's 8 ms traffic; its replies are left to whoever reads
            while not stop.wait(0.004):
                sent.append(port.writePort(PING_CM730))

        poller = threading.Thread(target=poll, daemon=True)
        poller.start()
        try:
            done = subprocess.run(
                darwin_command(
                    "daemon",
                    "--port",
                    sim.port,
                    "--robot",
                    "second-master",
                    "--camera",
                    "none",
                    "--listen",
                    f"tcp/127.0.0.1:{free_tcp_port()}",
                ),
                capture_output=True,
                text=True,
                timeout=60,
                env={**os.environ, "DARWIN_PROC_ROOT": str(blind)},
            )
        except subprocess.TimeoutExpired as exc:
            raise AssertionError(
                f"the daemon ran on ({len(sent)} pings sent): {exc.stderr!r}"
            ) from None
        finally:
            stop.set()
            poller.join()
            port.closePort()
    assert done.returncode == 1, done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "arrived on" in lines[0], done.stderr
    assert "/etc/rc.local" in lines[0] and "ROBOTIS's demo" in lines[0]


@pytest.mark.skipif(os.geteuid() != 0, reason="opening a TIOCEXCL tty twice needs root")
def test_a_process_that_opens_the_port_while_the_daemon_runs_halts_the_motion(
    tmp_path: Path,
) -> None:
    with (
        start_emulator_process(*SIM, link_dir=tmp_path) as sim,
        daemon(tmp_path, sim.port) as robot,
    ):
        events = Events(robot)
        try:
            robot.wait_for("status", lambda s: s.state in ("running", "degraded"), WAIT)
            fd = os.open(sim.port, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
            try:
                fault = events.wait(lambda e: e.kind == "fault" and "PID" in e.message)
                assert fault.data["pid"] == os.getpid()
                assert "/etc/rc.local" in fault.message
                with robot.control(), pytest.raises(CommandError, match="holds"):
                    robot.joint("head_pan", 0.1)
            finally:
                os.close(fd)
        finally:
            events.close()
        assert sys.platform.startswith("linux")
