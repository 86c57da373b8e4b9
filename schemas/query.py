"""Query/reply over Zenoh, written once for every queryable and every caller.

Servers (the arbiter, the emulator's control, the replay control) take a query's payload with
:func:`request_bytes` (size checked *before* anything is copied or decoded), decode it with
:func:`decode_request` (msgpack map, schema version, bounded strings/lists/depth) and answer with
:func:`answer` (``ok_reply`` through ``query.reply``, ``error_reply`` through
``query.reply_err``; the query is always finalised). :func:`serve` does all of it for a
synchronous handler ``handle(request) -> applied``; any :class:`CommandError` it raises becomes
the error reply with its code and field, anything else an ``internal`` error.

Callers use :func:`ask`: one ``session.get``, and one translation of what can come back into the
project's errors: no reply → the ``unreachable`` error the caller names, Zenoh's ``Timeout`` →
:class:`CommandTimeoutError`, an error reply → the :class:`CommandError` subclass of its code.
"""

from __future__ import annotations

import contextlib
import logging
from collections.abc import Callable
from typing import Any

import msgpack
import zenoh

from schemas import SCHEMA_VERSION, qos
from schemas.errors import (
    CommandError,
    CommandTimeoutError,
    ErrorCode,
    InternalError,
    InvalidCommandError,
    OutOfRangeError,
    PayloadTooLargeError,
    ProtocolError,
    RobotUnreachableError,
    brief,
    command_error,
)
from schemas.messages import decode_dict, error_reply, ok_reply, version_refusal

log = logging.getLogger(__name__)

# A command is a few hundred bytes; a long choreography a few KiB. Anything bigger is refused
# before it is decoded (daemon.toml [daemon.arbiter] max_payload_bytes overrides it).
MAX_PAYLOAD = 64 * 1024
# Structure limits of a decoded request, whatever the verb (verbs set tighter ones per field).
MAX_STRING = 1024
MAX_ITEMS = 512
MAX_DEPTH = 8


def request_bytes(query: zenoh.Query, max_bytes: int = MAX_PAYLOAD) -> bytes:
    """The query's payload, refused with :class:`PayloadTooLargeError` when over ``max_bytes``
    (measured on Zenoh's buffer, so a huge payload is never copied into Python)."""
    payload = query.payload
    if payload is None:
        return b""
    size = len(payload)
    if size > max_bytes:
        raise PayloadTooLargeError(
            f"payload of {size} bytes is over the {max_bytes}-byte limit: send less (split a "
            "long choreography, shorten strings)"
        )
    return payload.to_bytes()


def decode_request(payload: bytes, max_bytes: int = MAX_PAYLOAD) -> dict[str, Any]:
    """A request map with this build's schema version, bounded in size and shape.

    Raises :class:`OutOfRangeError` (too large: payload, a string, a list or nesting) or
    :class:`InvalidCommandError` (not a msgpack map, wrong version), each naming the field."""
    if len(payload) > max_bytes:
        raise OutOfRangeError(
            ErrorCode.OUT_OF_RANGE,
            f"payload of {len(payload)} bytes is over the {max_bytes}-byte limit",
            "payload",
        )
    if not payload:
        raise InvalidCommandError(
            ErrorCode.INVALID, f"empty payload: send a msgpack map with v={SCHEMA_VERSION}", "v"
        )
    try:
        d = decode_dict(payload)
    except ProtocolError as exc:
        raise InvalidCommandError(ErrorCode.INVALID, str(exc)[:200], "payload") from None
    check_bounds(d)
    if d.get("v") != SCHEMA_VERSION:
        raise InvalidCommandError(
            ErrorCode.INVALID,
            version_refusal(d.get("v")),
            "v",
        )
    return d


def check_bounds(
    value: Any,
    where: str = "",
    *,
    max_string: int = MAX_STRING,
    max_items: int = MAX_ITEMS,
    max_depth: int = MAX_DEPTH,
) -> None:
    """Refuse a decoded value with a string, bytes, list or map longer than the limits, or
    nested deeper than ``max_depth``; the error names the path (``items[3].say``)."""
    stack: list[tuple[Any, str, int]] = [(value, where, 0)]
    while stack:
        v, path, depth = stack.pop()
        name = path or "payload"
        if isinstance(v, str | bytes):
            if len(v) > max_string:
                raise OutOfRangeError(
                    ErrorCode.OUT_OF_RANGE, f"{name} is longer than {max_string} characters", name
                )
            continue
        if not isinstance(v, list | tuple | dict):
            continue
        if depth >= max_depth:
            raise OutOfRangeError(
                ErrorCode.OUT_OF_RANGE, f"{name} is nested deeper than {max_depth} levels", name
            )
        if len(v) > max_items:
            raise OutOfRangeError(
                ErrorCode.OUT_OF_RANGE, f"{name} has more than {max_items} entries", name
            )
        if isinstance(v, dict):
            for k, item in v.items():
                if not isinstance(k, str) or len(k) > 64:
                    raise InvalidCommandError(
                        ErrorCode.INVALID, f"{name} has a key {brief(k)}: keys are short strings",
                        name,
                    )
                stack.append((item, f"{path}.{k}" if path else k, depth + 1))
        else:
            stack.extend((item, f"{name}[{i}]", depth + 1) for i, item in enumerate(v))


