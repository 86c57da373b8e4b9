"""The first session's safety on the emulator (issue 25): a CM-730 that answers late starts no
get-up page, and the bulk read asks the CM-730 first once it answers."""

from __future__ import annotations

import pytest

from clients.robot import Robot
from schemas.errors import UnavailableError
from schemas.sim_control import SimControl
from tests.fixtures.system import start_system
from tests.integration.test_motion_system import Events

WAIT = 30.0


def test_a_cm730_that_answers_late_makes_no_fall_and_starts_no_page() -> None:
    # ~250 reads unanswered: the scan's, then 2 s of bulk reads with no CM-730 data at all.
    with (
        start_system(sim_args=["--cm730-late-reads=250"], gateway=False) as system,
        system.robot_client(name="late-cm730") as robot,
    ):
        status = robot.wait_for(
            "status",
            lambda s: s.bus["cm730_online"] and s.motion["imu"]["calibrated"],
            WAIT,
        )
        # A second of valid data after calibration: the fall monitor runs on it.
        tick = robot.wait_for("imu", timeout=WAIT).tick
        robot.wait_for("imu", lambda m: m.tick > tick + 125, WAIT)
        status = robot.wait_for("status", timeout=WAIT)
        assert status.motion["fall"]["falls"] == 0
        assert status.motion["fall"]["state"] == "upright"
        assert not status.motion["action"]["playing"]
        assert status.motion["imu"]["gyro_centre"][0] > 400  # measured on real readings


def test_the_reset_button_leaves_the_servos_off_until_asked_and_torque_returns_where_it_was(
) -> None:
    """The CM-730's reset button (DXL power off) is a stop: one event, the servos stay
    unpowered (``servos_off``) and commands that would drive them are refused until `power`
    op=on; then torque comes back only on the servos that had it, the limp arm stays limp."""
    with (
        start_system(gateway=False) as system,
        system.robot_client(name="power-loss") as robot,
    ):
        robot.wait_for("status", lambda s: s.state == "running", WAIT)
        sim = SimControl(robot.session, system.robot)
        events = Events(robot)
        try:
            with robot.control():
                robot.torque(False, [1, 3, 5])  # the right arm made limp
            robot.wait_for("status", lambda s: {1, 3, 5} <= set(s.bus["torque_off"]), WAIT)
            sim.call("dxl_power_loss")
            power = events.wait(lambda e: e.kind == "power")
            assert "DXL_POWER 0" in power.message
            assert "stay off until someone powers them" in power.message
            status = robot.wait_for("status", lambda s: s.state == "servos_off", WAIT)
            # Two seconds of ticks later nobody powered anything (it used to within 0.5 s).
            tick = status.loop["ticks"]
            robot.wait_for("status", lambda s: s.loop["ticks"] > tick + 250, WAIT)
            state = sim.call("state")
            assert not state["dxl_power"] and not state["servo_power"]
            assert [e.kind for e in events.seen].count("power") == 1
            assert not [e for e in events.seen if e.kind in ("port", "servo_offline")]
            with robot.control():
                with pytest.raises(UnavailableError, match="servos are off"):
                    robot.joint("head_pan", 0.2)
                done = robot.power(True)
                assert done["changed"] and 1 not in done["torque"]
            back = events.wait(lambda e: e.kind == "power" and "powered again" in e.message)
            assert set(back.data["torque"]) == set(range(1, 21)) - {1, 3, 5}, [
                e.message for e in events.seen
            ]
            robot.wait_for("status", lambda s: s.state == "running", WAIT)
            joints = robot.wait_for("joints", lambda j: all(j.online), WAIT)
            assert [i + 1 for i, on in enumerate(joints.torque_enabled) if not on] == [1, 3, 5]
            servos = sim.call("state")["servos"]
            assert [int(i) for i, s in servos.items() if not s["torque"]] == [1, 3, 5]
        finally:
            events.close()


def press(robot: Robot, sim: SimControl, name: str) -> None:
    """A press held until the daemon has read it (status.buttons), then released."""
    sim.call("button", name=name, pressed=True)
    robot.wait_for("status", lambda s: s.buttons.get(name), WAIT)
    sim.call("button", name=name, pressed=False)


def test_mode_stops_a_walk_and_start_powers_the_servos_after_the_reset_button() -> None:
    """The CM-730's buttons (``daemon.buttons``): MODE = safe stop and hold, START = power."""
    with (
        start_system(gateway=False) as system,
        system.robot_client(name="buttons") as robot,
    ):
        robot.wait_for("status", lambda s: s.state == "running", WAIT)
        sim = SimControl(robot.session, system.robot)
        events = Events(robot)
        try:
            robot.acquire()
            robot.walk(x=0.02)
            robot.wait_for("status", lambda s: s.motion.get("walking", {}).get("walking"), WAIT)
            press(robot, sim, "mode")
            mode = events.wait(lambda e: e.kind == "button")
            assert mode.data["button"] == "mode" and "stops safely" in mode.message
            robot.wait_for(
                "status", lambda s: not s.motion.get("walking", {}).get("walking"), WAIT
            )
            robot.release()
            sim.call("dxl_power_loss")
            robot.wait_for("status", lambda s: s.state == "servos_off", WAIT)
            press(robot, sim, "start")
            back = events.wait(lambda e: e.kind == "power" and "powered again" in e.message)
            assert back.data["by"] == "the START button"
            robot.wait_for("status", lambda s: s.state == "running", WAIT)
            assert sim.call("state")["servo_power"]
        finally:
            events.close()
