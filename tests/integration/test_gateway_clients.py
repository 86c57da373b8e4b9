"""Many legacy clients at once: each gets exactly its streams, and a client that never reads
does not slow the others down."""

from __future__ import annotations

import contextlib
import itertools
import queue
import threading
import time
from collections.abc import Iterator

from clients.robot import topic_key
from schemas.keys import Keys
from schemas.session import connect, resolve
from tests.fixtures.system import RunningSystem, start_system
from tests.legacy_client import CONVENTIONS, LegacyClient, start_gateway

SENSOR_STREAMS = ("accelerometer", "gyroscope", "motors")


def test_twenty_clients_each_receive_exactly_their_streams(robot_system: RunningSystem) -> None:
    assert robot_system.gateway is not None
    host, port = robot_system.gateway
    # Every non-empty subset of the sensor streams, in every framing convention, 20 clients.
    subsets = [
        set(s)
        for n in range(1, len(SENSOR_STREAMS) + 1)
        for s in itertools.combinations(SENSOR_STREAMS, n)
    ]
    wanted = [subsets[i % len(subsets)] for i in range(20)]
    with contextlib.ExitStack() as stack:
        clients = []
        for i, streams in enumerate(wanted):
            order, counted = CONVENTIONS[i % len(CONVENTIONS)]
            c = stack.enter_context(LegacyClient(host, port, order, counted, timeout=20.0))
            c.send({"monitor": {**{s: 1 for s in streams}, "period": 20 + 5 * (i % 4)}})
            clients.append(c)
        for c, streams in zip(clients, wanted, strict=True):
            seen: set[str] = set()
            # Read until every requested stream showed up at least once (first message is full).
            while seen != streams:
                msg = c.recv()
                assert msg is not None and list(msg) == ["monitor"], msg
                keys = set(msg["monitor"])
                assert keys <= streams, (keys, streams)
                seen |= keys
            # Switching one stream off stops it; an unknown tag's error reply marks the point
            # after which every monitor message is built with the new set.
            c.send({"monitor": {sorted(streams)[0]: 0}})
            c.send({"marker": 1})
        for c, streams in zip(clients, wanted, strict=True):
            off = sorted(streams)[0]
            assert c.recv_error()["code"] == "unknown"
            if streams == {off}:
                continue  # nothing left on: this client's messages stop altogether
            for _ in range(5):
                msg = c.recv()
                assert msg is not None and off not in msg["monitor"], msg
                assert set(msg["monitor"]) <= streams


def _count_messages(clients: list[LegacyClient], stop: threading.Event, counts: list[int]) -> None:
    """Read the clients round-robin until ``stop``, counting monitor messages."""
    while not stop.is_set():
        for i, c in enumerate(clients):
            with contextlib.suppress(TimeoutError):
                if c.recv(timeout=0.05) is not None:
                    counts[i] += 1


@contextlib.contextmanager
def counting(clients: list[LegacyClient]) -> Iterator[list[int]]:
    counts = [0] * len(clients)
    stop = threading.Event()
    t = threading.Thread(target=_count_messages, args=(clients, stop, counts))
    t.start()
    try:
        yield counts
    finally:
        stop.set()
        t.join()


def window(clients: list[LegacyClient], seconds: float) -> float:
    """Messages per second per client over a window (a rate, compared with a baseline)."""
    with counting(clients) as counts:
        t0 = time.monotonic()
        # The window is the measurement itself, not a synchronisation.
        threading.Event().wait(seconds)
        elapsed = time.monotonic() - t0
    return sum(counts) / len(clients) / elapsed


def test_a_client_that_never_reads_does_not_slow_the_others(robot_system: RunningSystem) -> None:
    small = {"write_buffer": 2048, "socket_send_buffer": 4096, "log_interval": 0.5}
    with start_gateway(robot_system.endpoint, robot_system.robot, small) as gw:
        readers = [gw.client(timeout=30.0) for _ in range(4)]
        try:
            for c in readers:
                c.send({"monitor": {"motors": 1, "accelerometer": 1, "gyroscope": 1, "period": 20}})
                c.recv()
            baseline = window(readers, 1.5)

            # A client with a tiny receive window asks for everything every 10 ms, never reads.
            stalled = gw.client(rcvbuf=1024)
            stalled.send(
                {"monitor": {"motors": 1, "accelerometer": 1, "gyroscope": 1, "period": 10}}
            )
            # The gateway says when it starts dropping that client's stale messages.
            with counting(readers):
                gw.wait_line("does not keep up", 30.0)
            loaded = window(readers, 1.5)
            stalled.close()
        finally:
            for c in readers:
                c.close()
    # Same gateway, same robot, same run: the others' rate is not dragged down by the stall.
    assert loaded > 0.7 * baseline, (loaded, baseline)


def test_a_gateway_follows_joints_and_imu_only_while_a_legacy_client_is_connected() -> None:
    """Nobody connected, the gateway subscribes to neither stream, so the daemon builds neither
    for it; the first client brings both back, the last one leaving ends them again."""
    with start_system() as system:
        assert system.gateway is not None
        host, port = system.gateway
        session = connect(resolve(system.endpoint, system.robot))
        matching: dict[str, queue.SimpleQueue[bool]] = {}
        publishers = []
        try:
            for topic in ("joints", "imu"):
                heard: queue.SimpleQueue[bool] = queue.SimpleQueue()
                pub = session.declare_publisher(topic_key(Keys(system.robot), topic))
                pub.declare_matching_listener(lambda s, q=heard: q.put(bool(s.matching)))
                heard.put(bool(pub.matching_status.matching))  # type: ignore[attr-defined]
                matching[topic] = heard
                publishers.append(pub)

            def settles_at(topic: str, value: bool) -> None:
                heard = matching[topic]
                while heard.get(timeout=30) is not value:
                    pass

            for topic in matching:
                settles_at(topic, False)
            with LegacyClient(host, port, timeout=20.0) as client:
                for topic in matching:
                    settles_at(topic, True)
                client.send({"monitor": {"motors": 1, "gyroscope": 1, "period": 20}})
                msg = client.recv()
                assert msg is not None and {"motors", "gyroscope"} & set(msg["monitor"]), msg
            for topic in matching:
                settles_at(topic, False)
        finally:
            for pub in publishers:
                pub.undeclare()
            session.close()
