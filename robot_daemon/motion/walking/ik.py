"""Closed-form leg inverse kinematics, the exact inverse of ``schemas.kinematics.leg_fk_angles``.

The foot target is the pose of the sole relative to the hip point (m, rad). As in the ROBOTIS
framework the knee comes from the law of cosines on the hip–ankle distance; then the ankle roll
puts the hip in the shank's pitch plane, and hip yaw/roll and the pitch sum fall out of the
remaining rotation. Unlike the framework's version this one is exact (FK(IK(p)) == p), which
matters for odometry in the simulator.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from schemas.kinematics import (
    ANKLE_LENGTH,
    CALF_LENGTH,
    LEG_LENGTH,
    THIGH_LENGTH,
    Side,
    leg_angles_to_servo,
    rot_x,
    rot_z,
    rpy_matrix,
)

LegAngles = tuple[float, float, float, float, float, float]


def leg_ik(target: np.ndarray) -> LegAngles | None:
    """Leg angles (yaw, roll, pitch, knee, ankle pitch, ankle roll) putting the sole at
    ``target`` (4×4 pose relative to the hip point), or None when it is out of reach."""
    r = target[:3, :3]
    ankle = target[:3, 3] + r @ np.array([0.0, 0.0, ANKLE_LENGTH])
    dist2 = float(ankle @ ankle)
    cos_knee = (dist2 - THIGH_LENGTH**2 - CALF_LENGTH**2) / (2 * THIGH_LENGTH * CALF_LENGTH)
    if not -1.0 <= cos_knee <= 1.0 or dist2 < 1e-12:
        return None
    knee = math.acos(cos_knee)
    # The hip seen from the ankle, in the foot's frame: the ankle roll brings it into the shank's
    # pitch plane (y = 0); of the two rolls that do, the one within ±90° (a real ankle's range).
    v = -(r.T @ ankle)
    ankle_roll = math.atan2(v[1], v[2]) if v[2] >= 0 else math.atan2(-v[1], -v[2])
    r_shank = r @ rot_x(-ankle_roll)  # = Rz(yaw)·Rx(roll)·Ry(pitch sum)
    yaw = math.atan2(-r_shank[0, 1], r_shank[1, 1])
    m = rot_z(-yaw) @ r_shank  # = Rx(roll)·Ry(pitch sum)
    roll = math.atan2(m[2, 1], m[1, 1])
    pitch_sum = math.atan2(m[0, 2], m[0, 0])
    # Ankle point in the frame after hip yaw and roll: Ry(hip pitch) applied to the bent leg.
    q = rot_x(-roll) @ rot_z(-yaw) @ ankle
    ux = -CALF_LENGTH * math.sin(knee)
    uz = -THIGH_LENGTH - CALF_LENGTH * math.cos(knee)
    hip_pitch = _wrap(math.atan2(q[0], q[2]) - math.atan2(ux, uz))
    ankle_pitch = _wrap(pitch_sum - hip_pitch - knee)
    return (yaw, roll, hip_pitch, knee, ankle_pitch, ankle_roll)


def _wrap(a: float) -> float:
    return (a + math.pi) % (2 * math.pi) - math.pi


def foot_target(x: float, y: float, z: float, roll: float, pitch: float, yaw: float) -> np.ndarray:
    """The framework's foot end point (``Walking::computeIK`` arguments, here in m and rad):
    ``z`` is how far the sole is raised from the fully stretched leg."""
    t = np.eye(4)
    t[:3, :3] = rpy_matrix(roll, pitch, yaw)
    t[:3, 3] = (x, y, z - LEG_LENGTH)
    return t


def leg_servo_angles(
    side: Side, end_point: Sequence[float], hip_pitch_offset: float = 0.0
) -> dict[int, float] | None:
    """Servo angles {id: rad} for a framework end point (x, y, z, roll, pitch, yaw) of one leg,
    with the framework's hip pitch offset (leans the body forward); None if unreachable."""
    angles = leg_ik(foot_target(*end_point))
    if angles is None:
        return None
    servo = leg_angles_to_servo(angles, side)
    pitch_id = 11 if side == "right" else 12
    direction = 1.0 if side == "right" else -1.0
    servo[pitch_id] -= direction * hip_pitch_offset
    return servo
