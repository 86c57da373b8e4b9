"""The daemon against a misbehaving bus: dropped and corrupt replies, a silent servo, a serial
port that vanishes, a second process on the same port; and the camera captured only while
watched."""

from __future__ import annotations

import contextlib
import math
import subprocess
from collections.abc import Iterator

import pytest

from clients.robot import Robot
from schemas.errors import CommandError
from schemas.messages import CameraFrame
from schemas.sim_control import SimControl
from tests.fixtures.emulator import wait_until
from tests.fixtures.system import EventLog, RunningSystem, darwin_command, start_system

HEAD_PAN = 19


@pytest.fixture(scope="module")
def faulty_system() -> Iterator[RunningSystem]:
    """One system for this module, its emulator dropping and corrupting 1 % of the replies."""
    with start_system(
        sim_args=["--drop=0.01", "--corrupt=0.01", "--seed=7"], camera="sim", gateway=False
    ) as system:
        yield system


@contextlib.contextmanager
def robot_events(robot: Robot) -> Iterator[EventLog]:
    """The robot's events, logged while the block runs."""
    events = EventLog()
    sub = robot.subscribe("events", events)
    try:
        yield events
    finally:
        sub.close()


@contextlib.contextmanager
def servo_fault(sim: SimControl, op: str, dxl_id: int, flag: str) -> Iterator[None]:
    """The emulator's servo ``dxl_id`` faulty (control op ``op`` with ``flag`` true) while the
    block runs, whatever the block raises."""
    sim.call(op, id=dxl_id, **{flag: True})
    try:
        yield
    finally:
        sim.call(op, id=dxl_id, **{flag: False})


def sim_goals(sim: SimControl) -> dict[str, float]:
    return {k: v["goal"] for k, v in sim.call("state")["servos"].items()}


def test_bad_replies_are_counted_and_no_unmeant_goal_is_written(
    faulty_system: RunningSystem,
) -> None:
    with faulty_system.robot_client(name="faults") as robot:
        sim = SimControl(robot.session, faulty_system.robot)
        status = robot.wait_for(
            "status",
            lambda s: s.bus["missing_replies"] > 0 and s.bus["corrupt_replies"] > 0,
            timeout=30,
        )
        assert status.bus["stale_ticks"] > 0
        before_ticks = status.loop["ticks"]
        goals_before = sim_goals(sim)
        with robot.control():
            target = 0.3 if abs(goals_before[str(HEAD_PAN)] - 0.3) > 0.1 else -0.3
            robot.joint("head_pan", target)
            robot.wait_for(
                "joints", lambda m: abs(m.position[HEAD_PAN - 1] - target) < 0.03, timeout=15
            )
        goals_after = sim_goals(sim)
        assert goals_after.pop(str(HEAD_PAN)) == pytest.approx(target, abs=0.002)
        goals_before.pop(str(HEAD_PAN))
        assert goals_after == goals_before  # nobody else's goal was touched
        status = robot.wait_for("status", lambda s: s.loop["ticks"] > before_ticks + 100)
        assert status.state in ("running", "degraded")


def test_a_silent_servo_goes_offline_and_comes_back(faulty_system: RunningSystem) -> None:
    with faulty_system.robot_client(name="silence") as robot, robot_events(robot) as events:
        sim = SimControl(robot.session, faulty_system.robot)
        with servo_fault(sim, "silence", 7, "silent"):
            status = robot.wait_for("status", lambda s: 7 in s.bus["offline"], timeout=15)
            assert status.state == "degraded"
            # Joints sampled after the status: on a loaded machine one published before it can
            # arrive after it (each topic has its own queue).
            j = robot.wait_for("joints", lambda m: m.stamp > status.stamp)
            assert j.online[6] is False
            with robot.control(), pytest.raises(CommandError) as info:
                robot.joint(7, 0.1)
            assert info.value.code == "unavailable" and info.value.field == "id"
        robot.wait_for("status", lambda s: 7 not in s.bus["offline"], timeout=15)
        events.wait(lambda e: e.kind == "servo_offline" and e.data.get("id") == 7)
        events.wait(lambda e: e.kind == "servo_online" and e.data.get("id") == 7)


