"""Forward kinematics and the walking engine's leg IK (its exact inverse)."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from robot_daemon.motion.walking.ik import foot_target, leg_ik, leg_servo_angles
from schemas import kinematics as K


def _zero() -> np.ndarray:
    return np.zeros(21)


def test_stretched_legs_hang_straight_below_the_hips() -> None:
    for side in K.SIDES:
        foot = K.leg_fk(_zero(), side)
        np.testing.assert_allclose(foot[:3, 3], K.hip_point(side) - [0, 0, K.LEG_LENGTH])
        np.testing.assert_allclose(foot[:3, :3], np.eye(3), atol=1e-12)
    assert K.hip_point("left")[1] == pytest.approx(0.037)
    assert K.hip_point("right")[1] == pytest.approx(-0.037)


def test_mirrored_servos_give_mirrored_feet() -> None:
    """The same servo angles on both sides, negated on one, are a mirror image (hardware.md)."""
    pos = _zero()
    for r_id, l_id, deg in [(7, 8, 10), (9, 10, 8), (11, 12, -30), (13, 14, 50), (15, 16, 20)]:
        pos[r_id] = math.radians(deg)
        pos[l_id] = -math.radians(deg)
    right = K.leg_fk(pos, "right")[:3, 3]
    left = K.leg_fk(pos, "left")[:3, 3]
    np.testing.assert_allclose(right * [1, -1, 1], left, atol=1e-12)


def test_signs_follow_the_framework() -> None:
    """Knee bend raises the foot; right hip pitch < 0 (servo) swings the right thigh forward;
    right hip roll > 0 (servo) moves the right foot outward (−y)."""
    pos = _zero()
    pos[11] = math.radians(-30)
    assert K.leg_fk(pos, "right")[0, 3] > K.hip_point("right")[0] + 0.05
    pos = _zero()
    pos[12] = math.radians(30)  # left mirrored
    assert K.leg_fk(pos, "left")[0, 3] > K.hip_point("left")[0] + 0.05
    pos = _zero()
    pos[9] = math.radians(20)
    assert K.leg_fk(pos, "right")[1, 3] < K.hip_point("right")[1] - 0.05
    pos = _zero()
    pos[13], pos[11], pos[15] = math.radians(60), math.radians(-30), math.radians(30)
    foot = K.leg_fk(pos, "right")
    assert foot[2, 3] > K.hip_point("right")[2] - K.LEG_LENGTH + 0.01
    np.testing.assert_allclose(foot[:3, :3], np.eye(3), atol=1e-12)  # flat: -30 + 60 - 30


GRID = list(
    itertools.product(
        (-0.04, 0.0, 0.05),  # x
        (-0.03, 0.0, 0.03),  # y
        (0.02, 0.05, 0.09),  # z: raised from the stretched leg
        (-0.15, 0.0, 0.2),  # roll
        (-0.2, 0.0, 0.15),  # pitch
        (-0.3, 0.0, 0.35),  # yaw
    )
)


@pytest.mark.parametrize("side", K.SIDES)
def test_fk_of_ik_lands_the_foot_where_asked(side: K.Side) -> None:
    for x, y, z, roll, pitch, yaw in GRID:
        target = foot_target(x, y, z, roll, pitch, yaw)
        servo = leg_servo_angles(side, (x, y, z, roll, pitch, yaw))
        assert servo is not None, (x, y, z, roll, pitch, yaw)
        pose = K.leg_fk(servo, side)
        hip = K.transform(translation=K.hip_point(side))
        np.testing.assert_allclose(pose, hip @ target, atol=1e-9)


def test_ik_recovers_the_angles_that_made_the_pose() -> None:
    rng = np.random.default_rng(4)
    for _ in range(300):
        angles = (
            rng.uniform(-0.5, 0.5),
            rng.uniform(-0.4, 0.4),
            rng.uniform(-1.2, 0.4),
            rng.uniform(0.05, 2.0),
            rng.uniform(-1.0, 1.0),
            rng.uniform(-0.4, 0.4),
        )
        back = leg_ik(K.leg_fk_angles(angles))
        assert back is not None
        np.testing.assert_allclose(back, angles, atol=1e-9)


def test_unreachable_targets_give_none() -> None:
    assert leg_ik(foot_target(0.0, 0.0, -0.01, 0, 0, 0)) is None  # below the stretched leg
    assert leg_ik(foot_target(0.3, 0.0, 0.0, 0, 0, 0)) is None  # far ahead
    assert leg_servo_angles("left", (0.0, 0.2, 0.1, 0, 0, 0)) is None  # far to the side


def test_camera_looks_level_at_tilt_equal_to_the_eye_offset() -> None:
    pos = _zero()
    pos[20] = K.EYE_TILT_OFFSET
    cam = K.camera_pose(pos)
    np.testing.assert_allclose(cam[:3, :3], np.eye(3), atol=1e-12)
    np.testing.assert_allclose(
        cam[:3, 3], [K.CAMERA_DISTANCE, 0, K.NECK_HEIGHT + K.CAMERA_HEIGHT], atol=1e-12
    )
    pos[20] = 0.0  # servo zero: looking 40° down
    axis = K.camera_pose(pos)[:3, 0]
    assert math.degrees(math.atan2(-axis[2], axis[0])) == pytest.approx(40.0)
    pos[19] = math.radians(30)  # pan left
    axis = K.camera_pose(pos)[:3, 0]
    assert math.degrees(math.atan2(axis[1], axis[0])) == pytest.approx(30.0)


def test_skeleton_names_every_point_and_bones_join_known_points() -> None:
    pts = K.skeleton(_zero())
    for a, b in K.SKELETON_BONES:
        assert a in pts and b in pts
    for name in ("torso", "neck", "head", "r_hip", "l_knee", "r_ankle", "l_foot", "r_hand"):
        assert pts[name].shape == (3,)
    assert pts["l_hip"][1] > 0 > pts["r_hip"][1]
    assert pts["l_shoulder"][1] > 0 > pts["r_shoulder"][1]
    assert pts["head"][2] > pts["neck"][2] > pts["torso"][2] > pts["l_hip"][2] > pts["l_foot"][2]
    # At pitch 0 the roll axis sits at the fixed offset from the pitch axis.
    roll_axis = pts["r_shoulder"] + np.array(K.SHOULDER_ROLL_OFFSET) * [1, -1, 1]
    upper = np.linalg.norm(pts["r_elbow"] - roll_axis)
    assert upper == pytest.approx(math.hypot(K.UPPER_ARM_LENGTH, K.UPPER_ARM_FORWARD))
    assert np.linalg.norm(pts["l_hand"] - pts["l_elbow"]) == pytest.approx(K.FOREARM_LENGTH)


def test_arms_are_mirror_images_for_negated_servo_angles() -> None:
    pos = _zero()
    pos[1], pos[2] = 0.5, -0.5
    pos[3], pos[4] = -0.3, 0.3
    pos[5], pos[6] = 0.4, -0.4
    pts = K.skeleton(pos)
    np.testing.assert_allclose(pts["r_hand"] * [1, -1, 1], pts["l_hand"], atol=1e-12)
    assert pts["r_hand"][0] > pts["r_shoulder"][0]  # +pitch on the right swings forward


def test_positions_may_be_a_mapping_and_bad_side_is_refused() -> None:
    foot = K.leg_fk({13: 0.5}, "right")
    assert foot[2, 3] > K.hip_point("right")[2] - K.LEG_LENGTH
    with pytest.raises(ValueError, match="side"):
        K.leg_fk(_zero(), "middle")  # type: ignore[arg-type]
