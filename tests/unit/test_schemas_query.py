"""The one query/reply helper and the one exception tree, over real Zenoh sessions on loopback."""

from __future__ import annotations

import ast
import importlib
import inspect
import logging
import re
import threading
import time
from pathlib import Path

import pytest
import zenoh

import schemas.errors as errors_module
from schemas.errors import (
    ERROR_CLASSES,
    CommandError,
    CommandTimeoutError,
    DarwinError,
    ErrorCode,
    InvalidCommandError,
    OutOfRangeError,
    RateLimitedError,
    Reject,
    RobotUnreachableError,
    UnknownNameError,
    brief,
    command_error,
)
from schemas.messages import error_reply
from schemas.query import MAX_PAYLOAD, ask, check_bounds, request_payload, serve
from schemas.session import free_tcp_port, server_config

REPO = Path(__file__).resolve().parents[2]

# Keys in the robot key space, so that schemas/qos.py gives their queries a QoS.
KQ, KNONE, KSLOW = "darwin/t/read/q", "darwin/t/read/none", "darwin/t/read/slow"


def test_every_error_code_maps_to_its_class_and_back() -> None:
    assert set(ERROR_CLASSES) == {str(c) for c in ErrorCode}
    for code in ErrorCode:
        cls = ERROR_CLASSES[code]
        assert code == cls.CODE
        err = command_error(code, "m", "f", "verb", 0.5)
        assert type(err) is cls and err.code == code and err.retry_after == 0.5
    assert type(command_error("from_the_future", "m")) is CommandError
    # Old callers catch InvalidCommandError for every bad value; they still do.
    assert issubclass(OutOfRangeError, InvalidCommandError)
    assert issubclass(UnknownNameError, InvalidCommandError)


def _project_exceptions() -> list[type[BaseException]]:
    """Every public exception class defined anywhere in the project's packages (found by reading
    the sources, so a module nobody imports here is not missed). A private one (``_Mismatch``)
    is control flow inside its module and never reaches a caller."""
    found = []
    for package in ("schemas", "config", "robot_daemon", "gateway", "clients"):
        for path in sorted((REPO / package).rglob("*.py")):
            module = ".".join(path.relative_to(REPO).with_suffix("").parts)
            for node in ast.walk(ast.parse(path.read_text())):
                if isinstance(node, ast.ClassDef) and node.bases and node.name[0] != "_":
                    try:
                        cls = getattr(importlib.import_module(module), node.name, None)
                    except ImportError:  # an extra that is not installed here
                        continue
                    if inspect.isclass(cls) and issubclass(cls, BaseException):
                        found.append(cls)
    return found


def test_every_project_exception_is_in_the_one_tree() -> None:
    classes = [c for _, c in inspect.getmembers(errors_module, inspect.isclass)]
    exceptions = [c for c in classes if issubclass(c, BaseException)]
    assert all(issubclass(c, DarwinError) for c in exceptions), exceptions
    everywhere = _project_exceptions()
    assert len(everywhere) > len(exceptions)  # the scan reached beyond schemas/errors.py
    outside = [
        f"{c.__module__}.{c.__qualname__}" for c in everywhere if not issubclass(c, DarwinError)
    ]
    assert not outside, f"exceptions outside the tree (schemas/errors.py): {outside}"
    drawn = errors_module.__doc__ or ""
    undrawn = [c.__name__ for c in everywhere if not re.search(rf"\b{c.__name__}\b", drawn)]
    assert not undrawn, f"exceptions missing from the tree drawn in schemas/errors.py: {undrawn}"
    from gateway.outbox import SlowReaderError
    from robot_daemon.arbiter.registry import Reject as RegistryReject
    from robot_daemon.emulator.op_table import FieldError
    from robot_daemon.motion.behaviours import BehaviourError

    for cls in (SlowReaderError, RegistryReject, BehaviourError, FieldError):
        assert issubclass(cls, DarwinError), cls
    assert RegistryReject is Reject


def test_brief_echoes_only_a_prefix() -> None:
    assert brief("abc") == "'abc'"
    long = brief("x" * 10_000_000)
    assert len(long) <= 50 and long.endswith("(str)")


def test_check_bounds_names_the_path() -> None:
    with pytest.raises(OutOfRangeError) as info:
        check_bounds({"items": [{"say": "x" * 5000}]})
    assert info.value.field == "items[0].say"
    deep: list = []
    cur = deep
    for _ in range(20):
        cur.append([])
        cur = cur[0]
    with pytest.raises(OutOfRangeError):
        check_bounds({"a": deep})
    check_bounds({"items": [{"behaviour": 1}] * 256})


