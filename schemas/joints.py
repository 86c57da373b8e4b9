"""The 20 joints' names by servo id 1..20: the names ``config/robot.toml`` gives them (the
ROBOTIS framework's JointData order). Clients that must name joints without asking the daemon
(page files, the policy contract) use this one tuple; tests/unit/test_pages_editor.py checks
that the shipped config agrees."""

from __future__ import annotations

JOINT_NAMES: tuple[str, ...] = (
    "r_shoulder_pitch",
    "l_shoulder_pitch",
    "r_shoulder_roll",
    "l_shoulder_roll",
    "r_elbow",
    "l_elbow",
    "r_hip_yaw",
    "l_hip_yaw",
    "r_hip_roll",
    "l_hip_roll",
    "r_hip_pitch",
    "l_hip_pitch",
    "r_knee",
    "l_knee",
    "r_ankle_pitch",
    "l_ankle_pitch",
    "r_ankle_roll",
    "l_ankle_roll",
    "head_pan",
    "head_tilt",
)
JOINT_IDS: tuple[int, ...] = tuple(range(1, len(JOINT_NAMES) + 1))
