"""Key-space messages to ROS messages and ROS commands to checked arbiter fields."""

from __future__ import annotations

import math

import numpy as np
import pytest

from clients.rmw import convert
from clients.rmw.types import decode, encode, msg_class
from config.body import default_body
from schemas.errors import AdapterInputError
from schemas.messages import Imu, Joints


def _joints(load: float = 0.5, voltage: float = 12.0) -> Joints:
    n = 20
    return Joints(
        id=list(range(1, 21)),
        name=[f"j{i}" for i in range(1, 21)],
        position=[0.01 * i for i in range(1, 21)],
        goal=[0.0] * n,
        velocity=[0.1] * n,
        load=[load] * n,
        temperature=[40.0] * n,
        voltage=[voltage] * n,
        torque_enabled=[True] * n,
        online=[True] * n,
        alarm=[0] * n,
        stamp=1700000000.25,
    )


def test_joint_state_names_units_and_effort():
    body = default_body()
    names = {j.servo_id: j.name for j in body.servo_joints()}
    js = convert.joint_state(_joints(load=0.5, voltage=6.0), names)
    raw = encode(js, "sensor_msgs/msg/JointState")
    back = decode(raw, "sensor_msgs/msg/JointState")
    assert back.name == body.joint_names()
    np.testing.assert_allclose(back.position, [0.01 * i for i in range(1, 21)])
    # Half duty at half the stall voltage: a quarter of the 2.5 N·m stall torque.
    np.testing.assert_allclose(back.effort, [0.625] * 20)
    assert (back.header.stamp.sec, back.header.stamp.nanosec) == (1700000000, 250000000)


def test_imu_orientation_from_gravity_and_unknown_yaw():
    tilt = convert.TiltFilter()
    roll = 0.3
    accel = [0.0, 9.81 * math.sin(roll), 9.81 * math.cos(roll)]
    m = convert.imu(Imu(gyro=[0, 0, 0], accel=accel, gyro_raw=[], accel_raw=[], stamp=1.0), tilt)
    q = m.orientation
    assert 2 * math.atan2(q.x, q.w) == pytest.approx(roll, abs=1e-6)
    assert m.orientation_covariance[8] >= 1e3 and m.orientation_covariance[0] < 0.01


def test_twist_checks():
    v3 = msg_class("geometry_msgs/msg/Vector3")
    tw = msg_class("geometry_msgs/msg/Twist")(
        linear=v3(x=0.1, y=0, z=0), angular=v3(x=0, y=0, z=0.2)
    )
    assert convert.walk_from_twist("geometry_msgs/msg/Twist", tw) == convert.Walk(0.1, 0.0, 0.2)
    assert convert.Walk(0.0, 0.0, 0.0).zero
    stamped = msg_class("geometry_msgs/msg/TwistStamped")(header=convert.header(0.0), twist=tw)
    assert convert.walk_from_twist("geometry_msgs/msg/TwistStamped", stamped).turn == 0.2
    bad = msg_class("geometry_msgs/msg/Twist")(
        linear=v3(x=math.inf, y=0, z=0), angular=v3(x=0, y=0, z=0)
    )
    with pytest.raises(AdapterInputError, match=r"linear\.x is inf"):
        convert.walk_from_twist("geometry_msgs/msg/Twist", bad)


def _traj(names, points):
    JTP = msg_class("trajectory_msgs/msg/JointTrajectoryPoint")
    Dur = msg_class("builtin_interfaces/msg/Duration")
    empty = np.array([], dtype=np.float64)
    return msg_class("trajectory_msgs/msg/JointTrajectory")(
        header=convert.header(0.0),
        joint_names=names,
        points=[
            JTP(
                positions=np.array(pos, dtype=np.float64),
                velocities=empty,
                accelerations=empty,
                effort=empty,
                time_from_start=Dur(sec=int(t), nanosec=int((t % 1) * 1e9)),
            )
            for t, pos in points
        ],
    )


@pytest.fixture
def limits():
    return {
        j.name: convert.Limit(j.servo_id, j.lower, j.upper) for j in default_body().servo_joints()
    }


def test_a_trajectory_becomes_the_verbs_servo_ids_and_timed_points(limits):
    joints, points = convert.trajectory_command(
        _traj(["j_pan", "j_tilt"], [(0.5, [0.1, 0.2]), (1.5, [0.0, 0.0])]), limits
    )
    assert joints == [19, 20]
    assert points == [(0.5, [0.1, 0.2]), (1.5, [0.0, 0.0])]


def test_a_trajectory_naming_joints_ros_does_not_know_is_refused(limits):
    """Names are ROS's own (the URDF's); every other check is the daemon's (test_trajectory)."""
    with pytest.raises(AdapterInputError, match="unknown joints"):
        convert.trajectory_command(_traj(["j_nose"], [(1.0, [0.0])]), limits)


def test_tf_matches_the_body(limits):
    body = default_body()
    q = {i: 0.1 for i in range(1, 21)}
    tf = convert.tf_joints(body, q, 1.0)
    assert len(tf.transforms) == 20
    static = convert.tf_joints(body, q, 1.0, moving=False)
    assert {t.child_frame_id for t in static.transforms} >= {"camera", "camera_optical", "imu"}
    knee = next(t for t in tf.transforms if t.child_frame_id == "r_shin")
    assert knee.header.frame_id == "r_thigh"
    assert knee.transform.translation.z == pytest.approx(-0.093)
