"""The gait's float IK (``leg_ik_end_point``) against the matrix one (``leg_ik`` of
``foot_target``), on random end points across the reachable workspace and beyond."""

from __future__ import annotations

import math
import random

import numpy as np

from robot_daemon.motion.walking.ik import foot_target, leg_ik, leg_ik_end_point


def test_scalar_ik_matches_matrix_ik_on_random_end_points() -> None:
    rng = random.Random(30)
    reached = unreachable = 0
    for _ in range(20000):
        point = (
            rng.uniform(-0.12, 0.12),
            rng.uniform(-0.12, 0.12),
            rng.uniform(-0.03, 0.2),
            rng.uniform(-1.2, 1.2),
            rng.uniform(-1.2, 1.2),
            rng.uniform(-1.5, 1.5),
        )
        want = leg_ik(foot_target(*point))
        got = leg_ik_end_point(*point)
        if want is None:
            assert got is None, point
            unreachable += 1
            continue
        assert got is not None, point
        reached += 1
        for a, b in zip(got, want, strict=True):
            d = math.remainder(a - b, 2 * math.pi)
            assert abs(d) < 1e-9, (point, got, want)
    assert reached > 5000 and unreachable > 100


def _matrix_leg_servo_angles(side, end_point, hip_pitch_offset=0.0):
    """``leg_servo_angles`` as it was before the float IK: the reference."""
    from schemas.kinematics import leg_angles_to_servo

    angles = leg_ik(foot_target(*end_point))
    if angles is None:
        return None
    servo = leg_angles_to_servo(angles, side)
    servo[11 if side == "right" else 12] -= (1.0 if side == "right" else -1.0) * hip_pitch_offset
    return servo


def _walk_goals(commands: list[tuple[float, float, float]]) -> list[dict[int, float]]:
    from tests.unit.test_motion_walking import Rig

    rig = Rig()
    rng = random.Random(7)
    rig.walk.start(*commands[0])
    for cmd in commands:
        rig.walk.set_speed(*cmd)
        for _ in range(150):
            rig.gyro = np.array([512 + rng.randint(-40, 40) for _ in range(3)])  # as read
            rig.run(1)
    return rig.goals


def test_gait_goals_unchanged_by_the_float_ik(monkeypatch) -> None:
    """Every goal of a walk through forward, sideways, turning and mixed commands (with gyro
    feedback) equals what the matrix IK gives, to rounding."""
    import numpy as np

    from robot_daemon.motion.walking import gait

    commands = [(0.1, 0.0, 0.0), (0.0, 0.05, 0.0), (0.0, 0.0, 0.5), (-0.05, -0.03, -0.4)]
    commands += [(0.08, 0.04, 0.3), (0.0, 0.0, 0.0)]
    new = _walk_goals(commands)
    monkeypatch.setattr(gait, "leg_servo_angles", _matrix_leg_servo_angles)
    old = _walk_goals(commands)
    assert len(new) == len(old) > 800
    for g_new, g_old in zip(new, old, strict=True):
        assert g_new.keys() == g_old.keys()
        ids = sorted(g_new)
        assert np.allclose([g_new[j] for j in ids], [g_old[j] for j in ids], rtol=0, atol=1e-9)


def test_leg_servo_angles_are_the_leg_angles_turned_to_servos() -> None:
    """The gait's servo angles of a leg are ``leg_angles_to_servo`` of its IK with the hip
    pitch offset, to the bit (the shortcut maps the directions in one call)."""
    from robot_daemon.motion.walking.ik import leg_servo_angles
    from schemas.kinematics import leg_angles_to_servo

    rng = random.Random(31)
    for _ in range(5000):
        x, y, z = rng.uniform(-0.08, 0.08), rng.uniform(-0.08, 0.08), rng.uniform(-0.02, 0.12)
        point = (x, y, z, rng.uniform(-0.6, 0.6), rng.uniform(-0.6, 0.6), rng.uniform(-0.6, 0.6))
        side = rng.choice(["right", "left"])
        offset = rng.uniform(-0.3, 0.3)
        angles = leg_ik_end_point(*point)
        got = leg_servo_angles(side, point, offset)  # type: ignore[arg-type]
        if angles is None:
            assert got is None
            continue
        want = leg_angles_to_servo(angles, side)  # type: ignore[arg-type]
        want[11 if side == "right" else 12] -= (1.0 if side == "right" else -1.0) * offset
        assert repr(got) == repr(want)
