"""QoS per key (schemas/qos.py): video and telemetry may be dropped and go after commands; halt
and the lease go first and are never dropped; the daemon's publishers are declared with it."""

from __future__ import annotations

import threading
import uuid

import pytest
import zenoh

from robot_daemon.engine.publishers import SLOT_TOPICS, Publishers
from schemas import qos
from schemas.keys import VERBS, Keys
from schemas.messages import Event, Imu, decode
from schemas.session import free_tcp_port, server_config

KEYS = Keys("op1")
# zenoh.Priority, first served first (Zenoh's own order; its enum does not compare).
P = zenoh.Priority
ORDER = (P.REAL_TIME, P.INTERACTIVE_HIGH, P.INTERACTIVE_LOW, P.DATA_HIGH, P.DATA, P.DATA_LOW)


def rank(key: str) -> int:
    return ORDER.index(qos.for_key(key).priority)


def test_every_key_of_the_robot_has_a_qos() -> None:
    for key in KEYS.topics().values():
        assert qos.for_key(key) is not None
    for verb in VERBS:
        for key in (KEYS.cmd(verb), KEYS.admin(verb), KEYS.read(verb)):
            assert not qos.for_key(key).droppable, key
    for key in (KEYS.sim_control, KEYS.replay_control, KEYS.role("operator")):
        assert not qos.for_key(key).droppable


def test_halt_and_lease_go_before_commands_and_commands_before_telemetry_and_video() -> None:
    safety = {rank(KEYS.cmd("halt")), rank(KEYS.cmd("lease"))}
    assert len(safety) == 1
    (first,) = safety
    assert first < rank(KEYS.cmd("walk")) < rank(KEYS.status) < rank(KEYS.joints)
    assert rank(KEYS.joints) < rank(KEYS.camera_jpeg)
    for key in (KEYS.joints, KEYS.imu, KEYS.camera_jpeg, KEYS.sim_world, KEYS.vision_ball):
        assert qos.for_key(key).droppable, key
    assert (
        qos.for_key(KEYS.camera_jpeg).lossless().priority == qos.for_key(KEYS.camera_jpeg).priority
    )
    assert not qos.for_key(KEYS.camera_jpeg).lossless().droppable


def test_a_key_without_a_qos_is_refused_by_name() -> None:
    with pytest.raises(ValueError, match=r"darwin/op1/new/topic.*schemas/qos\.py"):
        qos.for_key("darwin/op1/new/topic")
    with pytest.raises(ValueError, match="not a darwin"):
        qos.for_key("rt/chatter")


def test_the_daemons_publishers_are_declared_with_the_table() -> None:
    keys = Keys(f"t{uuid.uuid4().hex[:8]}")
    with zenoh.open(server_config([f"tcp/127.0.0.1:{free_tcp_port()}"])) as session:
        pubs = Publishers(session, keys)
        try:
            for topic in (*SLOT_TOPICS, "events"):
                pub = pubs._pubs[topic]
                want = qos.for_key(getattr(keys, topic))
                assert (pub.priority, pub.congestion_control) == (
                    want.priority,
                    want.congestion_control,
                ), topic
        finally:
            pubs.close()


def test_only_droppable_newest_only_topics_are_put_from_the_callers_thread() -> None:
    keys = Keys(f"t{uuid.uuid4().hex[:8]}")
    with zenoh.open(server_config([f"tcp/127.0.0.1:{free_tcp_port()}"])) as session:
        pubs = Publishers(session, keys)
        try:
            got: list[bytes] = []
            arrived = threading.Event()

            def take(sample: zenoh.Sample) -> None:
                got.append(sample.payload.to_bytes())
                arrived.set()

            sub = session.declare_subscriber(keys.imu, take)
            imu = Imu(gyro=[0.0] * 3, accel=[0.0] * 3, gyro_raw=[512] * 3, accel_raw=[512] * 3)
            pubs.send("imu", imu)
            assert arrived.wait(10)
            assert decode(got[0], Imu) == imu
            sub.undeclare()
            with pytest.raises(ValueError, match="'events' is not a droppable newest-only"):
                pubs.send("events", Event(kind="info", message="x", data={}, seq=1))
        finally:
            pubs.close()
