"""The DARwIn-OP body description, defined once: links, joints, masses, primitive geometry.

The URDF (``darwin urdf``), the ROS adapter's ``tf`` and the physics model are all made from
:func:`build_body`; :mod:`schemas.kinematics` holds the dimensions it uses, and the tests check
that both give the same poses.

Conventions
-----------
* Joint angle = servo angle (0 = raw 2048, after the calibration offset the bus removes), so a
  joint's value is exactly ``Joints.position`` of the key space; no offsets, no sign maps. The
  servo's mounting direction is encoded in each joint's **axis** (Walking.cpp's direction table
  for the legs, :data:`schemas.kinematics.LEG_DIRECTION`), as the ROBOTIS-OP2 description does.
* Frames follow REP 103: ``base_link`` is the body frame of :mod:`schemas.kinematics` (x forward,
  y left, z up). ``camera`` has x along the optical axis; ``camera_optical`` is the REP 103
  optical frame (z forward, x right, y down) that image messages are stamped with. ``imu`` is the
  frame the daemon reports gyro and accelerometer in (the body axes, at the CM-730 in the torso).
* Joint names, limits and speed come from the robot config (``[robot.joints.*]``: ``urdf``,
  ``min_deg``, ``max_deg``, ``max_speed``); torque limit 2.5 N·m (MX-28 stall torque, ROBOTIS
  e-manual ``dxl_mx_info.yml``).

Masses and inertias
-------------------
Masses per link from HumaRobotics ``darwin_description`` (BSD-2-Clause, (c) 2013 Generation
Robots; the same values as Webots' DARwIn-OP model): body 0.97559947, neck 0.024357719, head
0.15804192, shoulder 0.025913024, upper arm 0.16837715, forearm 0.059288504, pelvis 0.167 (their
right pelvis says 0.197: we keep the mirror-symmetric value), thigh1 0.11904336, thigh2
0.11904336, tibia 0.070309794, ankle1 0.16710792, ankle2 0.0794462 kg. Their inertia tensors are
1000× too large and expressed in link frames that differ from ours, so instead each link's inertia
is that of a uniform box of its mass (the primitive geometry below, centre of mass at the box
centre). Boxes follow the sizes in HumaRobotics' commented primitives and Webots' collision boxes
(foot 0.105 × 0.066 × 0.013 m); the sole face of each foot box lies exactly at the sole frame.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

import numpy as np

from schemas import kinematics as kin

MX28_STALL_TORQUE = 2.5  # N·m at 12 V (ROBOTIS e-manual)


@dataclass(frozen=True)
class Box:
    """A link's box: its size and centre in the link's frame (m)."""

    size: tuple[float, float, float]
    centre: tuple[float, float, float] = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class Link:
    """A rigid link: its name, mass and box."""

    name: str
    mass: float = 0.0  # kg; 0 = a massless frame
    box: Box | None = None

    @property
    def inertia(self) -> tuple[float, float, float]:
        """Principal moments (ixx, iyy, izz) of a uniform box about its centre, kg·m²."""
        if self.box is None or self.mass <= 0:
            return (0.0, 0.0, 0.0)
        x, y, z = self.box.size
        m = self.mass / 12.0
        return (m * (y * y + z * z), m * (x * x + z * z), m * (x * x + y * y))


@dataclass(frozen=True)
class Joint:
    """A joint between two links: its origin, axis (None: fixed), servo and limits."""

    name: str
    parent: str
    child: str
    xyz: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)
    axis: tuple[float, float, float] | None = None  # None = fixed
    servo_id: int | None = None
    lower: float = 0.0
    upper: float = 0.0
    velocity: float = 0.0
    effort: float = MX28_STALL_TORQUE

    @property
    def fixed(self) -> bool:
        return self.axis is None

    @property
    def servo(self) -> int:
        """The servo id of a servo joint (a fixed frame has none)."""
        if self.servo_id is None:
            raise ValueError(f"joint {self.name} has no servo")
        return self.servo_id

    @cached_property
    def _origin(self) -> np.ndarray:
        return kin.transform(rpy_rotation(*self.rpy), self.xyz)

    def origin(self) -> np.ndarray:
        return self._origin.copy()

    def motion(self, angle: float) -> np.ndarray:
        """Origin, then the joint's rotation by ``angle`` (rad) about its axis."""
        if self.axis is None:
            return self._origin
        return self._origin @ kin.transform(axis_rotation(self.axis, angle))


@dataclass(frozen=True)
class JointLimits:
    """What the body needs from the robot config for one servo."""

    id: int
    urdf: str
    lower: float  # rad
    upper: float  # rad