def error_payload(what: str, exc: BaseException) -> bytes:
    """The error reply for an exception: a command error keeps its code and field; malformed
    input is ``invalid``; anything else is an ``internal`` error (and is logged)."""
    if isinstance(exc, CommandError):
        return error_reply(what, exc.code, exc.message, exc.field, exc.retry_after)
    if isinstance(exc, PayloadTooLargeError):
        return error_reply(what, ErrorCode.OUT_OF_RANGE, str(exc), "payload")
    if isinstance(exc, ProtocolError):
        return error_reply(what, ErrorCode.INVALID, str(exc)[:200], "payload")
    log.error("%s failed", what, exc_info=exc)
    return error_reply(
        what, ErrorCode.INTERNAL, f"{type(exc).__name__}: {brief(str(exc), 200)} (a bug)"
    )


def answer(query: zenoh.Query, key: str, ok: bool, payload: bytes) -> None:
    """Reply (ok or error) and finalise the query, whatever happens."""
    try:
        if ok:
            query.reply(key, payload)
        else:
            query.reply_err(payload)
    except Exception:
        log.exception("replying on %s failed", key)
    finally:
        with contextlib.suppress(Exception):
            query.drop()


Handler = Callable[[dict[str, Any]], dict[str, Any] | None]


def serve(
    session: zenoh.Session,
    key: str,
    handle: Handler,
    *,
    what: str,
    max_bytes: int = MAX_PAYLOAD,
    empty: dict[str, Any] | None = None,
) -> zenoh.Queryable[None]:
    """Declare a queryable on ``key`` that runs ``handle(request)`` in Zenoh's thread and
    replies ``ok_reply(what, applied)`` or the error. ``empty`` is the request an empty payload
    stands for (None: an empty payload is an error). Keep the returned object alive."""

    def on_query(query: zenoh.Query) -> None:
        try:
            raw = request_bytes(query, max_bytes)
            request = dict(empty) if not raw and empty is not None else decode_request(raw)
            reply, ok = ok_reply(what, handle(request) or {}), True
        except Exception as exc:
            reply, ok = error_payload(what, exc), False
        answer(query, key, ok, reply)

    return session.declare_queryable(key, on_query, complete=True)


def request_payload(**fields: Any) -> bytes:
    """A request map with the schema version."""
    payload: bytes = msgpack.packb({"v": SCHEMA_VERSION, **fields}, use_bin_type=True)
    return payload


def ask(
    session: zenoh.Session,
    key: str,
    payload: bytes,
    timeout: float,
    *,
    verb: str,
    unreachable: Callable[[], Exception],
) -> dict[str, Any]:
    """One query; its ``applied`` map, or the project's error for what came back."""
    if len(payload) > MAX_PAYLOAD:
        # Zenoh drops a message over the daemon's limit unanswered: say why here instead of
        # letting the caller wait for a timeout.
        raise OutOfRangeError(
            ErrorCode.OUT_OF_RANGE,
            f"payload of {len(payload)} bytes is over the {MAX_PAYLOAD}-byte limit: send less "
            "(split a long choreography, shorten strings)",
            "payload",
            verb,
        )
    try:
        # The reply comes back with the query's QoS: halt's and the lease's go first.
        replies = list(
            session.get(key, payload=payload, timeout=timeout, **qos.for_key(key).kwargs())
        )
    except zenoh.ZError as exc:
        raise RobotUnreachableError(f"{verb}: the Zenoh session failed: {exc}") from exc
    if not replies:
        raise unreachable()
    reply = replies[0]
    if reply.ok is not None:
        try:
            d = decode_dict(reply.ok.payload.to_bytes())
        except ProtocolError as exc:
            raise InternalError(ErrorCode.INTERNAL, str(exc), None, verb) from None
        applied = d.get("applied", {})
        return applied if isinstance(applied, dict) else {"value": applied}
    raw = reply.err.payload.to_bytes()
    try:
        d = decode_dict(raw)
    except ProtocolError:
        text = raw.decode("utf-8", "replace")
        if "timeout" in text.lower():
            raise CommandTimeoutError(
                f"{verb}: no answer within {timeout:g} s (the daemon may be overloaded or "
                "its motion loop stopped; see status)"
            ) from None
        raise InternalError(ErrorCode.INTERNAL, brief(text, 200), None, verb) from None
    retry = d.get("retry_after")
    raise command_error(
        str(d.get("code", ErrorCode.INTERNAL)),
        str(d.get("message", "")),
        d.get("field") if isinstance(d.get("field"), str) else None,
        verb,
        float(retry) if isinstance(retry, int | float) else None,
    )


__all__ = [
    "MAX_PAYLOAD",
    "answer",
    "ask",
    "check_bounds",
    "decode_request",
    "error_payload",
    "request_bytes",
    "request_payload",
    "serve",
]
