"""The motion thread's share of arbiter work is bounded per tick: halt first, a count and time
budget, and client register reads within a measured share of bus time."""

from __future__ import annotations

import time
from collections.abc import Iterator

import pytest
import zenoh

from robot_daemon.arbiter.core import Arbiter, Pending
from robot_daemon.arbiter.registry import Request
from robot_daemon.arbiter.throttle import ArbiterLimits, Buckets
from schemas.keys import Keys
from schemas.session import server_config
from tests.unit.arbiter_rig import ArbiterRig


class Query:
    """The edge: what Zenoh would carry back to the caller."""

    key_expr = "darwin/op1/cmd/halt"  # the arbiter answers on the key a query came on

    def __init__(self) -> None:
        self.replies: list[tuple[bool, bytes]] = []

    def reply(self, _key: str, payload: bytes) -> None:
        self.replies.append((True, payload))

    def reply_err(self, payload: bytes) -> None:
        self.replies.append((False, payload))

    def drop(self) -> None:
        pass


@pytest.fixture
def arbiter() -> Iterator[tuple[Arbiter, ArbiterRig]]:
    rig = ArbiterRig()
    session = zenoh.open(server_config([]))
    # A generous time budget: these tests check the count and the bus share, on any machine.
    limits = ArbiterLimits(
        commands_per_tick=3, bus_time_share=0.02, queue_size=8, work_budget_ms=1000.0
    )
    arb = Arbiter(session, Keys("budget"), rig.lease, limits=limits)
    try:
        yield arb, rig
    finally:
        arb.close()
        session.close()


def _queue(arb: Arbiter, verb: str, client: str, token: str | None = None, **fields) -> Pending:
    p = Pending(Request(verb, client, client, fields, token), Query(), time.monotonic() + 60)  # type: ignore[arg-type]
    with arb._qlock:
        reads = verb == "registers" and "data" not in fields
        if verb == "halt":
            arb._urgent.append(p)
        elif reads or arb._reading.get(client):
            arb._reads.append(p)
            arb._reading[client] = arb._reading.get(client, 0) + 1
        else:
            arb._queue.append(p)
    return p


def test_halt_first_then_a_bounded_count_per_tick(arbiter) -> None:
    arb, rig = arbiter
    ctx = rig.context()
    many = [_queue(arb, "config", f"c{i}") for i in range(7)]
    halt = _queue(arb, "halt", "anyone")
    assert arb.apply_pending(ctx) == 4  # the halt + commands_per_tick
    assert halt.ok and sum(p.ok for p in many) == 3
    assert [p.ok for p in many] == [True] * 3 + [False] * 4  # in arrival order
    arb.apply_pending(ctx)
    arb.apply_pending(ctx)
    assert all(p.ok for p in many)


def test_reads_wait_for_their_bus_share_and_do_not_block_others(arbiter) -> None:
    arb, rig = arbiter
    ctx = rig.context()
    arb._bus_credit, arb._credit_at = 0.0, time.monotonic()
    reads = [_queue(arb, "registers", "reader", id=19, address=36, length=2) for _ in range(5)]
    later = _queue(arb, "config", "someone-else")
    follows = _queue(arb, "config", "reader")  # the reader's own next command keeps its place
    arb.apply_pending(ctx)
    assert later.ok  # not stuck behind the reads
    ticks = 1
    while not (all(p.ok for p in reads) and follows.ok) and ticks < 100_000:
        arb.apply_pending(ctx)
        ticks += 1
    assert all(p.ok for p in reads) and follows.ok
    assert ticks > len(reads)  # reads were spread over ticks, never all at once
    assert len(rig.bus.reads) == len(reads)


def test_fail_pending_answers_everything_queued(arbiter) -> None:
    arb, _ = arbiter
    queued = [_queue(arb, "config", "a"), _queue(arb, "halt", "b")]
    queued.append(_queue(arb, "registers", "c", id=19, address=36, length=2))
    assert arb.fail_pending("the serial port is lost") == 3
    assert all(p.answered and not p.ok for p in queued)
    assert not arb.has_pending()


def test_token_buckets_refill_at_their_rate() -> None:
    t = [0.0]
    b = Buckets(rate=10.0, burst=2, clock=lambda: t[0])
    assert b.take("a") == 0 and b.take("a") == 0
    wait = b.take("a")
    assert wait == pytest.approx(0.1)
    assert b.take("b") == 0  # per key
    t[0] += 0.1
    assert b.take("a") == 0
