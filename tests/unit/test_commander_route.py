"""A command sent while the client's session is re-establishing its link waits (within its
timeout) for the daemon's queryable to be declared again instead of failing at once as "nobody
answers"; a key never served still fails at once. Real Zenoh sessions on loopback: the listening
one stands in for the daemon, and is closed and opened again as a link that failed and came back.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterator
from typing import Any

import pytest
import zenoh

from clients.commander import Commander, _matching
from schemas.errors import RobotUnreachableError
from schemas.keys import Keys
from schemas.query import serve
from schemas.session import client_config, free_tcp_port, server_config

KEYS = Keys("r1")
KEY = KEYS.cmd("config")  # an observer's command: no role to learn first


class Daemon:
    """A listening session serving ``KEY``, counting the commands it ran."""

    def __init__(self, endpoint: str) -> None:
        self.endpoint = endpoint
        self.ran = 0
        self.session: zenoh.Session | None = None
        self._queryable: Any = None

    def up(self) -> None:
        self.session = zenoh.open(server_config([self.endpoint]))
        self._queryable = serve(self.session, KEY, self._handle, what="config")

    def down(self) -> None:
        if self.session is not None:
            self._queryable.undeclare()
            self.session.close()
            self.session = None

    def _handle(self, request: dict[str, Any]) -> dict[str, Any]:
        self.ran += 1
        return {"ran": self.ran}


class _Querier:
    """A querier that calls ``waiting`` once its owner listens for a matching queryable (the
    command is then waiting for the route): the test brings the daemon back only then, so the
    command is surely sent into the gap, whatever the machine's speed."""

    def __init__(self, querier: zenoh.Querier, waiting: Callable[[], None]) -> None:
        self._querier = querier
        self._waiting = waiting

    def __getattr__(self, name: str) -> Any:
        return getattr(self._querier, name)

    def declare_matching_listener(self, handler: Any) -> Any:
        listener = self._querier.declare_matching_listener(handler)
        self._waiting()
        return listener


class _Session:
    """The client's real session, whose queriers say when a command waits for its route."""

    def __init__(self, session: zenoh.Session, waiting: Callable[[], None]) -> None:
        self._session = session
        self._waiting = waiting

    def __getattr__(self, name: str) -> Any:
        return getattr(self._session, name)

    def declare_querier(self, key: str, **kwargs: Any) -> _Querier:
        return _Querier(self._session.declare_querier(key, **kwargs), self._waiting)


@pytest.fixture
def daemon() -> Iterator[Daemon]:
    d = Daemon(f"tcp/127.0.0.1:{free_tcp_port()}")
    d.up()
    try:
        yield d
    finally:
        d.down()


def _route_gone(session: zenoh.Session) -> None:
    """Returns once ``session`` knows no queryable on ``KEY`` (its link closed)."""
    querier = session.declare_querier(KEY)
    gone = threading.Event()
    listener = querier.declare_matching_listener(lambda s: None if s.matching else gone.set())
    try:
        # A listener hears changes only: a route already gone is read from the status.
        assert not _matching(querier) or gone.wait(10.0), "the client still sees the queryable"
    finally:
        listener.undeclare()
        querier.undeclare()


def _client(daemon: Daemon, waiting: Callable[[], None]) -> tuple[zenoh.Session, Commander]:
    session = zenoh.open(client_config(daemon.endpoint))
    hooked: Any = _Session(session, waiting)
    return session, Commander(robot="r1", session=hooked, name="route", timeout=20.0)


def test_a_command_sent_while_the_link_is_re_established_waits_for_it(daemon: Daemon) -> None:
    session, client = _client(daemon, waiting=lambda: daemon.up())
    try:
        assert client.config() == {"ran": 1}
        daemon.down()  # the link fails: the client's session reconnects by itself
        _route_gone(session)
        # Sent while no route exists; the daemon comes back once it waits (see _Querier). Before,
        # Zenoh's instant empty answer raised RobotUnreachableError here.
        assert client.config() == {"ran": 2}
        assert daemon.ran == 2  # each command ran once
    finally:
        client.close()
        session.close()


def test_a_route_that_does_not_come_back_fails_within_the_timeout(daemon: Daemon) -> None:
    session, client = _client(daemon, waiting=lambda: None)
    try:
        client.config()
        daemon.down()
        _route_gone(session)
        with pytest.raises(RobotUnreachableError, match="nobody answers"):
            client.command("config", timeout=0.5)
    finally:
        client.close()
        session.close()


def test_a_key_never_served_fails_at_once_without_waiting(daemon: Daemon) -> None:
    """A wrong robot name is said at once, as before: nothing to wait for."""
    waited: list[bool] = []
    session = zenoh.open(client_config(daemon.endpoint))
    hooked: Any = _Session(session, lambda: waited.append(True))
    client = Commander(robot="nobody-here", session=hooked, name="route", timeout=20.0)
    try:
        with pytest.raises(RobotUnreachableError, match="nobody answers"):
            client.config()
        assert waited == []
    finally:
        client.close()
        session.close()
