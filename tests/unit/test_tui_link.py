"""The TUI's link (clients/tui/link.py) waits for its threads when it closes: one left inside a
Zenoh call when the TUI exits comes back into a finalizing Python and is ended by pthread_exit
through Zenoh's Rust frames, which aborts the process ("FATAL: exception not rethrown")."""

from __future__ import annotations

import sys
import threading
from collections.abc import Iterator
from types import SimpleNamespace
from typing import Any

import pytest

import clients.tui.link as link_module
from clients.tui.link import CommandDone, Link
from schemas.errors import DarwinError

WAIT = 30.0


class FakeApp:
    def __init__(self) -> None:
        self.posted: list[Any] = []

    def post_message(self, message: Any) -> bool:
        self.posted.append(message)
        return True


class FakeRobot:
    """A robot whose calls in flight end when it closes, as a Zenoh session's queries do."""

    client_id = "fake"
    role = None

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        self.in_call = threading.Event()
        self.closed = threading.Event()
        self.target = SimpleNamespace(endpoint="tcp/127.0.0.1:7447", robot="op1")
        self.protocol = SimpleNamespace(listen=lambda callback: None)
        undeclare = SimpleNamespace(undeclare=lambda: None)
        liveliness = SimpleNamespace(declare_subscriber=lambda *a, **k: undeclare)
        self.session = SimpleNamespace(liveliness=lambda: liveliness)
        self.keys = SimpleNamespace(alive="darwin/op1/alive")
        ROBOTS.append(self)

    def _in_flight(self) -> None:
        self.in_call.set()
        assert self.closed.wait(WAIT)

    def command(self, verb: str, **fields: Any) -> dict[str, Any]:
        self._in_flight()
        raise DarwinError(f"{verb}: the session closed")

    def alive(self, timeout: float) -> bool:  # the connect's liveliness query
        self._in_flight()
        return False

    def subscribe(self, topic: str, callback: Any) -> None:
        pass

    def close(self) -> None:
        self.closed.set()


ROBOTS: list[FakeRobot] = []


@pytest.fixture
def gil_held_until_blocked() -> Iterator[None]:
    # A thread woken while another runs gets the GIL when that one blocks (or after the switch
    # interval): made long, a call in flight that the close ends cannot finish before close
    # returns unless close waits for it, however the machine schedules the two.
    interval = sys.getswitchinterval()
    sys.setswitchinterval(1000.0)
    try:
        yield
    finally:
        sys.setswitchinterval(interval)


@pytest.mark.parametrize("call", ["command", "halt", "connect"])
def test_close_returns_once_a_call_in_flight_has_ended(
    call: str, monkeypatch: pytest.MonkeyPatch, gil_held_until_blocked: None
) -> None:
    ROBOTS.clear()
    monkeypatch.setattr(link_module, "Robot", FakeRobot)
    app = FakeApp()
    link = Link(app)  # type: ignore[arg-type]
    before = set(threading.enumerate())
    if call == "connect":
        link.connect("tcp/127.0.0.1:7447", "op1")  # its first queries, on the connector
    else:
        link.robot = FakeRobot()  # type: ignore[assignment]
        if call == "command":
            link.send("walk", x=0.1)
        else:
            link.halt()
    (thread,) = [link._runner] if call == "command" else set(threading.enumerate()) - before
    (robot,) = ROBOTS
    assert robot.in_call.wait(WAIT)
    link.close()
    assert not thread.is_alive(), f"close returned with the {call} still in flight"
    assert not link._runner.is_alive()
    if call != "connect":
        (done,) = [m for m in app.posted if isinstance(m, CommandDone)]
        assert "the session closed" in done.error
