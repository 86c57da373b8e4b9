"""Body dimensions and forward kinematics of the DARwIn-OP, defined once.

Frames and units
----------------
* Lengths are metres, angles rad. Poses are 4×4 homogeneous transforms (numpy arrays).
* The **body frame**: x forward, y left, z up. Its origin is the torso reference point of
  hardware.md, the point from which the hip yaw axes sit at (−5, ±37, −90.7) mm.
* Joint angles are servo angles (0 = raw 2048) indexed by joint id, exactly what
  ``JointFrame.position`` holds: a numpy array of length 21 (slot 0 unused), a list, or a
  ``{id: rad}`` mapping (missing ids count as 0).

Legs (the ROBOTIS framework's model, Walking.cpp / Kinematics.h)
---------------------------------------------------------------
The three hip axes meet in one point, the **hip point**. From it the chain is

    Rz(yaw) · Rx(roll) · Ry(pitch) · T(0,0,−thigh) · Ry(knee) · T(0,0,−calf)
            · Ry(ankle_pitch) · Rx(ankle_roll) · T(0,0,−ankle)

ending at the sole of the foot. These are the *leg angles* of the framework's inverse
kinematics (knee > 0 is bent; hip pitch < 0 swings the thigh forward). Servos are mounted
mirrored, so a servo angle is ``LEG_DIRECTION[side][k] · leg angle`` (Walking.cpp's ``dir``):
right (7, 9, 11, 13, 15, 17) → (−1, −1, +1, +1, −1, +1),
left  (8, 10, 12, 14, 16, 18) → (−1, −1, −1, −1, +1, +1).

Head and camera
---------------
Head pan turns about z (positive = look left), head tilt about y (positive = look up). The
camera is fixed in the head, pitched down by the eye tilt offset (40°): at tilt = +40° it looks
level, and it sits 33.2 mm ahead of and 34.4 mm above the tilt axis in that pose. The camera
frame has x along the optical axis, y to the image's left, z to the image's top.

Arms (after Bold Hearts' published DARwIn body model, converted to this frame)
----------------------------------------------------------------------------
Shoulder pitch about the lateral axis (right: +angle swings the arm forward; left mirrored)
with a 45° origin chosen so the stock resting pose (page 1: right −48°, left +41°) hangs the
arms down; shoulder roll about the fore-aft axis with a 45° built-in abduction and the elbow
with a 90° built-in bend (the offsets the original project added on ids 3/4 and 5/6 to match
its URDF). The arms only feed the stick figure: nothing steers by them.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Literal

import numpy as np

Side = Literal["right", "left"]
SIDES: tuple[Side, Side] = ("right", "left")

# -- dimensions (m) --------------------------------------------------------------------------
THIGH_LENGTH = 0.093
CALF_LENGTH = 0.093
ANKLE_LENGTH = 0.0335
LEG_LENGTH = THIGH_LENGTH + CALF_LENGTH + ANKLE_LENGTH  # 0.2195, fully stretched hip → sole
LEG_SIDE_OFFSET = 0.037  # hip point from the mid-plane
HIP_OFFSET_X = -0.005
HIP_OFFSET_Z = -0.0907
# Arms as the ROBOTIS-OP2 description (robotis_op2.structure.arm.xacro) has them: the shoulder
# pitch axis 57.5 mm out, the roll axis 24.5 mm further out and 16 mm lower (turning with the
# pitch), the elbow 16 mm ahead of and 60 mm below the roll axis.
SHOULDER_SIDE_OFFSET = 0.0575
SHOULDER_HEIGHT = 0.0315  # shoulder pitch axis above the body origin
SHOULDER_ROLL_OFFSET = (0.0, 0.0245, -0.016)  # roll axis from the pitch axis (left; y mirrors)
UPPER_ARM_LENGTH = 0.060
UPPER_ARM_FORWARD = 0.016  # the elbow sits slightly ahead of the upper arm's axis
FOREARM_LENGTH = 0.129
NECK_HEIGHT = 0.082  # head pan axis / tilt axis above the body origin
CAMERA_DISTANCE = 0.0332  # ahead of the tilt axis, with the camera level (tilt = eye offset)
CAMERA_HEIGHT = 0.0344  # above the tilt axis, same pose
HEAD_TOP = 0.065  # top of the head above the tilt axis (drawing only)
EYE_TILT_OFFSET = math.radians(40.0)
# Servo zero of the arms: the upper arm hangs 45° out to the side (no pitch offset: at pitch 0 it
# is not swung forward or back) and the forearm points forward, 90° from the upper arm
# (ROBOTIS-OP2 description: roll origin rpy ±45° about x, elbow origin rpy −90° about y).
SHOULDER_ROLL_ORIGIN = math.radians(45.0)
ELBOW_ORIGIN = math.radians(90.0)

# -- joint ids -------------------------------------------------------------------------------
LEG_IDS: dict[str, tuple[int, int, int, int, int, int]] = {
    # hip yaw, hip roll, hip pitch, knee, ankle pitch, ankle roll
    "right": (7, 9, 11, 13, 15, 17),
    "left": (8, 10, 12, 14, 16, 18),
}
LEG_DIRECTION: dict[str, tuple[int, int, int, int, int, int]] = {
    "right": (-1, -1, 1, 1, -1, 1),
    "left": (-1, -1, -1, -1, 1, 1),
}
ARM_IDS: dict[str, tuple[int, int, int]] = {"right": (1, 3, 5), "left": (2, 4, 6)}
HEAD_PAN_ID = 19
HEAD_TILT_ID = 20

Positions = Mapping[int, float] | Sequence[float] | np.ndarray


# -- elementary transforms ---------------------------------------------------------------------
def rot_x(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_y(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_z(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def transform(
    rotation: np.ndarray | None = None, translation: Sequence[float] | np.ndarray = (0, 0, 0)
) -> np.ndarray:
    """A 4×4 pose from a 3×3 rotation and a translation."""
    t = np.eye(4)
    if rotation is not None:
        t[:3, :3] = rotation
    t[:3, 3] = translation
    return t


def rpy_matrix(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """Rz(yaw)·Ry(pitch)·Rx(roll), the framework's ``Matrix3D::SetTransform`` order."""
    return rot_z(yaw) @ rot_y(pitch) @ rot_x(roll)


