"""The first session's safety on the emulator (issue 25): a CM-730 that answers late starts no
get-up page, and the bulk read asks the CM-730 first once it answers."""

from __future__ import annotations

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


def test_dxl_power_loss_halts_reports_and_powers_scans_and_holds_again() -> None:
    with (
        start_system(gateway=False) as system,
        system.robot_client(name="power-loss") as robot,
    ):
        robot.wait_for("status", lambda s: s.state == "running", WAIT)
        sim = SimControl(robot.session, system.robot)
        events = Events(robot)
        try:
            sim.call("dxl_power_loss")
            fault = events.wait(lambda e: e.kind == "fault" and "DXL power" in e.message)
            assert "DXL_POWER 0" in fault.message and "powering them again" in fault.message
            events.wait(lambda e: e.kind == "port" and "back" in e.message)
            joints = robot.wait_for("joints", lambda j: all(j.torque_enabled), WAIT)
            assert all(joints.online)
            assert robot.wait_for("status", lambda s: s.state == "running", WAIT)
            state = sim.call("state")
            assert state["dxl_power"] and state["servo_power"]
        finally:
            events.close()
