"""`darwin up --foxglove` spoken to as a Foxglove client would: advertised channels, joints and
transforms that match the project's FK, the camera only while subscribed, halt, and a Teleop
walk through the lease."""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from config.loader import load_robot
from schemas import kinematics as K
from schemas.messages import Status
from schemas.session import free_tcp_port
from tests.fixtures.system import RunningSystem, start_system
from tests.foxglove_ws import WAIT, FoxgloveClient
from tests.transforms import tf_poses

pytestmark = pytest.mark.timeout(240)
LAYOUT = Path(__file__).resolve().parents[2] / "clients" / "foxglove" / "layout.json"


def address(system: RunningSystem, name: str) -> str:
    """The ``name: address`` line `darwin up` prints (after the lines the fixture waits for)."""
    line = system.wait_line(lambda line: line.startswith(f"{name}: "))
    return line.split(" ", 1)[1].strip()


@pytest.fixture(scope="module")
def fox() -> Iterator[tuple[RunningSystem, str]]:
    listen = f"127.0.0.1:{free_tcp_port()}"
    with start_system(
        camera="sim", gateway=False, extra_args=["--foxglove", "--foxglove-listen", listen]
    ) as system:
        url = address(system, "foxglove")
        assert url == f"ws://{listen}"
        yield system, url


def test_channels_are_advertised_with_foxglove_schemas(fox: tuple[RunningSystem, str]) -> None:
    _, url = fox
    with FoxgloveClient.open(url) as fc:
        assert fc.ws.subprotocol == "foxglove.sdk.v1"
        assert {"services", "parameters", "clientPublish"} <= set(fc.server_info["capabilities"])
        schemas = {ch["topic"]: (ch["encoding"], ch["schemaName"]) for ch in fc.channels.values()}
        assert schemas["/tf"] == ("protobuf", "foxglove.FrameTransforms")
        assert schemas["/camera/image"] == ("protobuf", "foxglove.CompressedImage")
        assert schemas["/camera/ball"] == ("protobuf", "foxglove.ImageAnnotations")
        assert schemas["/events"] == ("protobuf", "foxglove.Log")
        for topic in ("/joints", "/imu", "/status", "/loop", "/world"):
            assert schemas[topic][0] == "json", topic
        assert {"/halt", "/lease", "/action", "/behaviour", "/torque"} <= set(fc.services)
        assert "/robot_description" in schemas
        # The shipped layout names only channels this server advertises (and /cmd_vel, which
        # the Teleop panel publishes), and joint plot paths name real joints.
        joint_names = set(load_robot().names)
        for topic, path in layout_paths():
            assert topic in schemas or topic in {"/cmd_vel", "/robot_description"}, topic
            if topic == "/joints":
                assert path.split(".")[2] in joint_names, path


def test_joints_and_transforms_match_the_kinematics(fox: tuple[RunningSystem, str]) -> None:
    _, url = fox
    with FoxgloveClient.open(url) as fc:
        fc.subscribe("/joints", "/tf", "/imu", "/status", "/loop")
        joints = fc.take("/joints")
        assert len(joints["id"]) == 20
        for column in ("position", "goal", "velocity", "load", "temperature", "voltage"):
            assert len(joints[column]) == 20
        assert set(joints["by_name"][joints["name"][0]]) >= {"position", "goal", "load"}
        assert "gyro" in fc.take("/imu") and "state" in fc.take("/status")
        # What the layout's battery and heat plot reads (docs/power.md).
        status = fc.take("/status", lambda m: bool(m.get("heat", {}).get("hottest")))
        assert status["power"]["volts"] > 0 and status["heat"]["hottest"][0]["celsius"] > 0
        assert "p50" in str(fc.take("/loop")) or fc.take("/loop")
        # A /tf message carries the stamp of the joints it was computed from.
        seen: dict[int, dict] = {}
        while True:
            tf = fc.take("/tf", lambda m: len(m.transforms) > 3)
            stamp = tf.transforms[0].timestamp
            ns = stamp.seconds * 1_000_000_000 + stamp.nanos
            while len(seen) < 500:
                rec = next((r for r in fc.pending if r.topic == "/joints"), None)
                if rec is None:
                    break
                fc.pending.remove(rec)
                j = fc.decode(rec)
                seen[round(j["stamp"] * 1e9)] = j
            match = next((j for t, j in seen.items() if abs(t - ns) < 1000), None)
            if match is not None:
                break
        pos = {i: p for i, p in zip(match["id"], match["position"], strict=True)}
        poses = tf_poses(tf.transforms)
        expect = {
            "r_sole": K.leg_fk(pos, "right"),
            "l_sole": K.leg_fk(pos, "left"),
            "camera": K.camera_pose(pos),
            "head": K.head_pose(pos),
        }
        for frame, pose in expect.items():
            assert np.allclose(poses[frame], pose, atol=1e-9), frame
        hand = K.arm_chain(pos, "right")[2]
        assert np.allclose(poses["r_hand"][:3, 3], hand, atol=1e-9)