def matrix_rpy(r: np.ndarray) -> tuple[float, float, float]:
    """Inverse of :func:`rpy_matrix` (roll, pitch, yaw), for |pitch| < 90°."""
    pitch = math.atan2(-r[2, 0], math.hypot(r[0, 0], r[1, 0]))
    roll = math.atan2(r[2, 1], r[2, 2])
    yaw = math.atan2(r[1, 0], r[0, 0])
    return roll, pitch, yaw


def quaternion(r: np.ndarray) -> tuple[float, float, float, float]:
    """(x, y, z, w) of a rotation matrix (Shepperd's method: stable for every rotation)."""
    (m00, m01, m02), (m10, m11, m12), (m20, m21, m22) = r[:3, :3].tolist()
    tr = m00 + m11 + m22
    if tr > 0:
        s = 2.0 * math.sqrt(tr + 1.0)
        return ((m21 - m12) / s, (m02 - m20) / s, (m10 - m01) / s, 0.25 * s)
    if m00 > m11 and m00 > m22:
        s = 2.0 * math.sqrt(1.0 + m00 - m11 - m22)
        return (0.25 * s, (m01 + m10) / s, (m02 + m20) / s, (m21 - m12) / s)
    if m11 > m22:
        s = 2.0 * math.sqrt(1.0 + m11 - m00 - m22)
        return ((m01 + m10) / s, 0.25 * s, (m12 + m21) / s, (m02 - m20) / s)
    s = 2.0 * math.sqrt(1.0 + m22 - m00 - m11)
    return ((m02 + m20) / s, (m12 + m21) / s, 0.25 * s, (m10 - m01) / s)


def _angle(positions: Positions, joint_id: int) -> float:
    if isinstance(positions, Mapping):
        return float(positions.get(joint_id, 0.0))
    return float(positions[joint_id])


# -- legs --------------------------------------------------------------------------------------
def hip_point(side: Side) -> np.ndarray:
    """Where the hip axes meet, in the body frame (m)."""
    sign = 1.0 if side == "left" else -1.0
    return np.array([HIP_OFFSET_X, sign * LEG_SIDE_OFFSET, HIP_OFFSET_Z])


def _check_side(side: str) -> None:
    if side not in LEG_IDS:
        raise ValueError(f"side must be 'right' or 'left', not {side!r}")


def servo_to_leg_angles(positions: Positions, side: Side) -> tuple[float, ...]:
    """The six leg angles (yaw, roll, pitch, knee, ankle pitch, ankle roll) from servo angles."""
    _check_side(side)
    return tuple(
        d * _angle(positions, j) for j, d in zip(LEG_IDS[side], LEG_DIRECTION[side], strict=True)
    )


def leg_angles_to_servo(angles: Sequence[float], side: Side) -> dict[int, float]:
    """Servo angles {id: rad} for six leg angles (inverse of :func:`servo_to_leg_angles`)."""
    _check_side(side)
    return {
        j: d * float(a) for j, d, a in zip(LEG_IDS[side], LEG_DIRECTION[side], angles, strict=True)
    }


def leg_chain(angles: Sequence[float]) -> list[np.ndarray]:
    """Poses relative to the hip point of: hip (after yaw/roll/pitch), knee, ankle, sole."""
    yaw, roll, pitch, knee, ankle_pitch, ankle_roll = (float(a) for a in angles)
    hip = transform(rot_z(yaw) @ rot_x(roll) @ rot_y(pitch))
    knee_t = hip @ transform(translation=(0, 0, -THIGH_LENGTH)) @ transform(rot_y(knee))
    ankle_t = (
        knee_t
        @ transform(translation=(0, 0, -CALF_LENGTH))
        @ transform(rot_y(ankle_pitch) @ rot_x(ankle_roll))
    )
    sole = ankle_t @ transform(translation=(0, 0, -ANKLE_LENGTH))
    return [hip, knee_t, ankle_t, sole]


