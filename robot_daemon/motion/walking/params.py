"""Gait parameters: the framework's [Walking Config] plus command limits, from
``config/walking.toml`` and changeable at run time (``walk_params`` verb)."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields
from typing import Any

from config.loader import nearest


@dataclass
class WalkParams:
    x_offset: float = -10.0
    y_offset: float = 5.0
    z_offset: float = 20.0
    roll_offset: float = 0.0
    pitch_offset: float = 0.0
    yaw_offset: float = 0.0
    hip_pitch_offset: float = 13.0
    period_time: float = 600.0
    dsp_ratio: float = 0.1
    step_forward_back_ratio: float = 0.28
    foot_height: float = 40.0
    swing_right_left: float = 20.0
    swing_top_down: float = 5.0
    pelvis_offset: float = 3.0
    arm_swing_gain: float = 1.5
    balance_enable: bool = True
    balance_knee_gain: float = 0.3
    balance_ankle_pitch_gain: float = 0.9
    balance_hip_roll_gain: float = 0.5
    balance_ankle_roll_gain: float = 1.0
    balance_filter: float = 0.1
    balance_limit: float = 3.0
    p_gain: int = 32
    i_gain: int = 0
    d_gain: int = 0
    max_x: float = 40.0
    max_y: float = 40.0
    max_turn: float = 30.0
    accel_x: float = 10.0
    accel_y: float = 10.0
    accel_turn: float = 10.0
    ready_time: float = 0.6

    @classmethod
    def from_config(cls, section: dict[str, Any] | None) -> WalkParams:
        params = cls()
        params.update(section or {})
        return params

    def update(self, changes: dict[str, Any]) -> dict[str, Any]:
        """Apply changes after checking all of them; ``ValueError`` (naming the parameter)
        leaves every value as it was. Returns what was applied."""
        checked = {name: check(name, value) for name, value in changes.items()}
        for name, value in checked.items():
            setattr(self, name, value)
        return checked

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


# name → (low, high); bools and gains are typed below.
RANGES: dict[str, tuple[float, float]] = {
    "x_offset": (-50, 50),
    "y_offset": (-30, 50),
    "z_offset": (0, 80),
    "roll_offset": (-15, 15),
    "pitch_offset": (-15, 15),
    "yaw_offset": (-15, 15),
    "hip_pitch_offset": (-20, 40),
    "period_time": (200, 2000),
    "dsp_ratio": (0.0, 0.6),
    "step_forward_back_ratio": (0, 1),
    "foot_height": (0, 80),
    "swing_right_left": (0, 60),
    "swing_top_down": (0, 30),
    "pelvis_offset": (-10, 10),
    "arm_swing_gain": (0, 5),
    "balance_knee_gain": (-5, 5),
    "balance_ankle_pitch_gain": (-5, 5),
    "balance_hip_roll_gain": (-5, 5),
    "balance_ankle_roll_gain": (-5, 5),
    "balance_filter": (0, 2),
    "balance_limit": (0, 30),
    "p_gain": (0, 254),
    "i_gain": (0, 254),
    "d_gain": (0, 254),
    "max_x": (0, 80),
    "max_y": (0, 80),
    "max_turn": (0, 45),
    "accel_x": (0.5, 80),
    "accel_y": (0.5, 80),
    "accel_turn": (0.5, 45),
    "ready_time": (0, 5),
}
_TYPES = {f.name: f.type for f in fields(WalkParams)}


def check(name: str, value: Any) -> Any:
    if name not in _TYPES:
        near = nearest(str(name), _TYPES)
        raise ValueError(
            f"unknown walking parameter {name!r} (nearest known: {near!r}); "
            f"known: {', '.join(_TYPES)}"
        )
    kind = _TYPES[name]
    if kind in ("bool", bool):
        if not isinstance(value, bool):
            raise ValueError(f"walking parameter {name} must be true or false, got {value!r}")
        return value
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise ValueError(f"walking parameter {name} must be a number, got {value!r}")
    low, high = RANGES[name]
    if not low <= value <= high:
        raise ValueError(f"walking parameter {name}={value!r} is outside {low}..{high}")
    if kind in ("int", int):
        if value != int(value):
            raise ValueError(f"walking parameter {name} must be an integer, got {value!r}")
        return int(value)
    return float(value)
