"""Gait parameters: the framework's [Walking Config] plus command limits, from
``config/walking.toml`` and changeable at run time (``walk_params`` verb)."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields
from typing import Any

from config.loader import RANGE, nearest, range_problem, ranged


@dataclass
class WalkParams:
    """Every number with its allowed range: ``ranged(default, low, high)``."""

    x_offset: float = ranged(-10.0, -50, 50)
    y_offset: float = ranged(5.0, -30, 50)
    z_offset: float = ranged(20.0, 0, 80)
    roll_offset: float = ranged(0.0, -15, 15)
    pitch_offset: float = ranged(0.0, -15, 15)
    yaw_offset: float = ranged(0.0, -15, 15)
    hip_pitch_offset: float = ranged(13.0, -20, 40)
    period_time: float = ranged(600.0, 200, 2000)
    dsp_ratio: float = ranged(0.1, 0.0, 0.6)
    step_forward_back_ratio: float = ranged(0.28, 0, 1)
    foot_height: float = ranged(40.0, 0, 80)
    swing_right_left: float = ranged(20.0, 0, 60)
    swing_top_down: float = ranged(5.0, 0, 30)
    pelvis_offset: float = ranged(3.0, -10, 10)
    arm_swing_gain: float = ranged(1.5, 0, 5)
    balance_enable: bool = True
    balance_knee_gain: float = ranged(0.3, -5, 5)
    balance_ankle_pitch_gain: float = ranged(0.9, -5, 5)
    balance_hip_roll_gain: float = ranged(0.5, -5, 5)
    balance_ankle_roll_gain: float = ranged(1.0, -5, 5)
    balance_filter: float = ranged(0.1, 0, 2)
    balance_limit: float = ranged(3.0, 0, 30)
    p_gain: int = ranged(32, 0, 254)
    i_gain: int = ranged(0, 0, 254)
    d_gain: int = ranged(0, 0, 254)
    max_x: float = ranged(40.0, 0, 80)
    max_y: float = ranged(40.0, 0, 80)
    max_turn: float = ranged(30.0, 0, 45)
    accel_x: float = ranged(10.0, 0.5, 80)
    accel_y: float = ranged(10.0, 0.5, 80)
    accel_turn: float = ranged(10.0, 0.5, 45)
    ready_time: float = ranged(0.6, 0, 5)

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


_FIELDS = {f.name: f for f in fields(WalkParams)}


def check(name: str, value: Any) -> Any:
    if name not in _FIELDS:
        near = nearest(str(name), _FIELDS)
        raise ValueError(
            f"unknown walking parameter {name!r} (nearest known: {near!r}); "
            f"known: {', '.join(_FIELDS)}"
        )
    found = _FIELDS[name]
    if found.type in ("bool", bool):
        if not isinstance(value, bool):
            raise ValueError(f"walking parameter {name} must be true or false, got {value!r}")
        return value
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise ValueError(f"walking parameter {name} must be a number, got {value!r}")
    problem = range_problem(value, *found.metadata.get(RANGE, (None, None)))
    if problem:
        raise ValueError(f"walking parameter {name}={value!r} must be {problem}")
    if found.type in ("int", int):
        if value != int(value):
            raise ValueError(f"walking parameter {name} must be an integer, got {value!r}")
        return int(value)
    return float(value)
