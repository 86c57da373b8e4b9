"""Parsing a command and running it: the steps every command takes, whoever calls them (the
arbiter's threads, or a unit test's in-process pipeline)."""

from __future__ import annotations

from typing import Any

from robot_daemon.arbiter.lease import Lease
from robot_daemon.arbiter.registry import (
    REGISTRY,
    MotionContext,
    Reject,
    Request,
    check_fields,
)
from schemas.commands import ENVELOPE, MAX_CLIENT_ID, MAX_NAME
from schemas.errors import CommandError, ErrorCode
from schemas.query import MAX_PAYLOAD, decode_request


def _text(d: dict[str, Any], name: str, limit: int, required: bool) -> str | None:
    value = d.get(name)
    if value is None and not required:
        return None
    if not isinstance(value, str) or not value or len(value) > limit:
        what = f"a string of 1..{limit} characters"
        raise Reject(ErrorCode.INVALID, f"field {name!r} must be {what}", name)
    return value


def decode_command(payload: bytes | None, max_bytes: int = MAX_PAYLOAD) -> dict[str, Any]:
    """A command payload as a bounded map with this build's schema version, or ``Reject``."""
    try:
        return decode_request(payload or b"", max_bytes)
    except CommandError as exc:
        raise Reject(exc.code, exc.message, exc.field) from None


def parse_request(verb_name: str, payload: bytes | None, max_bytes: int = MAX_PAYLOAD) -> Request:
    """Decode a command payload and check its fields, or raise ``Reject`` naming what is
    wrong. Never lets any input through as anything but a ``Reject``."""
    return request_from(verb_name, decode_command(payload, max_bytes))


def request_from(verb_name: str, d: dict[str, Any]) -> Request:
    """The request in a decoded payload: envelope and fields checked (``Reject`` otherwise)."""
    client = _text(d, "client", MAX_CLIENT_ID, required=True)
    assert client is not None
    name = _text(d, "client_name", MAX_NAME, required=False)
    token = _text(d, "lease_token", 64, required=False)
    fields_ = {k: v for k, v in d.items() if k not in ENVELOPE}
    check_fields(verb_name, fields_)
    if name is None and verb_name == "lease" and isinstance(fields_.get("name"), str):
        name = fields_["name"]  # the lease verb's own field is the human name
    return Request(verb_name, client, name or client, fields_, token)


def execute(req: Request, ctx: MotionContext, lease: Lease) -> dict[str, Any]:
    """Run a parsed request in the motion thread: the lease check, then the verb's handler.
    Raises ``CommandError`` (a refusal, nothing touched) or returns what was applied."""
    handler = REGISTRY.get(req.verb)
    if handler is None:
        raise Reject(ErrorCode.UNAVAILABLE, f"verb {req.verb!r} is not available in this build")
    if req.op.lease:
        lease.check(req.client, req.token)
    return handler(req, ctx)