def layout_paths() -> list[tuple[str, str]]:
    """(topic, path) of every topic or message path the shipped layout refers to."""
    layout = json.loads(LAYOUT.read_text())
    found: list[tuple[str, str]] = []

    def walk(value: object) -> None:
        if isinstance(value, dict):
            for k, v in value.items():
                if k == "publish":
                    continue  # the 3D panel's click-to-publish defaults, unused here
                if isinstance(k, str) and k.startswith("/"):
                    found.append((k, k))
                walk(v)
        elif isinstance(value, list):
            for v in value:
                walk(v)
        elif isinstance(value, str) and value.startswith("/") and " " not in value:
            found.append(("/" + value[1:].split(".")[0].split("[")[0], value))

    walk(layout["configById"])
    return found


def test_world_pose_places_the_robot_and_the_ball(fox: tuple[RunningSystem, str]) -> None:
    _, url = fox
    with FoxgloveClient.open(url) as fc:
        fc.subscribe("/tf", "/world")
        world = fc.take("/world", lambda m: bool(m.get("ball")))
        tf = fc.take("/tf", lambda m: any(t.child_frame_id == "ball" for t in m.transforms))
        ball = next(t for t in tf.transforms if t.child_frame_id == "ball")
        assert ball.parent_frame_id == "field"
        assert abs(ball.translation.x - world["ball"]["x"]) < 0.5  # the ball rolls meanwhile
        base = next(t for t in tf.transforms if t.child_frame_id == "base_link")
        assert base.parent_frame_id == "field" and base.translation.z > 0.2


def camera_subscribed(robot_status: Status) -> bool:
    return bool(robot_status.camera.get("subscribed"))


def test_camera_only_while_a_client_subscribes(fox: tuple[RunningSystem, str]) -> None:
    system, url = fox
    with system.robot_client(name="watcher") as robot, FoxgloveClient.open(url) as fc:
        robot.wait_for("status", lambda s: not camera_subscribed(s), WAIT, fresh=False)
        before = robot.wait_for("status", lambda s: True, WAIT).camera["captured"]
        sub = fc.subscribe("/camera/image")
        robot.wait_for("status", camera_subscribed, WAIT)
        img = fc.take("/camera/image")
        assert img.format == "jpeg" and bytes(img.data[:2]) == b"\xff\xd8"
        assert robot.wait_for("status", lambda s: True, WAIT).camera["captured"] > before
        fc.unsubscribe(sub)
        # The server drops its camera subscription with the last Foxglove subscriber, and the
        # daemon stops capturing.
        robot.wait_for("status", lambda s: not camera_subscribed(s), WAIT)
        fc.drop("/camera/image")
        # A frame being rendered as the viewer left still completes: then capture stops.
        idle = robot.wait_for("status", lambda s: not s.camera["capturing"], WAIT, fresh=False)
        for _ in range(3):
            later = robot.wait_for("status", lambda s: True, WAIT)
            assert later.camera["captured"] == idle.camera["captured"]
            assert not camera_subscribed(later) and not later.camera["capturing"]


def test_halt_and_a_teleop_walk_through_the_lease(fox: tuple[RunningSystem, str]) -> None:
    system, url = fox
    with system.robot_client(name="watcher") as robot, FoxgloveClient.open(url) as fc:
        fc.subscribe("/status")  # a client that watches something, as Foxglove always does
        assert fc.call("/halt", {}, 1)[0] == "ok"
        fc.advertise(7, "/cmd_vel", "geometry_msgs/Twist")
        twist = {"linear": {"x": 0.05, "y": 0.0, "z": 0.0}, "angular": {"x": 0, "y": 0, "z": 0}}
        # Without the lease the arbiter refuses the walk and the client is told why.
        fc.publish(7, twist)
        fc.status_matching("teleop:")
        kind, reply = fc.call("/lease", {"op": "acquire"}, 2)
        assert kind == "ok", reply
        assert robot.wait_for("status", lambda s: s.lease is not None, WAIT).lease["name"] \
            .startswith("foxglove-")
        fc.publish(7, twist)
        robot.wait_for("status", lambda s: s.motion.get("walking", {}).get("walking"), WAIT)
        # Silence: the server stops the walk by itself.
        robot.wait_for("status", lambda s: not s.motion.get("walking", {}).get("walking"), WAIT)
        # An explicit zero stops too.
        fc.publish(7, twist)
        robot.wait_for("status", lambda s: s.motion.get("walking", {}).get("walking"), WAIT)
        fc.publish(7, {"linear": {"x": 0}, "angular": {"z": 0}})
        robot.wait_for("status", lambda s: not s.motion.get("walking", {}).get("walking"), WAIT)
        assert fc.call("/lease", {"op": "release"}, 3)[0] == "ok"
        robot.wait_for("status", lambda s: s.lease is None, WAIT)


