"""Random bytes, random frames and random JSON thrown at a running gateway: afterwards it still
serves a well-behaved client, and the robot's goals never changed from the fuzz connections."""

from __future__ import annotations

import contextlib
import json
import socket
import struct
from collections.abc import Iterator
from dataclasses import dataclass

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from clients.robot import Robot
from tests.fixtures.system import RunningSystem, start_system
from tests.legacy_client import CONVENTIONS, FUZZ_FIELDS, FUZZ_TAGS, LegacyClient

FUZZ = settings(
    max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow], database=None
)
leaf = (
    st.none()
    | st.booleans()
    | st.integers(-(2**40), 2**40)
    | st.floats(allow_nan=False)
    | st.sampled_from([0, 1, 3, 26, 27, 325, -360, 360, 1e308])
    | st.text(max_size=12)
)
values = st.recursive(
    leaf,
    lambda inner: (
        st.lists(inner, max_size=4)
        | st.dictionaries(st.sampled_from(FUZZ_FIELDS) | st.text(max_size=6), inner, max_size=5)
    ),
    max_leaves=12,
)
messages = st.dictionaries(st.sampled_from(FUZZ_TAGS) | st.text(max_size=8), values, max_size=2)


@dataclass
class Target:
    system: RunningSystem
    owner: Robot
    goals: list[float]

    @property
    def address(self) -> tuple[str, int]:
        assert self.system.gateway is not None
        return self.system.gateway


@pytest.fixture(scope="module")
def target(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Target]:
    """A system of its own (nothing else moves its robot), with an owner holding the lease so
    nothing could move the robot except through a bug; the goals are taken before the fuzz.
    The owner sends no command while the fuzz runs, which on a loaded machine took longer than
    the daemon's lease idle timeout (60 s: the lease ended "idle for 60 s", as it should), so
    this robot runs with that timeout off."""
    config = tmp_path_factory.mktemp("fuzz") / "no-idle.toml"
    config.write_text("[daemon.lease]\nidle_timeout = 0\n")
    with (
        start_system(extra_args=["--config", str(config)]) as system,
        system.robot_client(name="fuzz owner") as owner,
    ):
        owner.wait_for("status", lambda s: s.lease is None, timeout=30.0, fresh=False)
        owner.acquire()
        for _ in range(3):
            joints = owner.wait_for("joints", timeout=30.0)
        yield Target(system, owner, list(joints.goal))
        with contextlib.suppress(Exception):
            owner.release()


def raw_connection(address: tuple[str, int], data: bytes) -> None:
    with socket.create_connection(address, timeout=5.0) as s, contextlib.suppress(OSError):
        s.sendall(data)
        s.shutdown(socket.SHUT_WR)
        while s.recv(65536):  # until the gateway closes or answers everything
            pass


@FUZZ
@given(data=st.binary(max_size=300))
def test_random_bytes(target: Target, data: bytes) -> None:
    raw_connection(target.address, data)


@FUZZ
@given(
    header=st.sampled_from(["big", "little", "ascii", "random"]),
    size_delta=st.integers(-8, 8),
    body=st.binary(max_size=200) | values.map(lambda v: json.dumps(v).encode()),
)
def test_random_frames(
    target: Target,
    header: str,
    size_delta: int,
    body: bytes,
) -> None:
    size = max(0, len(body) + size_delta)
    if header == "ascii":
        head = b"%04d" % min(size, 9999)
    elif header == "random":
        head = bytes((size * 37 + i * 91) % 256 for i in range(4))
    else:
        head = struct.pack(">I" if header == "big" else "<I", size)
    raw_connection(target.address, head + body)


@FUZZ
@given(batch=st.lists(messages, min_size=1, max_size=8), convention=st.sampled_from(CONVENTIONS))
def test_random_json_messages(
    target: Target,
    batch: list[dict],
    convention: tuple[str, bool],
) -> None:
    order, counted = convention
    with LegacyClient(*target.address, order, counted, timeout=30.0) as c:
        for msg in batch:
            c.send(msg)
        # Messages of one connection are handled in order: the marker's error comes after all.
        c.send({"end-of-batch": 1})
        c.recv_until(lambda m: "end-of-batch" in m.get("error", {}).get("message", ""))


def test_after_the_fuzz_the_gateway_serves_and_nothing_moved(target: Target) -> None:
    system, owner = target.system, target.owner
    assert system.alive, system.output()
    joints = owner.wait_for("joints", timeout=30.0)
    assert joints.goal == target.goals
    status = owner.wait_for("status", timeout=30.0)
    # The daemon logs why a lease ended: named when the owner's did (under load).
    leases = [ln for ln in system.lines if "lease " in ln and " daemon" in ln]
    assert status.lease is not None and status.lease["client"] == owner.client_id, leases
    # The gateway logged no failure (a bug costs one connection and logs an ERROR).
    assert not [
        ln for ln in system.lines if " gateway." in ln and (" ERROR" in ln or "failed" in ln)
    ]
    with LegacyClient(*target.address, order="little", counted=True, timeout=30.0) as c:
        c.send({"monitor": {"gyroscope": 1, "motors": 1}})
        msg = c.recv_until(lambda m: bool(m.get("monitor")))
        assert set(msg["monitor"]) <= {"gyroscope", "motors"} and msg["monitor"]
