"""The gait's balance: the ROBOTIS framework's gyro feedback (Walking.cpp) on the hip roll, knee,
ankle pitch and ankle roll goals of a walking tick."""

from __future__ import annotations

import math

from robot_daemon.frames import JointFrame
from robot_daemon.motion.walking.params import WalkParams
from schemas.units import RAD_PER_UNIT

# Framework servo directions used by the gyro feedback (Walking.cpp ``dir``).
_DIR = {9: -1, 10: -1, 13: 1, 14: -1, 15: -1, 16: 1, 17: 1, 18: 1}


def gyro_feedback(
    goals: dict[int, float], frame: JointFrame, p: WalkParams, filtered: list[float]
) -> list[float]:
    """The framework's gyro feedback (servo units per count × gain × 4), low-passed over
    ``balance_filter`` s and limited to ``balance_limit`` degrees per joint: on a body
    without compliance (the simulator) the raw law feeds its own correction back.

    Adds the corrections to ``goals``; ``filtered`` is the low-passed gyro (right/left,
    front/back counts) of the previous tick, and the return value this tick's."""
    # Relative to the centres measured at start (motion/gyro_centre.py); stale adds nothing.
    centre = frame.gyro_centre
    raw = (
        (float(frame.gyro_raw[0] - centre[0]), float(frame.gyro_raw[1] - centre[1]))
        if frame.imu_valid
        else (0.0, 0.0)
    )
    a = 1.0 if p.balance_filter <= 0 else min(1.0, frame.dt / (p.balance_filter + frame.dt))
    filtered = [f + (r - f) * a for f, r in zip(filtered, raw, strict=True)]
    rl, fb = filtered
    unit = RAD_PER_UNIT  # the framework adds servo units
    limit = math.radians(p.balance_limit)
    terms = {
        9: _DIR[9] * rl * p.balance_hip_roll_gain,
        10: _DIR[10] * rl * p.balance_hip_roll_gain,
        13: -_DIR[13] * fb * p.balance_knee_gain,
        14: -_DIR[14] * fb * p.balance_knee_gain,
        15: -_DIR[15] * fb * p.balance_ankle_pitch_gain,
        16: -_DIR[16] * fb * p.balance_ankle_pitch_gain,
        17: -_DIR[17] * rl * p.balance_ankle_roll_gain,
        18: -_DIR[18] * rl * p.balance_ankle_roll_gain,
    }
    for j, term in terms.items():
        goals[j] += max(-limit, min(limit, term * 4 * unit))
    return filtered