def _unreachable() -> Exception:
    return RobotUnreachableError("nobody there")


def test_serve_and_ask_round_trip_with_errors_translated_once(zenoh_pair) -> None:
    server, client = zenoh_pair

    def handle(req: dict) -> dict:
        if req["op"] == "fail":
            raise RateLimitedError(ErrorCode.RATE_LIMITED, "slow down", "op", retry_after=0.25)
        if req["op"] == "bug":
            raise ZeroDivisionError("oops")
        return {"echo": req["op"]}

    q = serve(server, KQ, handle, what="test")
    try:
        got = ask(client, KQ, request_payload(op="hi"), 5, verb="hi", unreachable=_unreachable)
        assert got == {"echo": "hi"}
        with pytest.raises(RateLimitedError) as info:
            ask(client, KQ, request_payload(op="fail"), 5, verb="fail", unreachable=_unreachable)
        assert info.value.retry_after == 0.25 and info.value.field == "op"
        with pytest.raises(CommandError) as info:
            ask(client, KQ, request_payload(op="bug"), 5, verb="bug", unreachable=_unreachable)
        assert info.value.code == "internal"
        with pytest.raises(InvalidCommandError) as info:  # no schema version
            ask(client, KQ, b"\x81\xa2op\xa2hi", 5, verb="x", unreachable=_unreachable)
        assert info.value.field == "v"
        big = request_payload(op="hi", blob=b"x" * (MAX_PAYLOAD + 1))
        with pytest.raises(OutOfRangeError) as info:
            ask(client, KQ, big, 5, verb="big", unreachable=_unreachable)
        assert info.value.field == "payload" and len(info.value.message) < 200
        with pytest.raises(RobotUnreachableError):
            ask(client, KNONE, request_payload(op="hi"), 0.5, verb="x", unreachable=_unreachable)
    finally:
        q.undeclare()


def test_a_queryable_that_never_answers_is_a_timeout(zenoh_pair) -> None:
    server, client = zenoh_pair
    held: list[zenoh.Query] = []
    q = server.declare_queryable(KSLOW, held.append)
    try:
        t0 = time.monotonic()
        with pytest.raises(CommandTimeoutError):
            ask(client, KSLOW, request_payload(op="x"), 0.5, verb="x", unreachable=_unreachable)
        assert time.monotonic() - t0 < 5
    finally:
        for query in held:
            query.drop()
        q.undeclare()


def test_error_replies_carry_retry_after() -> None:
    import msgpack

    d = msgpack.unpackb(error_reply("walk", "rate_limited", "m", None, 0.1234))
    assert d["retry_after"] == 0.123
    assert "retry_after" not in msgpack.unpackb(error_reply("walk", "busy", "m"))


def test_a_failing_subscription_callback_is_logged_once_with_its_traceback(
    caplog: pytest.LogCaptureFixture,
) -> None:
    from clients.robot import Subscription

    calls = threading.Event()

    def bad(_msg: object) -> None:
        calls.set()
        raise ValueError("user bug")

    sub = Subscription(None, "joints", bad)  # type: ignore[arg-type]
    with caplog.at_level(logging.ERROR, logger="clients.robot"):
        for _ in range(5):
            sub._deliver(object())  # type: ignore[arg-type]
    records = [r for r in caplog.records if "subscription callback" in r.getMessage()]
    assert len(records) == 1 and records[0].exc_info is not None
    assert sub.errors == 5 and isinstance(sub.last_error, ValueError)


def test_a_caller_is_told_at_once_when_its_payload_is_too_large() -> None:
    # Zenoh would drop it unanswered at the daemon; the caller gets the reason, not a timeout.
    from schemas.errors import OutOfRangeError
    from schemas.query import MAX_PAYLOAD, ask

    port = free_tcp_port()
    with zenoh.open(server_config([f"tcp/127.0.0.1:{port}"])) as session:
        asked: list[str] = []
        queryable = session.declare_queryable(
            "darwin/op1/cmd/pose", lambda q: asked.append(str(q.key_expr)), complete=True
        )
        with pytest.raises(OutOfRangeError) as err:
            ask(
                session,
                "darwin/op1/cmd/pose",
                b"x" * (MAX_PAYLOAD + 1),
                1.0,
                verb="pose",
                unreachable=lambda: AssertionError("unreachable"),
            )
        queryable.undeclare()
    assert err.value.field == "payload"
    assert asked == []
