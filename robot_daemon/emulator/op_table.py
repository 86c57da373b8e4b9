"""The emulator's control op table: names to handlers, and the field checks handlers use.

The table is open: ``register_control_op("place_ball", fn)`` (or ``@control_op("place_ball")``)
adds ``fn(emulator, request) -> dict | None``. A handler raises :class:`FieldError` (or
``ValueError``/``KeyError``) for bad input; the error reply names the field. The emulator's own
ops (:mod:`robot_daemon.emulator.builtin_ops`) and the world's
(:mod:`robot_daemon.plant.world_ops`) register here; :mod:`robot_daemon.emulator.control_service`
runs and serves them. This module imports neither.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from schemas.errors import FieldError, brief

if TYPE_CHECKING:
    from robot_daemon.emulator.emulator import Emulator

ControlHandler = Callable[["Emulator", dict[str, Any]], dict[str, Any] | None]
OPS: dict[str, ControlHandler] = {}
_MISSING = object()

__all__ = ["OPS", "ControlHandler", "FieldError", "control_op", "control_ops", "field"]


def register_control_op(name: str, handler: ControlHandler) -> None:
    """Add (or replace) an op; the world adds ``place_robot``/``place_ball`` this way."""
    OPS[name] = handler


def control_op(name: str) -> Callable[[ControlHandler], ControlHandler]:
    def decorate(fn: ControlHandler) -> ControlHandler:
        register_control_op(name, fn)
        return fn

    return decorate


def control_ops() -> list[str]:
    return sorted(OPS)


def field(
    request: dict[str, Any], name: str, kind: type | tuple[type, ...], default: Any = _MISSING
):
    """``request[name]`` checked against ``kind`` (ints pass as floats), or ``default``."""
    if name not in request:
        if default is _MISSING:
            raise FieldError(name, f"field {name!r} is missing")
        return default
    value = request[name]
    kinds = kind if isinstance(kind, tuple) else (kind,)
    if float in kinds and isinstance(value, int) and not isinstance(value, bool):
        value = float(value)
    if not isinstance(value, kinds) or (isinstance(value, bool) and bool not in kinds):
        wanted = " or ".join(k.__name__ for k in kinds)
        raise FieldError(name, f"field {name!r} must be {wanted}, got {brief(value)}")
    return value
