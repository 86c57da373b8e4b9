"""The gait's balance: the ROBOTIS framework's gyro feedback (Walking.cpp) on the hip roll, knee,
ankle pitch and ankle roll goals of a walking tick."""

from __future__ import annotations

import math

from robot_daemon.frames import JointFrame
from robot_daemon.motion.walking.params import WalkParams
from schemas.units import RAD_PER_UNIT

# Framework servo directions used by the gyro feedback (Walking.cpp ``dir``).
_DIR = {9: -1, 10: -1, 13: 1, 14: -1, 15: -1, 16: 1, 17: 1, 18: 1}
# Each term's sign below, joints 9, 10, 13 … 18 in order (the compiled pose's, gait.py).
FEEDBACK_SIGNS = (_DIR[9], _DIR[10], -_DIR[13], -_DIR[14], -_DIR[15], -_DIR[16], -_DIR[17],
                  -_DIR[18])


def gyro_feedback(
    goals: dict[int, float], frame: JointFrame, p: WalkParams, filtered: list[float]
) -> list[float]:
    """The framework's gyro feedback (servo units per count × gain × 4), low-passed over
    ``balance_filter`` s and limited to ``balance_limit`` degrees per joint: on a body
    without compliance (the simulator) the raw law feeds its own correction back.

    Adds the corrections to ``goals``; ``filtered`` is the low-passed gyro (right/left,
    front/back counts) of the previous tick, and the return value this tick's."""
    # Relative to the centres measured at start (motion/gyro_centre.py); stale adds nothing.
    # Plain floats (one tolist each): this runs every walking tick, and numpy's scalars and a
    # dict of terms cost more than the arithmetic (docs/loop-cpu.md).
    if frame.imu_valid:
        gyro, centre = frame.gyro_raw.tolist(), frame.gyro_centre.tolist()
        r_rl, r_fb = float(gyro[0] - centre[0]), float(gyro[1] - centre[1])
    else:
        r_rl = r_fb = 0.0
    a = 1.0 if p.balance_filter <= 0 else min(1.0, frame.dt / (p.balance_filter + frame.dt))
    f_rl, f_fb = filtered
    rl = f_rl + (r_rl - f_rl) * a
    fb = f_fb + (r_fb - f_fb) * a
    unit = RAD_PER_UNIT  # the framework adds servo units
    limit = math.radians(p.balance_limit)
    hip, knee = p.balance_hip_roll_gain, p.balance_knee_gain
    pitch, roll = p.balance_ankle_pitch_gain, p.balance_ankle_roll_gain
    # term · dir (Walking.cpp), clamped to ±limit as max(-limit, min(limit, ·)) does.
    for j, term in (
        (9, _DIR[9] * rl * hip),
        (10, _DIR[10] * rl * hip),
        (13, -_DIR[13] * fb * knee),
        (14, -_DIR[14] * fb * knee),
        (15, -_DIR[15] * fb * pitch),
        (16, -_DIR[16] * fb * pitch),
        (17, -_DIR[17] * rl * roll),
        (18, -_DIR[18] * rl * roll),
    ):
        v = term * 4 * unit
        v = v if v < limit else limit
        goals[j] += v if v > -limit else -limit
    return [rl, fb]
