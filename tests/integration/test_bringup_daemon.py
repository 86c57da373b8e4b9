"""The first session's safety on the emulator (issue 25): a CM-730 that answers late starts no
get-up page, and the bulk read asks the CM-730 first once it answers."""

from __future__ import annotations

from tests.fixtures.system import start_system

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
