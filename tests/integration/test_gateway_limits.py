"""The gateway's limits hold against real TCP clients: bodies beyond the nesting and number
limits are answered and the connection goes on, the connection cap refuses one more client, a
message may not announce more than max_partial_frame, and the idle watchdog closes a client
that completes no message (a slow loris included) while a monitoring client keeps its data."""

from __future__ import annotations

import contextlib
import threading
import time
from collections.abc import Iterator

from tests.fixtures.system import RunningSystem
from tests.legacy_client import GatewayProcess, LegacyClient, header, start_gateway

DEEP = b'{"walk":' + b"[" * 5000 + b"]" * 5000 + b"}"
HUGE_INT = b'{"operate":{"all":0,"id":3,"position":' + b"1" * 5000 + b"}}"


def round_trip(c: LegacyClient) -> None:
    """The connection is served: an unknown tag is answered with its error."""
    c.send({"marker": 1})
    assert c.recv_error()["code"] == "unknown"


@contextlib.contextmanager
def gateway(system: RunningSystem, **settings: object) -> Iterator[GatewayProcess]:
    with start_gateway(system.endpoint, system.robot, settings) as gw:
        yield gw


def test_deep_nesting_and_huge_numbers_are_answered_and_the_connection_keeps_working(
    robot_system: RunningSystem,
) -> None:
    with gateway(robot_system, log_interval=3600.0) as gw:
        with gw.client(order="little", counted=True) as c:
            for _ in range(50):
                c.send(DEEP)
                c.send(HUGE_INT)
            errors = [c.recv_error() for _ in range(100)]
            assert all(e["code"] == "out_of_range" for e in errors), errors[:2]
            assert "deeper than 32 levels" in errors[0]["message"]
            assert "number of 5000 characters" in errors[1]["message"]
            # Still the same connection, still served.
            c.send({"monitor": {"gyroscope": 1}})
            c.recv_until(lambda m: "gyroscope" in m.get("monitor", {}))
        # 100 rejections, one log line (log_interval), and no traceback.
        gw.wait_line("rejected", 30.0)
        assert len([ln for ln in gw.lines if "rejected" in ln]) == 1, gw.lines
        assert not [ln for ln in gw.lines if "Traceback" in ln or " ERROR" in ln], gw.lines


def test_the_connection_cap_refuses_one_more_client_with_an_error(
    robot_system: RunningSystem,
) -> None:
    with gateway(robot_system, max_connections=3) as gw:
        clients = [gw.client() for _ in range(3)]
        try:
            for c in clients:
                round_trip(c)
            with gw.client() as extra:
                err = extra.recv_error()
                assert err["code"] == "busy" and "at most 3 clients" in err["message"], err
                assert extra.closed_by_server()
            for c in clients:
                round_trip(c)
            # A place frees up when a client goes.
            clients.pop().close()
            gw.wait_line("disconnected (2 clients", 30.0)
            with gw.client() as again:
                round_trip(again)
        finally:
            for c in clients:
                c.close()


def test_a_message_may_not_announce_more_than_max_partial_frame(
    robot_system: RunningSystem,
) -> None:
    with gateway(robot_system, max_partial_frame=1024) as gw:
        # First message: no convention reads the header as a size up to 1024 bytes.
        with gw.client() as c:
            c.send_raw(header(2000))
            err = c.recv_error()
            assert err["code"] == "invalid" and "up to 1024 bytes" in err["message"], err
            assert c.closed_by_server()
        # Later: the header alone is refused, the body is never waited for (nor held).
        with gw.client(order="ascii") as c:
            round_trip(c)
            c.send({"monitor": {"camera": 0, "pad": "x" * 950}})
            assert c.recv_error()["code"] == "unknown"  # ~990 bytes are fine
            c.send_raw(c.header(1025))
            err = c.recv_error()
            assert err["code"] == "out_of_range", err
            assert "maximum message size of 1024" in err["message"]
            assert c.closed_by_server()


def dribble(c: LegacyClient, stop: threading.Event) -> None:
    """A slow loris: a header for 100 bytes, then one byte every 0.1 s, until cut off."""
    with contextlib.suppress(OSError):
        c.send_raw(c.header(100))
        while not stop.wait(0.1):
            c.send_raw(b" ")


def closed_with(c: LegacyClient, code: str, needle: str) -> None:
    err = c.recv_error()
    assert err["code"] == code and needle in err["message"] and "idle_timeout" in err["message"]
    assert c.closed_by_server()


def test_the_idle_watchdog_counts_messages_not_bytes(robot_system: RunningSystem) -> None:
    timeout = 1.0
    with gateway(robot_system, idle_timeout=timeout) as gw, gw.client() as reader:
        # A monitoring client says one thing, then only reads: it is served, never idle.
        reader.send({"monitor": {"motors": 1, "period": 50}})
        reader.recv_until(lambda m: "motors" in m.get("monitor", {}))
        stop = threading.Event()
        t0 = time.monotonic()
        with gw.client() as loris, gw.client() as silent:
            sender = threading.Thread(target=dribble, args=(loris, stop))
            sender.start()
            try:
                # Bytes keep coming, but no message completes within the timeout.
                closed_with(loris, "invalid", "message incomplete")
                assert time.monotonic() - t0 >= timeout
                closed_with(silent, "refused", "no message")
            finally:
                stop.set()
                sender.join()
        # The reader has been quiet for longer than the timeout, and still gets its data.
        for _ in range(20):
            reader.recv_until(lambda m: "monitor" in m)
        # Once it starts a message, though, it has the timeout to finish it.
        t0 = time.monotonic()
        reader.send_raw(reader.header(100) + b'{"monitor":')
        closed_with(reader, "invalid", "message incomplete")
        assert time.monotonic() - t0 >= timeout
