"""Key-space messages → ROS messages, and ROS commands → checked arbiter fields (pure).

Units are SI both sides; frames REP 103/105. Effort: an MX-28's present load is its output duty
(physics.md), so torque ≈ load · stall torque · voltage / 12 V (2.5 N·m stall at 12 V).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from schemas.body import MX28_STALL_TORQUE, Body
from schemas.daemon_state import DaemonState
from schemas.errors import AdapterInputError
from schemas.kinematics import quaternion
from schemas.messages import Imu, Joints, Status, World

from .types import msg_class

STALL_VOLTAGE = 12.0
YAW_UNKNOWN_VARIANCE = 1.0e6  # rad²: no magnetometer, the yaw is not observed at all


def stamp(t: float) -> Any:
    sec = math.floor(t)
    return msg_class("builtin_interfaces/msg/Time")(sec=int(sec), nanosec=int((t - sec) * 1e9))


def header(t: float, frame_id: str = "") -> Any:
    return msg_class("std_msgs/msg/Header")(stamp=stamp(t), frame_id=frame_id)


def joint_state(joints: Joints, names_by_id: Mapping[int, str]) -> Any:
    ids = [i for i in joints.id if i in names_by_id]
    idx = [joints.id.index(i) for i in ids]
    effort = [
        joints.load[k] * MX28_STALL_TORQUE * (joints.voltage[k] or STALL_VOLTAGE) / STALL_VOLTAGE
        for k in idx
    ]
    return msg_class("sensor_msgs/msg/JointState")(
        header=header(joints.stamp),
        name=[names_by_id[i] for i in ids],
        position=np.array([joints.position[k] for k in idx], dtype=np.float64),
        velocity=np.array([joints.velocity[k] for k in idx], dtype=np.float64),
        effort=np.array(effort, dtype=np.float64),
    )


def rpy_quaternion(roll: float, pitch: float, yaw: float) -> tuple[float, float, float, float]:
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    return (
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
        cr * cp * cy + sr * sp * sy,
    )


class TiltFilter:
    """Roll and pitch from a complementary filter (gyro integrated, pulled toward the
    accelerometer's gravity direction). Yaw is not observable without a magnetometer."""

    def __init__(self, gain: float = 0.02) -> None:
        self.gain = gain
        self.roll = 0.0
        self.pitch = 0.0
        self._t: float | None = None

    def update(self, gyro: Sequence[float], accel: Sequence[float], t: float) -> None:
        ax, ay, az = accel
        acc_roll = math.atan2(ay, az)
        acc_pitch = math.atan2(-ax, math.hypot(ay, az))
        if self._t is None or not (0.0 < t - self._t < 0.5):
            self.roll, self.pitch = acc_roll, acc_pitch
        else:
            dt = t - self._t
            self.roll = (1 - self.gain) * (self.roll + gyro[0] * dt) + self.gain * acc_roll
            self.pitch = (1 - self.gain) * (self.pitch + gyro[1] * dt) + self.gain * acc_pitch
        self._t = t


def imu(m: Imu, tilt: TiltFilter, frame_id: str = "imu") -> Any:
    tilt.update(m.gyro, m.accel, m.stamp)
    x, y, z, w = rpy_quaternion(tilt.roll, tilt.pitch, 0.0)
    q = msg_class("geometry_msgs/msg/Quaternion")(x=x, y=y, z=z, w=w)
    v3 = msg_class("geometry_msgs/msg/Vector3")
    orient_cov = np.zeros(9)
    orient_cov[0] = orient_cov[4] = 0.05**2  # rad², the filter's rough roll/pitch accuracy
    orient_cov[8] = YAW_UNKNOWN_VARIANCE
    gyro_cov = np.zeros(9)
    gyro_cov[0] = gyro_cov[4] = gyro_cov[8] = 0.02**2
    acc_cov = np.zeros(9)
    acc_cov[0] = acc_cov[4] = acc_cov[8] = 0.1**2
    return msg_class("sensor_msgs/msg/Imu")(
        header=header(m.stamp, frame_id),
        orientation=q,
        orientation_covariance=orient_cov,
        angular_velocity=v3(x=float(m.gyro[0]), y=float(m.gyro[1]), z=float(m.gyro[2])),
        angular_velocity_covariance=gyro_cov,
        linear_acceleration=v3(x=float(m.accel[0]), y=float(m.accel[1]), z=float(m.accel[2])),
        linear_acceleration_covariance=acc_cov,
    )


def transform(t: float | Any, parent: str, child: str, pose: np.ndarray) -> Any:
    """A TransformStamped; ``t`` is seconds or an already built builtin_interfaces/Time."""
    x, y, z, w = quaternion(pose)
    px, py, pz = pose[:3, 3].tolist()
    tr = msg_class("geometry_msgs/msg/Transform")(
        translation=msg_class("geometry_msgs/msg/Vector3")(x=px, y=py, z=pz),
        rotation=msg_class("geometry_msgs/msg/Quaternion")(x=x, y=y, z=z, w=w),
    )
    when = stamp(t) if isinstance(t, (int, float)) else t
    return msg_class("geometry_msgs/msg/TransformStamped")(
        header=msg_class("std_msgs/msg/Header")(stamp=when, frame_id=parent),
        child_frame_id=child,
        transform=tr,
    )


def tf_joints(body: Body, positions: Any, t: float, moving: bool = True) -> Any:
    """TFMessage of the servo joints (``moving``) or of the fixed joints (for tf_static)."""
    when = stamp(t)
    out = [
        transform(when, j.parent, j.child, body.joint_transform(j, positions))
        for j in body.joints
        if j.fixed != moving
    ]
    return msg_class("tf2_msgs/msg/TFMessage")(transforms=out)


def tf_odom(world: World) -> Any:
    r = world.robot
    pose = np.eye(4)
    c, s = math.cos(r.get("yaw", 0.0)), math.sin(r.get("yaw", 0.0))
    pose[:2, :2] = [[c, -s], [s, c]]
    pose[0, 3], pose[1, 3] = r.get("x", 0.0), r.get("y", 0.0)
    return msg_class("tf2_msgs/msg/TFMessage")(
        transforms=[transform(world.stamp, "odom", "base_link", pose)]
    )


def compressed_image(jpeg: bytes, t: float, frame_id: str = "camera_optical") -> Any:
    return msg_class("sensor_msgs/msg/CompressedImage")(
        header=header(t, frame_id), format="jpeg", data=np.frombuffer(jpeg, dtype=np.uint8)
    )


def diagnostics(
    joints: Joints | None, status: Status | None, names_by_id: Mapping[int, str], t: float
):
    ds = msg_class("diagnostic_msgs/msg/DiagnosticStatus")
    kv = msg_class("diagnostic_msgs/msg/KeyValue")
    out = []
    if joints is not None:
        for k, i in enumerate(joints.id):
            online, alarm, temp = joints.online[k], joints.alarm[k], joints.temperature[k]
            level, message = 0, "ok"
            if not online:
                level, message = 2, "offline"
            elif alarm:
                level, message = 2, f"alarm bits {alarm:#04x}"
            elif temp >= 70:
                level, message = 1, f"hot ({temp:.0f} °C)"
            out.append(
                ds(
                    level=level,
                    name=f"servo {names_by_id.get(i, i)}",
                    message=message,
                    hardware_id=f"dynamixel {i}",
                    values=[
                        kv(key="temperature_c", value=f"{temp:.0f}"),
                        kv(key="voltage_v", value=f"{joints.voltage[k]:.1f}"),
                        kv(key="alarm", value=str(alarm)),
                        kv(key="online", value=str(bool(online)).lower()),
                        kv(key="torque", value=str(bool(joints.torque_enabled[k])).lower()),
                    ],
                )
            )
    if status is not None:
        healthy = status.state == DaemonState.RUNNING
        values = [
            kv(key="state", value=status.state),
            kv(key="battery_v", value=f"{status.voltage:.1f}"),
        ]
        for section in ("bus", "loop"):
            for key, value in sorted(getattr(status, section).items()):
                if isinstance(value, (int, float, str, bool)):
                    values.append(kv(key=f"{section}.{key}", value=str(value)))
        out.append(
            ds(
                level=0 if healthy else 1,
                name="robot",
                message=status.state,
                hardware_id=status.robot,
                values=values,
            )
        )
    return msg_class("diagnostic_msgs/msg/DiagnosticArray")(header=header(t), status=out)


# -- commands ---------------------------------------------------------------------------------
@dataclass(frozen=True)
class Walk:
    """A ``cmd_vel`` as the walk verb's fields: forward and sideways speed, turn rate."""

    x: float
    y: float
    turn: float

    @property
    def zero(self) -> bool:
        return self.x == 0.0 and self.y == 0.0 and self.turn == 0.0


def walk_from_twist(ros_type: str, msg: Any) -> Walk:
    twist = msg.twist if ros_type.endswith("TwistStamped") else msg
    values = {
        "linear.x": twist.linear.x,
        "linear.y": twist.linear.y,
        "angular.z": twist.angular.z,
    }
    for name, v in values.items():
        if not math.isfinite(v):
            raise AdapterInputError(f"cmd_vel {name} is {v}: only finite speeds are accepted")
    return Walk(float(twist.linear.x), float(twist.linear.y), float(twist.angular.z))


@dataclass(frozen=True)
class Limit:
    """One servo's position limits (rad), for a ROS joint."""

    id: int
    lower: float
    upper: float


def trajectory_command(
    msg: Any, limits: Mapping[str, Limit]
) -> tuple[list[int], list[tuple[float, list[float]]]]:
    """A JointTrajectory as the ``trajectory`` verb's joints (servo ids, from the URDF joint
    names) and points (seconds from the start, positions). Only what ROS alone knows is checked
    here (the joint names); the daemon checks every point before anything moves."""
    names = list(msg.joint_names)
    unknown = [n for n in names if n not in limits]
    if unknown:
        raise AdapterInputError(
            f"joint_trajectory names unknown joints {unknown}; joints are {sorted(limits)}"
        )
    points = [
        (p.time_from_start.sec + p.time_from_start.nanosec * 1e-9, [float(v) for v in p.positions])
        for p in msg.points
    ]
    return [limits[n].id for n in names], points
