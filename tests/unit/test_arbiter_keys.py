"""A command runs as the verb of the queryable it reached, and only when the query's key is
exactly that queryable's: over real Zenoh sessions on loopback, with the real arbiter."""

from __future__ import annotations

from collections.abc import Iterator

import msgpack
import pytest
import zenoh

from robot_daemon.arbiter.core import Arbiter
from robot_daemon.arbiter.lease import Lease
from schemas.keys import Keys
from schemas.messages import command_payload

LED = {"head": [255, 0, 0]}


@pytest.fixture
def arbiter(zenoh_pair: tuple[zenoh.Session, zenoh.Session]) -> Iterator[Arbiter]:
    server, _ = zenoh_pair
    arb = Arbiter(server, Keys("r1"), Lease(60.0, heartbeat_timeout=0.0), reply_timeout=2.0)
    try:
        yield arb
    finally:
        arb.close()


def _errors(session: zenoh.Session, key: str, payload: bytes) -> list[dict]:
    replies = list(session.get(key, payload=payload, timeout=5.0))
    assert replies and all(r.ok is None for r in replies), replies
    return [msgpack.unpackb(r.err.payload.to_bytes()) for r in replies]


def test_a_command_on_a_wildcard_key_is_refused_not_run(
    zenoh_pair: tuple[zenoh.Session, zenoh.Session], arbiter: Arbiter
) -> None:
    # darwin/*/cmd/led reaches every robot's led queryable: it names no one robot.
    _, client = zenoh_pair
    (err,) = _errors(client, "darwin/*/cmd/led", command_payload("c1", **LED))
    assert err["verb"] == "led" and err["code"] == "invalid"
    assert "'darwin/*/cmd/led' reached the queryable of 'darwin/r1/cmd/led'" in err["message"]
    assert not arbiter.has_pending()  # nothing was queued for the motion thread
    assert arbiter.counts["rejected"] == 1


def test_a_query_handed_to_another_queryable_is_refused_not_run(
    zenoh_pair: tuple[zenoh.Session, zenoh.Session], arbiter: Arbiter
) -> None:
    """What a Zenoh that confused its key mappings would do: a query meant for another robot's
    led handed to this robot's (the query keeps its own key)."""
    server, client = zenoh_pair
    stray = server.declare_queryable(
        "darwin/r2/cmd/led", lambda q: arbiter._arrived(arbiter.keys.cmd("led"), q), complete=True
    )
    try:
        (err,) = _errors(client, "darwin/r2/cmd/led", command_payload("c1", **LED))
    finally:
        stray.undeclare()
    assert "'darwin/r2/cmd/led' reached the queryable of 'darwin/r1/cmd/led'" in err["message"]
    assert not arbiter.has_pending()


def test_a_command_on_its_own_key_is_queued(
    zenoh_pair: tuple[zenoh.Session, zenoh.Session], arbiter: Arbiter
) -> None:
    """The guard lets the right query through (it reaches the motion thread, which this test
    does not run: the reply is the arbiter's timeout)."""
    _, client = zenoh_pair
    (err,) = _errors(client, "darwin/r1/cmd/led", command_payload("c1", **LED))
    assert "did not take the command" in err["message"], err
    assert arbiter.counts["rejected"] == 0
