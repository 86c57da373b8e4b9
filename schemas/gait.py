"""Units of the gait parameters, as the walking engine and ``config/walking.toml`` use them
(the framework's own: lengths mm, angles degrees, times ms). Every UI shows them beside the
values, so nobody has to guess whether ``foot_height = 40`` is millimetres."""

from __future__ import annotations

GAIT_PARAM_UNITS: dict[str, str] = {
    "x_offset": "mm",
    "y_offset": "mm",
    "z_offset": "mm",
    "roll_offset": "°",
    "pitch_offset": "°",
    "yaw_offset": "°",
    "hip_pitch_offset": "°",
    "period_time": "ms",
    "foot_height": "mm",
    "swing_right_left": "mm",
    "swing_top_down": "mm",
    "pelvis_offset": "°",
    "arm_swing_gain": "°/mm",
    "balance_filter": "s",
    "balance_limit": "°",
    "max_x": "mm",
    "max_y": "mm",
    "max_turn": "°",
    "accel_x": "mm",
    "accel_y": "mm",
    "accel_turn": "°",
    "ready_time": "s",
}


def gait_label(name: str) -> str:
    """``foot_height (mm)``; ratios and gains have no unit and keep their bare name."""
    unit = GAIT_PARAM_UNITS.get(name)
    return f"{name} ({unit})" if unit else name