@dataclass
class Body:
    """The whole body: its links and the joints between them."""

    name: str
    links: list[Link]
    joints: list[Joint]
    by_child: dict[str, Joint] = field(init=False)

    def __post_init__(self) -> None:
        self.by_child = {j.child: j for j in self.joints}

    @property
    def root(self) -> str:
        return self.links[0].name

    def servo_joints(self) -> list[Joint]:
        """The 20 servo joints, by servo id."""
        return sorted((j for j in self.joints if j.servo_id is not None), key=lambda j: j.servo)

    def joint_names(self) -> list[str]:
        return [j.name for j in self.servo_joints()]

    def link_poses(self, positions: kin.Positions) -> dict[str, np.ndarray]:
        """Pose (4×4) of every link in ``base_link`` for servo angles (as kinematics takes)."""
        poses: dict[str, np.ndarray] = {self.root: np.eye(4)}
        for j in self.joints:  # parents always come before children
            poses[j.child] = poses[j.parent] @ self.joint_transform(j, positions)
        return poses

    def joint_transform(self, j: Joint, positions: kin.Positions) -> np.ndarray:
        """Parent-to-child transform of one joint (origin, then the joint's rotation)."""
        if j.axis is None or j.servo_id is None:
            return j.origin()
        return j.motion(kin._angle(positions, j.servo_id))

    def total_mass(self) -> float:
        return sum(link.mass for link in self.links)


