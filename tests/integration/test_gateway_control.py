"""Control through the gateway: the implicit lease, refusals that apply nothing, release on
disconnect and on idle, throttling that slows a client down without losing its messages."""

from __future__ import annotations

import math

from schemas import units
from tests.fixtures.system import RunningSystem
from tests.legacy_client import start_gateway


def goal_deg(robot, jid: int) -> float:
    j = robot.state.joints
    return math.degrees(j.goal[j.id.index(jid)])


def near(rad: float, deg: float) -> bool:
    return abs(rad - units.raw_to_rad(units.deg_to_raw(deg))) < 1e-3


def test_second_client_is_refused_until_the_first_goes(robot_system: RunningSystem) -> None:
    settings = {"lease_idle_timeout": 0.0}
    with (
        start_gateway(robot_system.endpoint, robot_system.robot, settings) as gw,
        robot_system.robot_client(name="observer") as robot,
    ):
        robot.wait_for("status", lambda s: s.lease is None, timeout=30.0, fresh=False)
        first = gw.client()
        second = gw.client()
        try:
            first.send({"operate": {"all": 0, "id": 1, "position": 10}})
            robot.wait_for("joints", lambda j: near(j.goal[j.id.index(1)], 10), 30.0)
            status = robot.wait_for("status", lambda s: s.lease is not None, 30.0, fresh=False)
            assert status.lease["name"].startswith("legacy 127.0.0.1:")

            # The second client's command is refused with the spec's error and not applied.
            second.send({"operate": {"all": 0, "id": 1, "position": -10}})
            err = second.recv_error()
            assert err["code"] == "busy" and "not applied" in err["message"], err
            # Monitoring works for everyone, lease or not.
            second.send({"monitor": {"motors": 1}})
            motors = second.recv_until(lambda m: "motors" in m.get("monitor", {}))
            pos = {m["motor"][0]: m["motor"][1] for m in motors["monitor"]["motors"]}
            assert 1 in pos
            assert near(robot.state.joints.goal[robot.state.joints.id.index(1)], 10)

            # The first disconnects: its token goes, the arbiter frees the lease.
            first.close()
            robot.wait_for("status", lambda s: s.lease is None, timeout=30.0, fresh=False)
            second.send({"operate": {"all": 0, "id": 1, "position": -10}})
            robot.wait_for("joints", lambda j: near(j.goal[j.id.index(1)], -10), 30.0)
        finally:
            first.close()
            second.close()


def test_idle_holder_releases_the_lease(robot_system: RunningSystem) -> None:
    with (
        start_gateway(robot_system.endpoint, robot_system.robot, {"lease_idle_timeout": 0.5}) as gw,
        robot_system.robot_client(name="observer") as robot,
    ):
        robot.wait_for("status", lambda s: s.lease is None, timeout=30.0, fresh=False)
        with gw.client() as c:
            c.send({"led": {"id": 27, "ledcolor": [0, 255, 0]}})
            robot.wait_for("status", lambda s: s.lease is not None, 30.0, fresh=False)
            # Still connected, but idle: the gateway gives the lease back.
            robot.wait_for("status", lambda s: s.lease is None, 30.0, fresh=False)
            gw.wait_line("lease released", 30.0)
            # The next command takes it again.
            c.send({"led": {"id": 27, "ledcolor": [0, 0, 255]}})
            robot.wait_for("status", lambda s: s.leds.get("eye") == [0, 0, 248], 30.0)


def test_out_of_range_for_the_robot_is_refused_and_nothing_moves(
    robot_system: RunningSystem,
) -> None:
    with (
        start_gateway(robot_system.endpoint, robot_system.robot) as gw,
        robot_system.robot_client(name="observer") as robot,
    ):
        robot.wait_for("status", lambda s: s.lease is None, timeout=30.0, fresh=False)
        with gw.client(order="little") as c:
            # Within the legacy range (−360..360) but outside joint 3's configured limits.
            c.send({"operate": {"all": 0, "id": 3, "position": 200}})
            err = c.recv_error()
            assert err["code"] == "out_of_range" and "operate" not in err["message"], err
            assert "joint" in err["message"]
            c.send({"operate": {"all": 1, "id": 1, "position": 359}})
            assert c.recv_error()["code"] == "out_of_range"
            # Neither value ever became a goal (other goals may move: a safe stop, a hold).
            c.send({"marker": 1})
            c.recv_error()
            joints = robot.wait_for("joints", timeout=30.0)
        assert not near(joints.goal[joints.id.index(3)], 200)
        assert not any(near(g, 359) for g in joints.goal)


def test_a_client_sending_too_fast_is_slowed_down_not_dropped(robot_system: RunningSystem) -> None:
    with start_gateway(
        robot_system.endpoint, robot_system.robot, {"max_rate": 50.0, "burst": 5}
    ) as gw:
        with gw.client() as c:
            for i in range(40):
                c.send({"nonsense": i})
            errors = [c.recv_error() for _ in range(40)]
        assert all(e["code"] == "unknown" for e in errors)
        gw.wait_line("sends faster than 50 messages/s", 30.0)
