"""The Foxglove transform tree: the URDF's joints from the body description, the ground, the
world pose; quaternions."""

from __future__ import annotations

import math

import numpy as np
import pytest

from clients.foxglove import frames
from clients.foxglove.control import parse_json, twist_speeds
from config.body import default_body
from schemas import kinematics as K
from schemas.errors import AdapterInputError
from schemas.messages import World
from tests.transforms import compose, quat_matrix


@pytest.mark.parametrize("seed", range(20))
def test_quaternion_round_trips_any_rotation(seed: int) -> None:
    rng = np.random.default_rng(seed)
    r = K.rpy_matrix(*rng.uniform(-math.pi, math.pi, 3))
    q = K.quaternion(r)
    assert math.isclose(float(np.linalg.norm(q)), 1.0, abs_tol=1e-12)
    assert np.allclose(quat_matrix(*q), r, atol=1e-12)


def test_half_turns_about_each_axis() -> None:
    for r in (K.rot_x(math.pi), K.rot_y(math.pi), K.rot_z(math.pi)):
        assert np.allclose(quat_matrix(*K.quaternion(r)), r, atol=1e-12)


def test_the_tree_is_the_urdf_and_stands_on_its_lower_sole() -> None:
    body = default_body()
    pos = {13: 0.6, 15: -0.3, 11: -0.3, 14: -0.2, 19: 0.4, 20: -0.2, 1: 0.5}
    tree = frames.body_transforms(body, pos)
    parent, child, base = tree[-1]
    assert (parent, child) == ("field", "base_link")
    soles = [K.leg_fk(pos, s)[2, 3] for s in K.SIDES]
    assert math.isclose(base[2, 3], -min(soles))
    # One transform per URDF joint, named by the URDF's links, and composed they are the
    # project's kinematics.
    assert {(p, c) for p, c, _ in tree[:-1]} == {(j.parent, j.child) for j in body.joints}
    poses = compose(tree[:-1])
    assert np.allclose(poses["camera"], K.camera_pose(pos))
    assert np.allclose(poses["head"], K.head_pose(pos))
    for side in K.SIDES:
        assert np.allclose(poses[f"{side[0]}_sole"], K.leg_fk(pos, side))


def test_world_pose_and_ball() -> None:
    w = World(robot={"x": 1.0, "y": -0.5, "yaw": 0.3}, ball={"x": 2.0, "y": 0.1, "vx": 0, "vy": 0})
    (_, _, base), (_, child, ball) = frames.world_transforms(w, 0.25)
    assert np.allclose(base[:3, 3], [1.0, -0.5, 0.25])
    assert np.allclose(base[:3, :3], K.rot_z(0.3))
    assert child == "ball" and np.allclose(ball[:3, 3], [2.0, 0.1, 0.0])
    assert len(frames.world_transforms(World(robot={}, ball={}), 0.2)) == 1


def test_teleop_and_request_parsing_refuse_bad_input() -> None:
    assert twist_speeds({"linear": {"x": 0.1}, "angular": {"z": -0.2}}) == (0.1, 0.0, -0.2)
    for bad in ({"linear": {"x": True}}, {"linear": [1]}, {"angular": {"z": "left"}}):
        with pytest.raises(AdapterInputError):
            twist_speeds(bad)
    for raw in (b"[1]", b"{nope", b"\xff", b"x" * 70000):
        with pytest.raises(AdapterInputError):
            parse_json(raw, "t")
    assert parse_json(b"", "t") == {}


def decoded(msg: object) -> object:
    """A foxglove-sdk message read back through its own protobuf schema."""
    from google.protobuf import descriptor_pb2, descriptor_pool, message_factory

    schema = type(msg).get_schema()  # type: ignore[attr-defined]
    pool = descriptor_pool.DescriptorPool()
    for f in descriptor_pb2.FileDescriptorSet.FromString(schema.data).file:
        pool.Add(f)
    cls = message_factory.GetMessageClass(pool.FindMessageTypeByName(schema.name))
    return cls.FromString(msg.encode())  # type: ignore[attr-defined]


def test_event_levels() -> None:
    from clients.foxglove.convert import log_entry
    from schemas.messages import Event

    error, warning, info = 4, 3, 2  # foxglove.Log.Level
    assert decoded(log_entry(Event(kind="fault", message="m"))).level == error
    assert decoded(log_entry(Event(kind="servo_alarm", message="m"))).level == warning
    entry = decoded(log_entry(Event(kind="walk", message="walking", stamp=12.5)))
    assert (entry.level, entry.name, entry.message) == (info, "walk", "walking")
    assert (entry.timestamp.seconds, entry.timestamp.nanos) == (12, 500_000_000)


def test_ball_annotation_circles_the_detection() -> None:
    from clients.foxglove.convert import ball_annotations
    from schemas.messages import BallDetection

    det = BallDetection(found=True, x=100.0, y=60.0, size=0.01, width=320, height=240)
    ann = decoded(ball_annotations(det))
    (circle,) = ann.circles
    assert (circle.position.x, circle.position.y) == (100.0, 60.0)
    assert math.isclose(circle.diameter, 2 * math.sqrt(0.01 * 320 * 240 / math.pi), rel_tol=1e-6)
    assert not decoded(ball_annotations(BallDetection(found=False))).circles
