"""Closed-form leg inverse kinematics, the exact inverse of ``schemas.kinematics.leg_fk_angles``.

The foot target is the pose of the sole relative to the hip point (m, rad). As in the ROBOTIS
framework the knee comes from the law of cosines on the hip–ankle distance; then the ankle roll
puts the hip in the shank's pitch plane, and hip yaw/roll and the pitch sum fall out of the
remaining rotation. Unlike the framework's version this one is exact (FK(IK(p)) == p), which
matters for odometry in the simulator.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from operator import mul
from typing import cast

import numpy as np

from robot_daemon import hotpath
from schemas.kinematics import (
    ANKLE_LENGTH,
    CALF_LENGTH,
    LEG_DIRECTION,
    LEG_IDS,
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


_TAU = 2 * math.pi
# Each leg's servo ids and directions (schemas.kinematics), for leg_servo_angles.
# Each leg's servo ids and directions, by side (the compiled pose's too, gait.py).
LEG_SERVOS = _LEG_SERVOS = {side: (LEG_IDS[side], LEG_DIRECTION[side]) for side in LEG_IDS}


def foot_target(x: float, y: float, z: float, roll: float, pitch: float, yaw: float) -> np.ndarray:
    """The framework's foot end point (``Walking::computeIK`` arguments, here in m and rad):
    ``z`` is how far the sole is raised from the fully stretched leg."""
    t = np.eye(4)
    t[:3, :3] = rpy_matrix(roll, pitch, yaw)
    t[:3, 3] = (x, y, z - LEG_LENGTH)
    return t


def leg_ik_end_point_py(
    x: float, y: float, z: float, roll: float, pitch: float, yaw: float
) -> LegAngles | None:
    """:func:`leg_ik` of :func:`foot_target` in plain float arithmetic, for the gait's 8 ms
    tick: numpy's per-call overhead on 3×3 matrices cost more than the maths (issue #30). The
    same steps as :func:`leg_ik`, each matrix product written out (equal to it to rounding;
    ``tests/unit/test_ik_scalar.py`` compares them). The definition of
    :func:`leg_ik_end_point`, which is this compiled where the C extension is built
    (``robot_daemon/_hotpath.c``: the same bits, ``tests/unit/test_hotpath.py``)."""
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    # r = Rz(yaw)·Ry(pitch)·Rx(roll)
    r00, r01, r02 = cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr
    r10, r11, r12 = sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr
    r21, r22 = cp * sr, cp * cr  # (r20 = -sp is not needed)
    ax = x + r02 * ANKLE_LENGTH
    ay = y + r12 * ANKLE_LENGTH
    az = z - LEG_LENGTH + r22 * ANKLE_LENGTH
    dist2 = ax * ax + ay * ay + az * az
    cos_knee = (dist2 - THIGH_LENGTH**2 - CALF_LENGTH**2) / (2 * THIGH_LENGTH * CALF_LENGTH)
    if not -1.0 <= cos_knee <= 1.0 or dist2 < 1e-12:
        return None
    knee = math.acos(cos_knee)
    v1 = -(r01 * ax + r11 * ay + r21 * az)
    v2 = -(r02 * ax + r12 * ay + r22 * az)
    ankle_roll = math.atan2(v1, v2) if v2 >= 0 else math.atan2(-v1, -v2)
    ca, sa = math.cos(ankle_roll), math.sin(ankle_roll)
    # r_shank = r·Rx(-ankle_roll): columns 1 and 2 turn, column 0 stays
    s01, s11, s21 = r01 * ca - r02 * sa, r11 * ca - r12 * sa, r21 * ca - r22 * sa
    s02, s12 = r01 * sa + r02 * ca, r11 * sa + r12 * ca
    hip_yaw = math.atan2(-s01, s11)
    cw, sw = math.cos(hip_yaw), math.sin(hip_yaw)
    # m = Rz(-yaw)·r_shank = Rx(roll)·Ry(pitch sum)
    hip_roll = math.atan2(s21, cw * s11 - sw * s01)
    pitch_sum = math.atan2(cw * s02 + sw * s12, cw * r00 + sw * r10)
    # q = Rx(-roll)·Rz(-yaw)·ankle (x and z only)
    p1 = cw * ay - sw * ax
    q0 = cw * ax + sw * ay
    q2 = math.cos(hip_roll) * az - math.sin(hip_roll) * p1
    ux = -CALF_LENGTH * math.sin(knee)
    uz = -THIGH_LENGTH - CALF_LENGTH * math.cos(knee)
    # _wrap written out (two Python calls a leg fewer; the same operations in the same order)
    pi = math.pi
    hip_pitch = (math.atan2(q0, q2) - math.atan2(ux, uz) + pi) % _TAU - pi
    ankle_pitch = (pitch_sum - hip_pitch - knee + pi) % _TAU - pi
    return (hip_yaw, hip_roll, hip_pitch, knee, ankle_pitch, ankle_roll)


leg_ik_end_point: Callable[[float, float, float, float, float, float], LegAngles | None]
if hotpath.compiled is not None:
    hotpath.compiled.configure_leg(
        ANKLE_LENGTH, LEG_LENGTH, THIGH_LENGTH**2, CALF_LENGTH**2, 2 * THIGH_LENGTH * CALF_LENGTH,
        CALF_LENGTH, THIGH_LENGTH, math.pi, _TAU, leg_ik_end_point_py,
    )
    leg_ik_end_point = hotpath.compiled.leg_ik_end_point
else:
    leg_ik_end_point = leg_ik_end_point_py
# The whole of leg_servo_angles below once its side is looked up, compiled (the same bits:
# tests/unit/test_hotpath.py); None where the extension is not built.
_servo_angles = hotpath.compiled.leg_servo_angles if hotpath.compiled is not None else None


def leg_servo_angles(
    side: Side, end_point: Sequence[float], hip_pitch_offset: float = 0.0
) -> dict[int, float] | None:
    """Servo angles {id: rad} for a framework end point (x, y, z, roll, pitch, yaw) of one leg,
    with the framework's hip pitch offset (leans the body forward); None if unreachable."""
    leg = _LEG_SERVOS.get(side)
    if _servo_angles is not None and leg is not None:
        # the hip pitch is the third of a leg's servos (LEG_IDS: yaw, roll, pitch, …)
        shift = (1.0 if side == "right" else -1.0) * hip_pitch_offset
        compiled = _servo_angles(end_point, leg[0], leg[1], 2, shift)
        if compiled is not NotImplemented:
            return cast("dict[int, float] | None", compiled)
    angles = leg_ik_end_point(*end_point)
    if angles is None:
        return None
    if leg is None:
        servo = leg_angles_to_servo(angles, side)  # which says what is wrong with ``side``
    else:  # leg_angles_to_servo on the IK's floats in one C call: the same products
        servo = dict(zip(leg[0], map(mul, leg[1], angles), strict=True))
    pitch_id = 11 if side == "right" else 12
    direction = 1.0 if side == "right" else -1.0
    servo[pitch_id] -= direction * hip_pitch_offset
    return servo
