"""The control lease as pure state: one holder bound to its secret, busy for others, released,
vanished, silent, idle."""

from __future__ import annotations

import pytest

from robot_daemon.arbiter.core import parse_request
from robot_daemon.arbiter.lease import SILENT, Holder, Lease
from robot_daemon.arbiter.registry import Reject
from schemas.messages import command_payload


class Clock:
    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


def make(
    idle: float = 60.0, heartbeat: float = 0.0
) -> tuple[Lease, Clock, list[tuple[str | None, str | None, str]]]:
    clock = Clock()
    changes: list[tuple[str | None, str | None, str]] = []

    def on_change(old: Holder | None, new: Holder | None, reason: str) -> None:
        changes.append((old.client if old else None, new.client if new else None, reason))

    return Lease(idle, on_change, clock, heartbeat_timeout=heartbeat), clock, changes


def renewed_each_second(lease: Lease, clock: Clock, token: str, seconds: int) -> int | None:
    """Client "a" renews the lease once a second for ``seconds``: the second the lease expired
    at, or None if it held."""
    for second in range(1, seconds + 1):
        clock.t += 1.0
        lease.renew("a", token)
        if lease.expire():
            return second
    return None


def test_one_holder_and_busy_for_others() -> None:
    lease, _, changes = make()
    token = lease.acquire("a", "alice").token
    with pytest.raises(Reject) as info:
        lease.acquire("b", "bob")
    assert info.value.code == "busy" and "alice" in info.value.message
    with pytest.raises(Reject) as info:
        lease.check("b", None)
    assert info.value.code == "busy"
    lease.check("a", token)
    again = lease.acquire("a", "alice again", token)  # re-acquiring with the token renames
    assert again.token == token and lease.status()["name"] == "alice again"
    assert changes == [(None, "a", "acquired")]


def test_the_token_is_secret_and_never_in_the_status() -> None:
    lease, _, _ = make()
    holder = lease.acquire("a", "alice")
    assert len(holder.token) >= 20
    assert holder.token not in repr(lease.status())
    other = make()[0].acquire("a", "alice")
    assert other.token != holder.token  # random, not derived from the id


def test_a_reused_client_id_without_the_token_can_do_nothing() -> None:
    lease, _, changes = make()
    token = lease.acquire("a", "alice").token
    for wrong in (None, "", "guess", token[:-1]):
        with pytest.raises(Reject) as info:
            lease.check("a", wrong)
        assert info.value.code == "busy" and info.value.field == "lease_token"
        with pytest.raises(Reject):
            lease.acquire("a", "mallory", wrong)
        with pytest.raises(Reject):
            lease.renew("a", wrong)
        assert lease.release("a", wrong) is False
    assert lease.holder is not None and lease.holder.name == "alice"
    assert changes == [(None, "a", "acquired")]


def test_no_holder_means_no_lease_error() -> None:
    lease, _, _ = make()
    with pytest.raises(Reject) as info:
        lease.check("a", None)
    assert info.value.code == "no_lease" and info.value.field == "client"


def test_release_only_by_the_holder() -> None:
    lease, _, changes = make()
    token = lease.acquire("a", "alice").token
    assert lease.release("b", token) is False
    assert lease.holder is not None
    assert lease.release("a", token) is True
    assert lease.holder is None
    assert changes[-1] == ("a", None, "released")


def test_vanished_client_loses_it() -> None:
    lease, _, changes = make()
    lease.acquire("a", "alice")
    assert lease.client_gone("b") is False
    assert lease.client_gone("a") is True
    assert changes[-1] == ("a", None, "holder vanished")


def test_a_silent_holder_loses_it_and_renewals_keep_it() -> None:
    lease, clock, changes = make(idle=60.0, heartbeat=1.5)
    token = lease.acquire("a", "alice").token
    assert renewed_each_second(lease, clock, token, 10) is None
    clock.t += 1.0
    assert lease.expire() is False
    clock.t += 0.6
    assert lease.expire() is True
    assert changes[-1] == ("a", None, SILENT)


def test_renewals_do_not_count_as_commands_for_the_idle_timeout() -> None:
    lease, clock, changes = make(idle=10.0, heartbeat=1.5)
    token = lease.acquire("a", "alice").token
    assert renewed_each_second(lease, clock, token, 11) is not None
    assert changes[-1][1] is None and "idle" in changes[-1][2]


def test_idle_timeout_counts_from_the_last_command() -> None:
    lease, clock, changes = make(idle=10.0)
    token = lease.acquire("a", "alice").token
    clock.t += 8
    lease.check("a", token)  # a command refreshes the idle clock
    clock.t += 8
    assert lease.expire() is False
    clock.t += 3
    assert lease.expire() is True
    assert changes[-1][1] is None and "idle" in changes[-1][2]


def test_zero_timeouts_never_expire() -> None:
    lease, clock, _ = make(idle=0, heartbeat=0)
    lease.acquire("a", "alice")
    clock.t += 1e6
    assert lease.expire() is False


def test_lease_from_config() -> None:
    lease = Lease.from_config({"idle_timeout": 5, "heartbeat_timeout": 0.5})
    assert (lease.idle_timeout, lease.heartbeat_timeout) == (5.0, 0.5)
    assert Lease.from_config({}).heartbeat_timeout == 1.5


@pytest.mark.parametrize(
    ("payload", "field"),
    [
        (b"", "v"),
        (b"\xc1", "payload"),
        (b"\x01", "payload"),
        (command_payload("")[:-1] + b"\xa0", "client"),
        (command_payload("c1", lease_token=7), "lease_token"),
        (command_payload("c" * 65), "client"),
        (command_payload("c1", client_name="n" * 65), "client_name"),
    ],
)
def test_malformed_payloads_are_rejected(payload: bytes, field: str | None) -> None:
    with pytest.raises(Reject) as info:
        parse_request("joint", payload)
    assert info.value.code == "invalid"
    assert info.value.field == field


def test_request_carries_client_name_token_and_verb_fields() -> None:
    req = parse_request(
        "joint", command_payload("c1", client_name="me", name="head_pan", lease_token="s3")
    )
    assert (req.client, req.name, req.fields, req.token) == ("c1", "me", {"name": "head_pan"}, "s3")
    lease_req = parse_request("lease", command_payload("c1", op="acquire", name="notebook"))
    assert lease_req.name == "notebook"


def test_the_daemons_own_stall_is_not_the_holders_silence() -> None:
    lease, clock, changes = make(idle=60.0, heartbeat=1.5)
    lease.acquire("a", "alice")
    clock.t += 2.0  # the daemon's loop did not run for 2 s; the renewals wait in its queue
    lease.excuse(2.0)
    assert lease.expire() is False
    clock.t += 1.6  # the daemon runs on, and no renewal comes: the holder is silent
    assert lease.expire() is True
    assert changes[-1] == ("a", None, SILENT)
    lease.excuse(5.0)  # nobody holds it: nothing to excuse
    assert lease.holder is None
