"""Run-time control of a running emulator: an op table, served on ``Keys(robot).sim_control``.

A request is a msgpack map ``{"v": 1, "op": name, …fields}``; the reply is ``ok_reply(op,
result)`` or, through ``query.reply_err``, ``error_reply(op, code, message, field)`` (both through
:mod:`schemas.query`, as every queryable). In-process callers use :func:`handle_request` with a
dict; other processes use :class:`SimControl`.

The table is open: ``register_control_op("place_ball", fn)`` (or ``@control_op("place_ball")``)
adds ``fn(emulator, request) -> dict | None``. A handler raises :class:`FieldError` (or
``ValueError``/``KeyError``) for bad input; the error reply names the field.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import zenoh

from schemas.errors import (
    CommandError,
    ErrorCode,
    FieldError,
    InvalidCommandError,
    UnavailableError,
    UnknownNameError,
    brief,
)
from schemas.keys import Keys
from schemas.messages import ok_reply
from schemas.query import ask, error_payload, request_payload, serve
from schemas.roles import SIM_CONTROL_ROLE, Role, discover_role, require

if TYPE_CHECKING:
    from robot_daemon.sim.emulator import Emulator

log = logging.getLogger(__name__)

ControlHandler = Callable[["Emulator", dict[str, Any]], dict[str, Any] | None]
_OPS: dict[str, ControlHandler] = {}
_MISSING = object()


__all__ = ["FieldError", "SimControl", "control_op", "field", "handle_request", "serve_control"]


def register_control_op(name: str, handler: ControlHandler) -> None:
    """Add (or replace) an op; the world adds ``place_robot``/``place_ball`` this way."""
    _OPS[name] = handler


def control_op(name: str) -> Callable[[ControlHandler], ControlHandler]:
    def decorate(fn: ControlHandler) -> ControlHandler:
        register_control_op(name, fn)
        return fn

    return decorate


def control_ops() -> list[str]:
    return sorted(_OPS)


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


def run_op(emulator: Emulator, request: dict[str, Any]) -> dict[str, Any]:
    """Run one request; its result, or a :class:`CommandError` naming what was wrong."""
    op = request.get("op")
    if not isinstance(op, str) or op not in _OPS:
        raise UnknownNameError(
            ErrorCode.UNKNOWN, f"unknown op {brief(op)}; ops: {', '.join(control_ops())}", "op"
        )
    try:
        return _OPS[op](emulator, request) or {}
    except CommandError:
        raise
    except (ValueError, KeyError, TypeError) as exc:
        message = exc.args[0] if isinstance(exc, KeyError) and exc.args else str(exc)
        raise InvalidCommandError(ErrorCode.INVALID, str(message)) from None


def handle_request(emulator: Emulator, request: dict[str, Any]) -> tuple[bool, bytes]:
    """Run one request in process; (ok, reply payload)."""
    op = str(request.get("op"))
    try:
        return True, ok_reply(op, run_op(emulator, request))
    except Exception as exc:
        return False, error_payload(op, exc)


def serve_control(session: zenoh.Session, robot: str, emulator: Emulator) -> zenoh.Queryable:
    """Declare the queryable; keep the returned object alive while serving."""
    return serve(
        session, Keys(robot).sim_control, lambda req: run_op(emulator, req), what="sim"
    )


class SimControl:
    """Client side: ``SimControl(session, "op1").call("faults", drop=0.1)``.

    Behind access control only :data:`~schemas.roles.SIM_CONTROL_ROLE` reaches the emulator,
    and a denied query gets no reply at all: so, like ``Robot.command``, a call first checks
    the session's role (``role``, else learnt from the daemon's role keys) and raises
    ``ForbiddenError`` naming the role that may, instead of "no emulator answers"."""

    def __init__(
        self,
        session: zenoh.Session,
        robot: str,
        timeout: float = 5.0,
        role: Role | str | None = None,
        user: str = "",
    ) -> None:
        self.session = session
        self.keys = Keys(robot)
        self.key = self.keys.sim_control
        self.timeout = timeout
        self.role: Role | str | None = role
        self.user = user

    def call(self, op: str, **fields: Any) -> dict[str, Any]:
        if self.role is None:
            # None (no daemon answers: a bare `darwin sim`) is asked again next time.
            self.role = discover_role(self.session, self.keys, min(self.timeout, 2.0))
        require(self.role, SIM_CONTROL_ROLE, f"the emulator's control ({op})", self.user, op)

        def unreachable() -> Exception:
            return UnavailableError(
                ErrorCode.UNAVAILABLE,
                f"no emulator answers on {self.key}; is `darwin sim --control-listen` running?",
                verb=op,
            )

        payload = request_payload(op=op, **fields)
        return ask(self.session, self.key, payload, self.timeout, verb=op, unreachable=unreachable)


# The built-in ops register themselves; imported last because they use the names above.
from robot_daemon.sim import control_ops as _builtin_ops  # noqa: E402, F401
