"""Field checks for verb handlers. Each raises :class:`Reject` naming the field and echoing at
most a short prefix of the value (:func:`schemas.errors.brief`)."""

from __future__ import annotations

import math
from typing import Any

from config.loader import JointConfig, RobotConfig
from schemas.errors import ErrorCode, Reject, brief

_MISSING = object()


def present(fields: dict[str, Any], name: str) -> Any:
    value = fields.get(name, _MISSING)
    if value is _MISSING or value is None:
        raise Reject(ErrorCode.INVALID, f"missing field {name!r}", name)
    return value


def number(
    fields: dict[str, Any],
    name: str,
    low: float | None = None,
    high: float | None = None,
    default: Any = _MISSING,
) -> float:
    if default is not _MISSING and fields.get(name) is None:
        return default
    value = present(fields, name)
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise Reject(ErrorCode.INVALID, f"{name} must be a number, got {brief(value)}", name)
    if not math.isfinite(value):
        raise Reject(ErrorCode.INVALID, f"{name} must be finite, got {brief(value)}", name)
    _within(name, value, low, high)
    return float(value)


def integer(
    fields: dict[str, Any],
    name: str,
    low: int | None = None,
    high: int | None = None,
    default: Any = _MISSING,
) -> int:
    if default is not _MISSING and fields.get(name) is None:
        return default
    value = present(fields, name)
    if isinstance(value, bool) or not isinstance(value, int):
        raise Reject(ErrorCode.INVALID, f"{name} must be an integer, got {brief(value)}", name)
    _within(name, value, low, high)
    return value


def _within(name: str, value: float, low: float | None, high: float | None) -> None:
    if (low is not None and value < low) or (high is not None and value > high):
        raise Reject(
            ErrorCode.OUT_OF_RANGE, f"{name}={brief(value)} is outside {low}..{high}", name
        )


def boolean(fields: dict[str, Any], name: str, default: Any = _MISSING) -> bool:
    if default is not _MISSING and fields.get(name) is None:
        return default
    value = present(fields, name)
    if not isinstance(value, bool):
        raise Reject(ErrorCode.INVALID, f"{name} must be true or false, got {brief(value)}", name)
    return value


def text(
    fields: dict[str, Any], name: str, choices: set[str] | None = None, default: Any = _MISSING
) -> str:
    if default is not _MISSING and fields.get(name) is None:
        return default
    value = present(fields, name)
    if not isinstance(value, str):
        raise Reject(ErrorCode.INVALID, f"{name} must be a string, got {brief(value)}", name)
    if choices is not None and value not in choices:
        raise Reject(
            ErrorCode.INVALID,
            f"{name}={brief(value)} is not one of {', '.join(sorted(choices))}",
            name,
        )
    return value


def joint_ref(robot: RobotConfig, value: Any, field_name: str) -> JointConfig:
    """A joint named by id (int or digit string) or by name."""
    if isinstance(value, str) and value.isdigit():
        value = int(value)
    if isinstance(value, bool) or not isinstance(value, int | str):
        raise Reject(
            ErrorCode.INVALID,
            f"{field_name} must be a joint id or name, got {brief(value)}",
            field_name,
        )
    try:
        return robot.joint(value)
    except KeyError as exc:
        raise Reject(ErrorCode.UNKNOWN, str(exc.args[0]), field_name) from None


def joint_position(joint: JointConfig, value: Any, field_name: str) -> float:
    """A target angle (rad) inside the joint's configured limits; never clamped."""
    pos = number({field_name: value}, field_name)
    if not joint.within(pos):
        raise Reject(
            ErrorCode.OUT_OF_RANGE,
            f"{joint.name} (id {joint.id}) target {math.degrees(pos):.1f}° is outside its "
            f"limits {joint.min_deg:.0f}°..{joint.max_deg:.0f}°",
            field_name,
        )
    return pos


def rgb(fields: dict[str, Any], name: str) -> tuple[int, int, int] | None:
    value = fields.get(name)
    if value is None:
        return None
    if not isinstance(value, list | tuple) or len(value) != 3:
        raise Reject(ErrorCode.INVALID, f"{name} must be [r, g, b], got {brief(value)}", name)
    out = []
    for c in value:
        if isinstance(c, bool) or not isinstance(c, int) or not 0 <= c <= 255:
            raise Reject(
                ErrorCode.OUT_OF_RANGE,
                f"{name} components must be 0..255, got {brief(value)}",
                name,
            )
        out.append(c)
    return (out[0], out[1], out[2])