def test_a_vanished_port_is_reopened(faulty_system: RunningSystem) -> None:
    with faulty_system.robot_client(name="unplug") as robot:
        sim = SimControl(robot.session, faulty_system.robot)
        sim.call("vanish")
        try:
            status = robot.wait_for("status", lambda s: s.state == "port_lost", timeout=15)
            assert status.bus["open"] is False
            # Commands get a clear answer while the port is gone; halt still works.
            robot.halt()
            with robot.control(), pytest.raises(CommandError) as info:
                robot.led(head=(0, 0, 255))
            assert "not open" in info.value.message or info.value.code == "unavailable"
        finally:
            sim.call("reappear")
        status = robot.wait_for("status", lambda s: s.state in ("running", "degraded"), timeout=30)
        assert status.bus["port_reopens"] >= 1
        robot.wait_for("joints", timeout=10)


def test_a_second_daemon_gets_port_in_use(faulty_system: RunningSystem) -> None:
    with faulty_system.robot_client() as robot:
        port = robot.wait_for("status", fresh=False).bus["port"]
    out = subprocess.run(
        darwin_command(
            "daemon",
            "--port",
            port,
            "--listen",
            "tcp/127.0.0.1:0",
            "--robot",
            "second",
        ),
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert out.returncode == 1
    assert "in use by PID" in out.stderr


def test_camera_is_captured_only_while_watched(faulty_system: RunningSystem) -> None:
    with faulty_system.robot_client(name="eyes") as robot:
        first = robot.wait_for("status", timeout=10)
        assert first.camera["source"] == "sim"
        # Nobody watches: several status periods pass without a single capture.
        for _ in range(5):
            status = robot.wait_for("status")
            assert status.camera["subscribed"] is False and status.camera["capturing"] is False
            assert status.camera["captured"] == first.camera["captured"]
        frames: list[CameraFrame] = []
        with robot.subscribe("camera", frames.append):
            frame = robot.wait_for("camera", timeout=15)
            assert frame.width == 320 and frame.height == 240
            assert frame.jpeg[:2] == b"\xff\xd8"  # a JPEG
            watched = robot.wait_for(
                "status", lambda s: s.camera["captured"] > first.camera["captured"], timeout=10
            )
            assert watched.camera["subscribed"] is True and watched.camera["capturing"] is True
        robot.wait_for("status", lambda s: not s.camera["subscribed"], timeout=10)
        # A frame already being rendered when the last subscriber left may still complete.
        stopped = robot.wait_for("status", lambda s: not s.camera["capturing"], timeout=10)
        for _ in range(5):
            status = robot.wait_for("status")
            assert status.camera["captured"] == stopped.camera["captured"]


def test_imu_is_published_in_si_units(faulty_system: RunningSystem) -> None:
    with faulty_system.robot_client() as robot:
        imu = robot.wait_for("imu", timeout=10)
        assert len(imu.gyro) == 3 and len(imu.accel_raw) == 3
        # Standing still: gravity on z, within the emulator's noise.
        assert math.isclose(imu.accel[2], 9.81, abs_tol=1.0)
        assert imu.fall == "none"


def test_an_overheating_servo_is_protected_and_reported(faulty_system: RunningSystem) -> None:
    with faulty_system.robot_client(name="thermal") as robot:
        sim = SimControl(robot.session, faulty_system.robot)
        with robot_events(robot) as events:
            with servo_fault(sim, "overheat", 5, "on"):
                robot.wait_for("status", lambda s: any(a["id"] == 5 for a in s.alarms), timeout=15)
                robot.wait_for("status", lambda s: 5 in s.bus["torque_off"], timeout=15)
                # The write went out on the bus; the emulator applies it as it arrives.
                wait_until(
                    lambda: sim.call("state")["servos"]["5"]["torque"] is False,
                    timeout=10,
                    what="servo 5's torque off in the emulator",
                )
            alarm = events.wait(lambda e: e.kind == "servo_alarm" and e.data["id"] == 5)
        assert "overheating" in alarm.data["alarms"] and "torque off" in alarm.message
        # Cooled in the emulator; the daemon refuses torque until its next read of the error
        # byte clears the alarm, as the refusal says (status.alarms).
        robot.wait_for("status", lambda s: all(a["id"] != 5 for a in s.alarms), timeout=15)
        with robot.control():  # torque back on only when someone asks
            robot.torque(True, [5])
        robot.wait_for("status", lambda s: 5 not in s.bus["torque_off"], timeout=15)
        # Re-armed (TORQUE_LIMIT back from the shutdown's 0) before the slow read reported the
        # 0: the servo holds, not TORQUE_ENABLE 1 on a limp motor.
        wait_until(
            lambda: sim.call("state")["servos"]["5"]["torque_limit"] > 0,
            timeout=10,
            what="servo 5's TORQUE_LIMIT re-armed in the emulator",
        )


def test_an_outage_halts_refuses_and_never_resumes(faulty_system: RunningSystem) -> None:
    with faulty_system.robot_client(name="outage") as robot:
        sim = SimControl(robot.session, faulty_system.robot)
        robot.wait_for("status", lambda s: s.state in ("running", "degraded"), timeout=30)
        with robot_events(robot) as events, robot.control():
            # The module's system is shared: an earlier test's alarm may have left a servo limp,
            # and a walk on a limp leg is refused, as it is while the [heat] policy's level of
            # an overheated servo stands (its hold time after cooling). Every servo torqued
            # first, once it answers so, and the heat level back to ok.
            def ready_to_walk() -> bool:
                with contextlib.suppress(CommandError):
                    robot.torque(True)
                status = robot.wait_for("status")
                return not status.bus["torque_off"] and status.heat.get("level") == "ok"

            wait_until(
                ready_to_walk, timeout=30, what="every servo torqued and cool before the walk"
            )
            robot.walk(x=0.05)
            events.wait(lambda e: e.kind == "walk" and e.data.get("state") == "started")
            sim.call("vanish")
            try:
                robot.wait_for("status", lambda s: s.state == "port_lost", timeout=15)
                # Every command that would move the robot is refused now, not run later.
                for verb, fields in (
                    ("walk", {"op": "set", "x": 0.05}),
                    ("joint", {"name": "head_pan", "position": 0.3}),
                    ("action", {"op": "play", "name": "stand"}),
                ):
                    with pytest.raises(CommandError) as info:
                        robot.command(verb, **fields)
                    assert info.value.code == "unavailable", (verb, info.value)
                    assert "port" in info.value.message
                robot.halt()  # halt, lease and config are still answered
                assert robot.command("config")["robot"] == faulty_system.robot
                lost = robot.wait_for("status", lambda s: s.state == "port_lost")
                assert lost.motion["walking"]["walking"] is False
            finally:
                sim.call("reappear")
            back = robot.wait_for(
                "status", lambda s: s.state in ("running", "degraded"), timeout=30
            )
            assert back.motion["walking"]["walking"] is False
            first = robot.wait_for("joints", timeout=10)
            # The robot holds the pose it is in: over a second of status, nothing moves.
            for _ in range(10):
                status = robot.wait_for("status")
                assert status.motion["walking"]["walking"] is False
                assert set(status.motion["owners"].values()) == {None}
            last = robot.wait_for("joints")
        moved = [abs(a - b) for a, b in zip(first.position, last.position, strict=True)]
        assert max(moved) < math.radians(2), moved
        assert not [
            e for e in events.items if e.kind == "walk" and e.data.get("state") == "started"
        ][1:], "walking started again after the outage"