def leg_fk_angles(angles: Sequence[float]) -> np.ndarray:
    """Pose of the sole relative to the hip point, from the six leg angles."""
    return leg_chain(angles)[-1]


def leg_fk(positions: Positions, side: Side) -> np.ndarray:
    """Pose (4×4, m) of the sole of the ``side`` foot in the body frame, from servo angles."""
    sole = leg_fk_angles(servo_to_leg_angles(positions, side))
    return transform(translation=hip_point(side)) @ sole


# -- head and camera ---------------------------------------------------------------------------
def head_pose(positions: Positions) -> np.ndarray:
    """Pose of the head (at the tilt axis, after pan and tilt) in the body frame."""
    pan = _angle(positions, HEAD_PAN_ID)
    tilt = _angle(positions, HEAD_TILT_ID)
    return transform(rot_z(pan) @ rot_y(-tilt), (0.0, 0.0, NECK_HEIGHT))


# The camera in the head frame: level when tilt == EYE_TILT_OFFSET.
_CAMERA_IN_HEAD = transform(
    rot_y(EYE_TILT_OFFSET), rot_y(EYE_TILT_OFFSET) @ np.array([CAMERA_DISTANCE, 0, CAMERA_HEIGHT])
)


def camera_pose(positions: Positions) -> np.ndarray:
    """Pose (4×4, m) of the camera in the body frame: x optical axis, y image left, z image up."""
    return head_pose(positions) @ _CAMERA_IN_HEAD


# -- arms --------------------------------------------------------------------------------------
def arm_chain(positions: Positions, side: Side) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Shoulder, elbow and hand points of one arm in the body frame."""
    _check_side(side)
    pitch_id, roll_id, elbow_id = ARM_IDS[side]
    sign = 1.0 if side == "left" else -1.0
    pitch = _angle(positions, pitch_id)
    roll = _angle(positions, roll_id)
    elbow = _angle(positions, elbow_id)
    # Right: +pitch swings forward, +roll abducts, +elbow bends the forearm up toward the upper
    # arm (ROBOTIS-OP2 axes); the left arm is the mirror image (its servos turn the other way).
    fwd_pitch = -sign * pitch
    abduction = -sign * roll + SHOULDER_ROLL_ORIGIN
    shoulder = np.array([0.0, sign * SHOULDER_SIDE_OFFSET, SHOULDER_HEIGHT])
    r_pitch = rot_y(-fwd_pitch)
    roll_p = shoulder + r_pitch @ (np.array(SHOULDER_ROLL_OFFSET) * [1.0, sign, 1.0])
    r_shoulder = r_pitch @ rot_x(sign * abduction)
    elbow_p = roll_p + r_shoulder @ np.array([UPPER_ARM_FORWARD, 0.0, -UPPER_ARM_LENGTH])
    r_elbow = r_shoulder @ rot_y(-ELBOW_ORIGIN) @ rot_y(sign * elbow)
    hand = elbow_p + r_elbow @ np.array([0.0, 0.0, -FOREARM_LENGTH])
    return shoulder, elbow_p, hand


# -- the whole body ----------------------------------------------------------------------------
SKELETON_BONES: tuple[tuple[str, str], ...] = (
    ("torso", "neck"),
    ("neck", "head"),
    ("neck", "r_shoulder"),
    ("neck", "l_shoulder"),
    ("r_shoulder", "r_elbow"),
    ("r_elbow", "r_hand"),
    ("l_shoulder", "l_elbow"),
    ("l_elbow", "l_hand"),
    ("torso", "r_hip"),
    ("torso", "l_hip"),
    ("r_hip", "r_knee"),
    ("r_knee", "r_ankle"),
    ("r_ankle", "r_foot"),
    ("l_hip", "l_knee"),
    ("l_knee", "l_ankle"),
    ("l_ankle", "l_foot"),
    ("head", "camera"),
)
"""Pairs of :func:`skeleton` points to join with lines to draw a stick figure."""


def skeleton(positions: Positions) -> dict[str, np.ndarray]:
    """Named 3-D points (m, body frame) for a stick figure; join them with SKELETON_BONES."""
    points: dict[str, np.ndarray] = {"torso": np.zeros(3)}
    head = head_pose(positions)
    points["neck"] = head[:3, 3].copy()
    points["head"] = (head @ np.array([0.0, 0.0, HEAD_TOP, 1.0]))[:3]
    points["camera"] = camera_pose(positions)[:3, 3].copy()
    for side in SIDES:
        p = side[0]
        shoulder, elbow, hand = arm_chain(positions, side)
        points[f"{p}_shoulder"], points[f"{p}_elbow"], points[f"{p}_hand"] = shoulder, elbow, hand
        base = transform(translation=hip_point(side))
        hip_t, knee_t, ankle_t, sole_t = (
            base @ t for t in leg_chain(servo_to_leg_angles(positions, side))
        )
        points[f"{p}_hip"] = hip_t[:3, 3].copy()
        points[f"{p}_knee"] = knee_t[:3, 3].copy()
        points[f"{p}_ankle"] = ankle_t[:3, 3].copy()
        points[f"{p}_foot"] = sole_t[:3, 3].copy()
    return points
