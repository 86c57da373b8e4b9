"""Field checks for verb handlers. Each raises :class:`Reject` naming the field and echoing at
most a short prefix of the value (:func:`schemas.errors.brief`)."""

from __future__ import annotations

import math
import types
from typing import Any

from config.loader import JointConfig, RobotConfig
from schemas.errors import ErrorCode, Reject, brief

# Any, so that it may stand as the default of a typed parameter.
_MISSING: Any = object()


def present(fields: dict[str, Any], name: str) -> Any:
    value = fields.get(name, _MISSING)
    if value is _MISSING or value is None:
        raise Reject(ErrorCode.INVALID, f"missing field {name!r}", name)
    return value


def _absent(fields: dict[str, Any], name: str, default: Any) -> bool:
    """True when the field is not given (or null) and has a default to stand in for it."""
    return default is not _MISSING and fields.get(name) is None


def _typed(fields: dict[str, Any], name: str, kind: type | types.UnionType, what: str) -> Any:
    """The field's value when it is a ``kind`` (a bool only when ``kind`` is bool)."""
    value = present(fields, name)
    if not isinstance(value, kind) or (isinstance(value, bool) and kind is not bool):
        raise Reject(ErrorCode.INVALID, f"{name} must be {what}, got {brief(value)}", name)
    return value


def number(
    fields: dict[str, Any],
    name: str,
    low: float | None = None,
    high: float | None = None,
    default: float = _MISSING,
) -> float:
    if _absent(fields, name, default):
        return default
    value = _typed(fields, name, int | float, "a number")
    if not math.isfinite(value):
        raise Reject(ErrorCode.INVALID, f"{name} must be finite, got {brief(value)}", name)
    _within(name, value, low, high)
    return float(value)


def integer(
    fields: dict[str, Any],
    name: str,
    low: int | None = None,
    high: int | None = None,
    default: int = _MISSING,
) -> int:
    if _absent(fields, name, default):
        return default
    value: int = _typed(fields, name, int, "an integer")
    _within(name, value, low, high)
    return value


def _within(name: str, value: float, low: float | None, high: float | None) -> None:
    if (low is not None and value < low) or (high is not None and value > high):
        raise Reject(
            ErrorCode.OUT_OF_RANGE, f"{name}={brief(value)} is outside {low}..{high}", name
        )


def boolean(fields: dict[str, Any], name: str, default: bool = _MISSING) -> bool:
    if _absent(fields, name, default):
        return default
    return bool(_typed(fields, name, bool, "true or false"))


def text(
    fields: dict[str, Any], name: str, choices: set[str] | None = None, default: str = _MISSING
) -> str:
    if _absent(fields, name, default):
        return default
    value: str = _typed(fields, name, str, "a string")
    if choices is not None and value not in choices:
        raise Reject(
            ErrorCode.INVALID,
            f"{name}={brief(value)} is not one of {', '.join(sorted(choices))}",
            name,
        )
    return value


def optional_text(
    fields: dict[str, Any], name: str, choices: set[str] | None = None
) -> str | None:
    """The field's text, or None when it is not given."""
    return None if fields.get(name) is None else text(fields, name, choices)


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
