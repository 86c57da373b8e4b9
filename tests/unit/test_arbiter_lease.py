"""The control lease as pure state: one holder, busy for others, released, vanished, idle."""

from __future__ import annotations

import pytest

from robot_daemon.arbiter.core import parse_request
from robot_daemon.arbiter.lease import Holder, Lease
from robot_daemon.arbiter.registry import Reject
from schemas.messages import command_payload


class Clock:
    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


def make(idle: float = 60.0) -> tuple[Lease, Clock, list[tuple[str | None, str | None, str]]]:
    clock = Clock()
    changes: list[tuple[str | None, str | None, str]] = []

    def on_change(old: Holder | None, new: Holder | None, reason: str) -> None:
        changes.append((old.client if old else None, new.client if new else None, reason))

    return Lease(idle, on_change, clock), clock, changes


def test_one_holder_and_busy_for_others() -> None:
    lease, _, changes = make()
    lease.acquire("a", "alice")
    with pytest.raises(Reject) as info:
        lease.acquire("b", "bob")
    assert info.value.code == "busy" and "alice" in info.value.message
    with pytest.raises(Reject) as info:
        lease.check("b")
    assert info.value.code == "busy"
    lease.check("a")
    lease.acquire("a", "alice again")  # re-acquiring is fine and renames
    assert lease.status()["name"] == "alice again"
    assert changes == [(None, "a", "acquired")]


def test_no_holder_means_no_lease_error() -> None:
    lease, _, _ = make()
    with pytest.raises(Reject) as info:
        lease.check("a")
    assert info.value.code == "no_lease" and info.value.field == "client"


def test_release_only_by_the_holder() -> None:
    lease, _, changes = make()
    lease.acquire("a", "alice")
    assert lease.release("b") is False
    assert lease.holder is not None
    assert lease.release("a") is True
    assert lease.holder is None
    assert changes[-1] == ("a", None, "released")


def test_vanished_client_loses_it() -> None:
    lease, _, changes = make()
    lease.acquire("a", "alice")
    assert lease.client_gone("b") is False
    assert lease.client_gone("a") is True
    assert changes[-1] == ("a", None, "holder vanished")


def test_idle_timeout_counts_from_the_last_command() -> None:
    lease, clock, changes = make(idle=10.0)
    lease.acquire("a", "alice")
    clock.t += 8
    lease.check("a")  # a command refreshes the idle clock
    clock.t += 8
    assert lease.expire() is False
    clock.t += 3
    assert lease.expire() is True
    assert changes[-1][1] is None and "idle" in changes[-1][2]


def test_zero_idle_timeout_never_expires() -> None:
    lease, clock, _ = make(idle=0)
    lease.acquire("a", "alice")
    clock.t += 1e6
    assert lease.expire() is False


@pytest.mark.parametrize(
    ("payload", "field"),
    [
        (b"", None),
        (b"\xc1", None),
        (b"\x01", None),
        (command_payload("")[:-1] + b"\xa0", "client"),
    ],
)
def test_malformed_payloads_are_rejected(payload: bytes, field: str | None) -> None:
    with pytest.raises(Reject) as info:
        parse_request("joint", payload)
    assert info.value.code == "invalid"
    assert info.value.field == field


def test_request_carries_client_name_and_verb_fields() -> None:
    req = parse_request("joint", command_payload("c1", client_name="me", name="head_pan"))
    assert (req.client, req.name, req.fields) == ("c1", "me", {"name": "head_pan"})
    lease_req = parse_request("lease", command_payload("c1", op="acquire", name="notebook"))
    assert lease_req.name == "notebook"