def test_walking_parameters_read_and_written_with_the_lease(
    fox: tuple[RunningSystem, str],
) -> None:
    system, url = fox
    with system.robot_client(name="watcher") as robot, FoxgloveClient.open(url) as fc:
        fc.subscribe("/status")
        params = {p["name"]: p for p in fc.get_parameters([], "all")}
        assert "walk/period_time" in params and "walk/balance_enable" in params
        old = params["walk/foot_height"]["value"]
        # Without the lease: refused, the old value stays.
        reply = fc.set_parameters([{"name": "walk/foot_height", "value": old + 5}], "w1")
        assert reply[0]["value"] == old
        fc.status_matching("walking parameters not changed")
        assert fc.call("/lease", {"op": "acquire"}, 10)[0] == "ok"
        reply = fc.set_parameters(
            [{"name": "walk/foot_height", "value": old + 5, "type": "float64"}], "w2"
        )
        assert reply[0]["value"] == old + 5
        assert robot.command("walk_params")["params"]["foot_height"] == old + 5
        fc.set_parameters([{"name": "walk/foot_height", "value": old, "type": "float64"}], "w3")
        fc.call("/lease", {"op": "release"}, 11)


def test_a_client_that_leaves_loses_its_lease(fox: tuple[RunningSystem, str]) -> None:
    system, url = fox
    with system.robot_client(name="watcher") as robot:
        with FoxgloveClient.open(url) as fc:
            fc.subscribe("/status")
            assert fc.call("/lease", {"op": "acquire"}, 1)[0] == "ok"
            robot.wait_for("status", lambda s: s.lease is not None, WAIT)
        # The connection closed: the server drops that client's Commander, whose liveliness
        # token goes, and the arbiter ends the lease (with a safe stop).
        robot.wait_for("status", lambda s: s.lease is None, WAIT)


def test_the_urdf_served_is_the_robots_body_with_the_daemons_joint_limits(
    fox: tuple[RunningSystem, str],
) -> None:
    import xml.etree.ElementTree as ET

    from clients.robot import Robot

    system, url = fox
    with Robot(system.endpoint, system.robot, name="fox-urdf") as robot:
        limits = {j["urdf"]: (j["min"], j["max"]) for j in robot.config()["joints"]}
    with FoxgloveClient.open(url) as fc:
        ch = fc.channel("/robot_description")
        assert (ch["encoding"], ch["schemaName"]) == ("json", "std_msgs/String")
        fc.subscribe("/robot_description")
        urdf = ET.fromstring(fc.take("/robot_description")["data"])
    joints = {j.get("name"): j for j in urdf.iter("joint") if j.get("type") == "revolute"}
    assert set(joints) == set(limits)
    for name, joint in joints.items():
        limit = joint.find("limit")
        assert limit is not None
        low, high = float(limit.get("lower", "nan")), float(limit.get("upper", "nan"))
        assert (low, high) == pytest.approx(limits[name], abs=1e-6), name


def test_the_ball_play_detections_become_image_annotations(
    fox: tuple[RunningSystem, str],
) -> None:
    from schemas.sim_control import SimControl

    system, url = fox
    with system.robot_client(name="player") as robot, FoxgloveClient.open(url) as fc:
        sim = SimControl(robot.session, system.robot)
        sim.call("place_robot", x=0.0, y=0.0, yaw=0.0)
        sim.call("place_ball", x=0.45, y=0.0)
        fc.subscribe("/camera/ball")
        with robot.control():
            robot.playball()
            try:
                seen = robot.wait_for("vision", lambda d: d.found, WAIT)
                ann = fc.take("/camera/ball", lambda m: len(m.circles) == 1)
                circle = ann.circles[0]
                assert 0 <= circle.position.x <= seen.width
                assert 0 <= circle.position.y <= seen.height
            finally:
                robot.playball_stop()
                robot.halt()
