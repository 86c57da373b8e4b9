"""The ROS 2 adapter's ROS-side session logs in where the ROS router requires it (a real Zenoh
router with user/password logins stands in for an rmw_zenohd with authentication), and behind
`darwin up --auth` the ROS key space follows the roles: observers watch, operators call."""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path

import pytest
import zenoh

pytest.importorskip("rosbags")

from schemas.session import Credentials, free_tcp_port, open_client, server_config
from tests.fixtures.system import RunningSystem, start_system
from tests.integration.test_auth import PASSWORDS, make_users
from tests.integration.test_ros2 import Adapter, adapter
from tests.ros2_observer import STORE, RmwObserver

ROS_USER, ROS_PASSWORD = "rosuser", "ros-password-1"


@pytest.fixture(scope="module")
def ros_router(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[str, Path]]:
    directory = tmp_path_factory.mktemp("ros-auth")
    dictionary = directory / "dictionary"
    dictionary.write_text(f"{ROS_USER}:{ROS_PASSWORD}\n")
    (directory / "ros.pw").write_text(ROS_PASSWORD + "\n")
    (directory / "wrong.pw").write_text("not-the-password\n")
    endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
    conf = server_config([endpoint], mode="router")
    conf.insert_json5("transport/auth/usrpwd/dictionary_file", json.dumps(str(dictionary)))
    with zenoh.open(conf):
        yield endpoint, directory


def test_the_ros_side_logs_in_to_a_router_that_requires_it(
    robot_system: RunningSystem, ros_router: tuple[str, Path]
) -> None:
    endpoint, directory = ros_router
    with (
        adapter("--connect", robot_system.endpoint, "--robot", robot_system.robot,
                "--router", endpoint, "--ros-user", ROS_USER,
                "--ros-password-file", str(directory / "ros.pw")),
        open_client(endpoint, creds=Credentials(ROS_USER, ROS_PASSWORD)) as ros,
    ):
        obs = RmwObserver(ros, domain=0)
        topic = f"/{robot_system.robot}/joint_states"
        obs.wait_for(lambda g: any(e.get("topic") == topic for e in g.values()))
        got, cond, close = obs.subscribe(topic, "sensor_msgs/msg/JointState")
        with cond:
            assert cond.wait_for(lambda: len(got) >= 3, 20.0)
        close()


def test_a_refused_ros_login_is_one_line_naming_it(
    robot_system: RunningSystem, ros_router: tuple[str, Path]
) -> None:
    endpoint, directory = ros_router
    for login in ([], ["--ros-user", ROS_USER, "--ros-password-file", str(directory / "wrong.pw")]):
        a = Adapter("--connect", robot_system.endpoint, "--robot", robot_system.robot,
                    "--router", endpoint, *login)
        try:
            assert a.proc.wait(timeout=60) == 1
        finally:
            a.stop()
        errors = [x for x in a.lines if x.startswith("darwin ros2:")]
        assert len(errors) == 1 and "Traceback" not in "\n".join(a.lines), a.lines
        assert f"cannot open the ROS session at {endpoint}" in errors[0]
        assert (f"as {ROS_USER}: check the user" if login else "pass --ros-user") in errors[0]


def test_behind_up_auth_ros_observers_watch_and_only_operators_call_services(
    tmp_path: Path,
) -> None:
    users = make_users(tmp_path)
    with start_system(extra_args=["--auth", str(users), "--ros2"], gateway=False) as system:
        system.wait_line(lambda x: x.startswith("ros2: "))
        ns = f"/{system.robot}"
        trigger = STORE.types["std_srvs/msg/Trigger_Request"](structure_needs_at_least_one_member=0)
        with open_client(system.endpoint, creds=Credentials("obs", PASSWORDS["obs"])) as ros:
            obs = RmwObserver(ros, domain=0)
            try:
                obs.wait_for(lambda g: any(e.get("topic") == f"{ns}/joint_states"
                                           for e in g.values()))
                got, cond, close = obs.subscribe(f"{ns}/joint_states", "sensor_msgs/msg/JointState")
                with cond:
                    assert cond.wait_for(lambda: len(got) >= 3, 20.0)
                close()
                # A service call is a command: access control drops an observer's.
                with pytest.raises(AssertionError, match="no reply"):
                    obs.call(f"{ns}/halt", "std_srvs/srv/Trigger", trigger)
            finally:
                obs.close()
        with open_client(system.endpoint, creds=Credentials("op", PASSWORDS["op"])) as ros:
            obs = RmwObserver(ros, domain=0, name="operator")
            try:
                obs.wait_for(lambda g: any(e.get("topic") == f"{ns}/halt" for e in g.values()))
                reply, *_ = obs.call(f"{ns}/halt", "std_srvs/srv/Trigger", trigger)
                assert reply.success
            finally:
                obs.close()
