"""Run-time control of a running emulator: the op table, served on ``Keys(robot).sim_control``.

A request is a msgpack map ``{"v", "op": name, …fields}``; the reply is ``ok_reply(op,
result)`` or, through ``query.reply_err``, ``error_reply(op, code, message, field)`` (both through
:mod:`schemas.query`, as every queryable). In-process callers use :func:`run_op` or
:func:`handle_request` with a dict; other processes use :class:`schemas.sim_control.SimControl`.

The ops are those in :mod:`robot_daemon.emulator.op_table`: the built-in ones
(:mod:`robot_daemon.emulator.builtin_ops`, registered on import of this module) and whatever
else registered there (the world's).
"""

from __future__ import annotations

import logging
from typing import TYPE_CHECKING, Any

import zenoh

from robot_daemon.emulator import builtin_ops as _builtin_ops  # noqa: F401  (registers them)
from robot_daemon.emulator.op_table import OPS, control_ops
from schemas.errors import (
    CommandError,
    ErrorCode,
    InvalidCommandError,
    UnknownNameError,
    brief,
)
from schemas.keys import Keys
from schemas.messages import ok_reply
from schemas.query import error_payload, serve

if TYPE_CHECKING:
    from robot_daemon.emulator.emulator import Emulator

log = logging.getLogger(__name__)

__all__ = ["handle_request", "run_op", "serve_control"]


def run_op(emulator: Emulator, request: dict[str, Any]) -> dict[str, Any]:
    """Run one request; its result, or a :class:`CommandError` naming what was wrong."""
    op = request.get("op")
    if not isinstance(op, str) or op not in OPS:
        raise UnknownNameError(
            ErrorCode.UNKNOWN, f"unknown op {brief(op)}; ops: {', '.join(control_ops())}", "op"
        )
    try:
        return OPS[op](emulator, request) or {}
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
    return serve(session, Keys(robot).sim_control, lambda req: run_op(emulator, req), what="sim")
