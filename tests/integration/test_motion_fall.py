"""A fall in the simulated world stops the motion, is published, and the get-up page plays."""

from __future__ import annotations

from collections.abc import Callable

from schemas.messages import Event
from schemas.sim_control import SimControl
from tests.fixtures.system import RunningSystem
from tests.integration.test_motion_system import WAIT, Events


def _kind(kind: str, **data: object) -> Callable[[Event], bool]:
    return lambda e: e.kind == kind and all(e.data.get(k) == v for k, v in data.items())


def test_tipping_over_backward_is_detected_and_the_robot_gets_up(
    robot_system: RunningSystem,
) -> None:
    with robot_system.robot_client(name="fall-test") as robot:
        robot.wait_for("joints", timeout=WAIT)
        sim = SimControl(robot.session, robot_system.robot)
        robot.acquire()
        events = Events(robot)
        try:
            robot.action("stand")
            events.wait(_kind("action", page=1, state="finished"))
            # Pitch both feet 45° up against the body: standing on them tips the body back past
            # the world's tilt limit, and the accelerometer reads "fallen backward".
            robot.pose({"r_ankle_pitch": -0.8, "l_ankle_pitch": 0.8}, duration=0.5)
            fall = events.wait(_kind("fall", state="fallen_backward"))
            assert fall.data["recovering"] is True and fall.data["page"] == 11
            events.wait(_kind("action", page=11, state="started"))
            assert robot.wait_for("imu", lambda m: m.accel_raw[0] > 580, WAIT)
            status = robot.wait_for("status", lambda s: s.motion["fall"]["falls"] >= 1, WAIT)
            assert status.motion["fall"]["state"] == "fallen_backward"
            assert robot.wait_for("imu", lambda m: m.fall == "backward", WAIT)
            # One detector: the fall is one `fall` event, of the one documented shape.
            falls = [e for e in events.seen if e.kind == "fall"]
            fell = {"state": "fallen_backward", "direction": "backward", "recovering": True}
            assert [e.data for e in falls] == [{**fell, "page": 11}]
        finally:
            # Back on its feet for the other tests: the stand pose, then the world told so.
            robot.command("halt")
            events.close()
            events = Events(robot)
            robot.action("stand")
            events.wait(
                lambda e: (
                    e.kind == "action"
                    and e.data.get("page") == 1
                    and e.data.get("state") in ("finished", "interrupted", "halted")
                )
            )
            sim.call("place_robot", x=-1.0, y=0.0, yaw=0.0)
            robot.wait_for("status", lambda s: s.motion["fall"]["state"] == "upright", WAIT)
            robot.release()
            events.close()
