"""Run-time control of a running emulator: an op table, served on ``Keys(robot).sim_control``.

A request is a msgpack map ``{"op": name, …fields}``; the reply is ``ok_reply(op, result)`` or,
through ``query.reply_err``, ``error_reply(op, code, message, field)``. In-process callers use
:func:`handle_request` with a dict; other processes use :class:`SimControl`.

The table is open: ``register_control_op("place_ball", fn)`` (or ``@control_op("place_ball")``)
adds ``fn(emulator, request) -> dict | None``. A handler raises :class:`FieldError` (or
``ValueError``/``KeyError``) for bad input; the error reply names the field.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import msgpack
import zenoh

from schemas.errors import ErrorCode, ProtocolError, command_error
from schemas.keys import Keys
from schemas.messages import decode_dict, error_reply, ok_reply

if TYPE_CHECKING:
    from robot_daemon.sim.emulator import Emulator

log = logging.getLogger(__name__)

ControlHandler = Callable[["Emulator", dict[str, Any]], dict[str, Any] | None]
_OPS: dict[str, ControlHandler] = {}
_MISSING = object()


class FieldError(ValueError):
    def __init__(self, field_name: str, message: str) -> None:
        super().__init__(message)
        self.field = field_name


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
        raise FieldError(name, f"field {name!r} must be {wanted}, got {value!r}")
    return value


def handle_request(emulator: Emulator, request: dict[str, Any]) -> tuple[bool, bytes]:
    """Run one request; (ok, reply payload)."""
    op = request.get("op")
    if not isinstance(op, str) or op not in _OPS:
        return False, error_reply(
            str(op), ErrorCode.UNKNOWN, f"unknown op {op!r}; ops: {', '.join(control_ops())}", "op"
        )
    try:
        result = _OPS[op](emulator, request)
    except FieldError as exc:
        return False, error_reply(op, ErrorCode.INVALID, str(exc), exc.field)
    except (ValueError, KeyError, TypeError) as exc:
        message = exc.args[0] if isinstance(exc, KeyError) and exc.args else str(exc)
        return False, error_reply(op, ErrorCode.INVALID, str(message))
    except Exception as exc:
        log.exception("sim control op %s failed", op)
        return False, error_reply(op, ErrorCode.INTERNAL, f"{type(exc).__name__}: {exc}")
    return True, ok_reply(op, result or {})


def serve_control(session: zenoh.Session, robot: str, emulator: Emulator) -> zenoh.Queryable:
    """Declare the queryable; keep the returned object alive while serving."""
    key = Keys(robot).sim_control

    def on_query(query: zenoh.Query) -> None:
        try:
            payload = query.payload.to_bytes() if query.payload is not None else b""
            try:
                request = decode_dict(payload)
            except ProtocolError as exc:
                ok, reply = False, error_reply("?", ErrorCode.INVALID, str(exc))
            else:
                ok, reply = handle_request(emulator, request)
            if ok:
                query.reply(key, reply)
            else:
                query.reply_err(reply)
        except Exception:
            log.exception("answering a sim control query failed")
        finally:
            query.drop()

    return session.declare_queryable(key, on_query, complete=True)


class SimControl:
    """Client side: ``SimControl(session, "op1").call("faults", drop=0.1)``."""

    def __init__(self, session: zenoh.Session, robot: str, timeout: float = 5.0) -> None:
        self.session = session
        self.key = Keys(robot).sim_control
        self.timeout = timeout

    def call(self, op: str, **fields: Any) -> dict[str, Any]:
        payload = msgpack.packb({"op": op, **fields}, use_bin_type=True)
        replies = list(self.session.get(self.key, payload=payload, timeout=self.timeout))
        if not replies:
            raise command_error(
                ErrorCode.UNAVAILABLE,
                f"no emulator answers on {self.key}; is `darwin sim --control-listen` running?",
                verb=op,
            )
        reply = replies[0]
        if reply.ok is not None:
            return decode_dict(reply.ok.payload.to_bytes()).get("applied", {})
        raw = reply.err.payload.to_bytes()
        try:
            d = decode_dict(raw)
        except ProtocolError:
            d = {"code": ErrorCode.UNAVAILABLE, "message": raw.decode(errors="replace")}
        raise command_error(d.get("code", "internal"), d.get("message", ""), d.get("field"), op)


# The built-in ops register themselves; imported last because they use the names above.
from robot_daemon.sim import control_ops as _builtin_ops  # noqa: E402, F401