def rpy_rotation(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """URDF's fixed-axis roll-pitch-yaw: Rz(yaw)·Ry(pitch)·Rx(roll)."""
    return kin.rpy_matrix(roll, pitch, yaw)


_PRINCIPAL = {0: kin.rot_x, 1: kin.rot_y, 2: kin.rot_z}


def axis_rotation(axis: Iterable[float], angle: float) -> np.ndarray:
    """Rotation by ``angle`` about a unit ``axis`` (Rodrigues; direct for ±x, ±y, ±z)."""
    axis = tuple(axis)
    nonzero = [k for k, v in enumerate(axis) if v != 0.0]
    if len(nonzero) == 1 and abs(axis[nonzero[0]]) == 1.0:
        k = nonzero[0]
        return _PRINCIPAL[k](angle * axis[k])
    a = np.asarray(axis, dtype=float)
    a = a / np.linalg.norm(a)
    cross = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
    return np.eye(3) + math.sin(angle) * cross + (1.0 - math.cos(angle)) * (cross @ cross)


def limits_from_config(robot: Any) -> list[JointLimits]:
    """Joint limits from a :class:`config.loader.RobotConfig` (or anything with ``joints``
    carrying ``id``, ``urdf``, ``min_rad``, ``max_rad``)."""
    return [
        JointLimits(j.id, j.urdf, j.min_rad, j.max_rad)
        for j in robot.joints
    ]


def limits_from_config_reply(reply: Mapping[str, Any]) -> list[JointLimits]:
    """Joint limits from the arbiter's ``config`` verb reply (the running robot's config)."""
    out = []
    for j in reply["joints"]:
        out.append(JointLimits(int(j["id"]), str(j["urdf"]), float(j["min"]), float(j["max"])))
    return out


# -- the description ---------------------------------------------------------------------------
_MASS = {
    "base_link": 0.97559947,
    "neck": 0.024357719,
    "head": 0.15804192,
    "shoulder": 0.025913024,
    "upper_arm": 0.16837715,
    "forearm": 0.059288504,
    "hip_yaw": 0.167,
    "hip_roll": 0.11904336,
    "thigh": 0.11904336,
    "shin": 0.070309794,
    "ankle": 0.16710792,
    "foot": 0.0794462,
}
_FOOT_BOX = (0.105, 0.066, 0.013)


def _xyz(v: Sequence[float]) -> tuple[float, float, float]:
    x, y, z = v
    return (float(x), float(y), float(z))


def build_body(
    limits: Iterable[JointLimits], max_speed: float = 5.65, name: str = "darwin_op"
) -> Body:
    """The body for one robot config: 20 servo joints named and limited as configured."""
    by_id = {jl.id: jl for jl in limits}
    missing = sorted(set(range(1, 21)) - set(by_id))
    if missing:
        raise ValueError(f"the robot config has no joints with ids {missing}: all 20 are needed")
    links: list[Link] = [
        Link("base_link", _MASS["base_link"], Box((0.102, 0.109, 0.106), (-0.0235, 0.0, -0.03525)))
    ]
    joints: list[Joint] = []

    def servo(
        jid: int,
        parent: str,
        child: Link,
        xyz: Sequence[float] = (0.0, 0.0, 0.0),
        rpy: Sequence[float] = (0.0, 0.0, 0.0),
        axis: Sequence[float] = (0.0, 0.0, 1.0),
    ) -> None:
        jl = by_id[jid]
        links.append(child)
        joints.append(
            Joint(
                jl.urdf,
                parent,
                child.name,
                _xyz(xyz),
                _xyz(rpy),
                _xyz(axis),
                jid,
                jl.lower,
                jl.upper,
                max_speed,
            )
        )

    def frame(
        jname: str,
        parent: str,
        child: str,
        xyz: Sequence[float] = (0.0, 0.0, 0.0),
        rpy: Sequence[float] = (0.0, 0.0, 0.0),
    ) -> None:
        links.append(Link(child))
        joints.append(Joint(jname, parent, child, _xyz(xyz), _xyz(rpy)))

    # Head: pan about z, tilt about -y (positive tilt looks up), camera pitched by the eye offset.
    servo(
        kin.HEAD_PAN_ID,
        "base_link",
        Link("neck", _MASS["neck"], Box((0.022, 0.045, 0.0325), (0.0, 0.0, -0.016))),
        (0, 0, kin.NECK_HEIGHT),
    )
    servo(
        kin.HEAD_TILT_ID,
        "neck",
        Link("head", _MASS["head"], Box((0.0634, 0.061, 0.065), (0.0, 0.0, 0.03))),
        axis=(0, -1, 0),
    )
    cam = kin._CAMERA_IN_HEAD
    frame("camera_joint", "head", "camera", tuple(cam[:3, 3]), (0.0, kin.EYE_TILT_OFFSET, 0.0))
    frame("camera_optical_joint", "camera", "camera_optical", rpy=(-math.pi / 2, 0.0, -math.pi / 2))
    frame("imu_joint", "base_link", "imu")

    for side in kin.SIDES:
        s = 1.0 if side == "left" else -1.0
        p = side[0]
        # Arms: the ROBOTIS-OP2 description's origins and axes (schemas.kinematics).
        pitch_id, roll_id, elbow_id = kin.ARM_IDS[side]
        servo(
            pitch_id,
            "base_link",
            Link(f"{p}_shoulder", _MASS["shoulder"], Box((0.016, 0.033, 0.02165))),
            (0, s * kin.SHOULDER_SIDE_OFFSET, kin.SHOULDER_HEIGHT),
            axis=(0, s, 0),
        )
        roll_xyz = np.array(kin.SHOULDER_ROLL_OFFSET) * (1.0, s, 1.0)
        servo(
            roll_id,
            f"{p}_shoulder",
            Link(
                f"{p}_upper_arm",
                _MASS["upper_arm"],
                Box(
                    (0.035, 0.032, kin.UPPER_ARM_LENGTH),
                    (kin.UPPER_ARM_FORWARD / 2, 0, -kin.UPPER_ARM_LENGTH / 2),
                ),
            ),
            tuple(roll_xyz),
            rpy=(s * kin.SHOULDER_ROLL_ORIGIN, 0, 0),
            axis=(-1, 0, 0),
        )
        servo(
            elbow_id,
            f"{p}_upper_arm",
            Link(
                f"{p}_forearm",
                _MASS["forearm"],
                Box((0.032, 0.032, kin.FOREARM_LENGTH), (0, 0, -kin.FOREARM_LENGTH / 2)),
            ),
            (kin.UPPER_ARM_FORWARD, 0, -kin.UPPER_ARM_LENGTH),
            (0, -kin.ELBOW_ORIGIN, 0),
            (0, s, 0),
        )
        frame(f"{p}_hand_joint", f"{p}_forearm", f"{p}_hand", (0, 0, -kin.FOREARM_LENGTH))

        # Legs: Rz(yaw)·Rx(roll)·Ry(pitch) at the hip point, knee, ankle pitch and roll; the
        # servo direction is the axis sign (servo angle = direction · leg angle).
        yaw_id, roll_id, hpitch_id, knee_id, apitch_id, aroll_id = kin.LEG_IDS[side]
        d = kin.LEG_DIRECTION[side]
        servo(
            yaw_id,
            "base_link",
            Link(f"{p}_hip_yaw", _MASS["hip_yaw"], Box((0.045, 0.03, 0.028), (0, 0, 0.014))),
            tuple(kin.hip_point(side)),
            axis=(0, 0, d[0]),
        )
        servo(
            roll_id,
            f"{p}_hip_yaw",
            Link(f"{p}_hip_roll", _MASS["hip_roll"], Box((0.045, 0.035, 0.03))),
            axis=(d[1], 0, 0),
        )
        servo(
            hpitch_id,
            f"{p}_hip_roll",
            Link(
                f"{p}_thigh",
                _MASS["thigh"],
                Box((0.035, 0.045, kin.THIGH_LENGTH), (0, 0, -kin.THIGH_LENGTH / 2)),
            ),
            axis=(0, d[2], 0),
        )
        servo(
            knee_id,
            f"{p}_thigh",
            Link(
                f"{p}_shin",
                _MASS["shin"],
                Box((0.035, 0.045, kin.CALF_LENGTH), (0, 0, -kin.CALF_LENGTH / 2)),
            ),
            (0, 0, -kin.THIGH_LENGTH),
            axis=(0, d[3], 0),
        )
        servo(
            apitch_id,
            f"{p}_shin",
            Link(f"{p}_ankle", _MASS["ankle"], Box((0.045, 0.035, 0.03))),
            (0, 0, -kin.CALF_LENGTH),
            axis=(0, d[4], 0),
        )
        servo(
            aroll_id,
            f"{p}_ankle",
            Link(
                f"{p}_foot",
                _MASS["foot"],
                Box(_FOOT_BOX, (0, 0, -kin.ANKLE_LENGTH + _FOOT_BOX[2] / 2)),
            ),
            axis=(d[5], 0, 0),
        )
        frame(f"{p}_sole_joint", f"{p}_foot", f"{p}_sole", (0, 0, -kin.ANKLE_LENGTH))
    return Body(name, links, joints)
