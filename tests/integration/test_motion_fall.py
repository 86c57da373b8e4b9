"""A fall in the simulated world stops the motion and is published; a get-up page plays by
itself only inside a lease holder's walk, ball play, behaviour or policy (the motion-authority
rule, robot_daemon/motion_authority.py): knocked over with nobody in control, or by a client's
own pose, the robot lies still and the fall event says why."""

from __future__ import annotations

from collections.abc import Callable

from clients.robot import Robot
from schemas.messages import Event
from schemas.sim_control import SimControl
from tests.fixtures.system import RunningSystem
from tests.integration.test_motion_system import WAIT, Events

KNOCK = {"fx": 20.0, "fy": 0.0, "duration": 0.1}  # 2 N·s: over the kinematic world's limit


def _kind(kind: str, **data: object) -> Callable[[Event], bool]:
    return lambda e: e.kind == kind and all(e.data.get(k) == v for k, v in data.items())


def _stand_up_again(robot: Robot, sim: SimControl) -> None:
    """Back on its feet for the other tests: the stand pose, then the world told so."""
    robot.command("halt")
    events = Events(robot)
    try:
        robot.action("stand")
        events.wait(
            lambda e: (
                e.kind == "action"
                and e.data.get("page") == 1
                and e.data.get("state") in ("finished", "interrupted", "halted")
            )
        )
    finally:
        events.close()
    sim.call("place_robot", x=-1.0, y=0.0, yaw=0.0)
    robot.wait_for("status", lambda s: s.motion["fall"]["state"] == "upright", WAIT)


def test_tipped_over_by_its_own_pose_the_robot_lies_still_until_asked_to_get_up(
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
            fell = {"state": "fallen_backward", "direction": "backward", "recovering": False}
            assert fall.data == {**fell, "page": None}
            assert "not getting up: no walk, ball play, behaviour or policy loop" in fall.message
            assert "play page 11" in fall.message
            status = robot.wait_for("status", lambda s: s.motion["fall"]["falls"] >= 1, WAIT)
            assert not status.motion["action"]["playing"]
            assert robot.wait_for("imu", lambda m: m.fall == "backward", WAIT)
            # Asked, it gets up.
            robot.action(11)
            events.wait(_kind("action", page=11, state="started"))
            assert [e for e in events.seen if e.kind == "fall"] == [fall]  # one fall, one event
        finally:
            _stand_up_again(robot, sim)
            robot.release()
            events.close()


def test_knocked_over_with_nobody_in_control_it_lies_still_and_inside_a_walk_it_gets_up(
    robot_system: RunningSystem,
) -> None:
    with robot_system.robot_client(name="fall-test") as robot:
        robot.wait_for("joints", timeout=WAIT)
        sim = SimControl(robot.session, robot_system.robot)
        events = Events(robot)
        try:
            robot.wait_for("status", lambda s: s.lease is None, WAIT)
            sim.call("push", **KNOCK)
            fall = events.wait(_kind("fall", direction="forward"))
            assert fall.data["recovering"] is False and fall.data["page"] is None
            assert "not getting up: nobody holds the lease" in fall.message
            status = robot.wait_for("status", lambda s: s.motion["fall"]["falls"] >= 1, WAIT)
            assert not status.motion["action"]["playing"]
            robot.acquire()
            _stand_up_again(robot, sim)
            # Walking in place, the holder's motion: knocked over, it gets up by itself.
            events.close()
            events = Events(robot)
            robot.walk(0.0)
            events.wait(_kind("walk", state="started"))
            sim.call("push", **KNOCK)
            fall = events.wait(_kind("fall", direction="forward"))
            assert fall.data["recovering"] is True and fall.data["page"] == 10
            events.wait(_kind("action", page=10, state="started"))
        finally:
            if not robot.holds_lease:
                robot.acquire()
            _stand_up_again(robot, sim)
            robot.release()
            events.close()
