"""A ``Robot`` acts on a sample only when it came on its subscription's key and is of its topic's
message type: over real Zenoh sessions on loopback, the far one standing in for a daemon."""

from __future__ import annotations

import logging
import threading
from collections.abc import Iterator

import pytest
import zenoh

from clients.robot import Robot
from schemas.keys import Keys
from schemas.messages import Imu, Message, Status, encode
from schemas.versions import PROTOCOL_VERSION

KEYS = Keys("r1")


def _status(robot: str) -> Status:
    return Status(state="running", robot=robot, protocol=list(PROTOCOL_VERSION))


def _publisher(session: zenoh.Session, key: str) -> zenoh.Publisher:
    """A publisher on ``key`` once a subscriber of it is known here (else a put goes nowhere)."""
    pub = session.declare_publisher(key)
    matched = threading.Event()
    listener = pub.declare_matching_listener(lambda s: s.matching and matched.set())
    assert matched.wait(10.0), f"no subscriber of {key} was declared to the publishing session"
    listener.undeclare()
    return pub


@pytest.fixture
def robot(zenoh_pair: tuple[zenoh.Session, zenoh.Session]) -> Iterator[Robot]:
    _, client = zenoh_pair
    with Robot(robot="r1", session=client, name="watcher") as r:
        yield r


def test_another_message_type_on_the_status_key_is_not_acted_on(
    zenoh_pair: tuple[zenoh.Session, zenoh.Session],
    robot: Robot,
    caplog: pytest.LogCaptureFixture,
) -> None:
    server, _ = zenoh_pair
    heard: list[Message] = []
    robot.subscribe("status", heard.append)
    imu = Imu(gyro=[0.0] * 3, accel=[0.0, 0.0, 9.81], gyro_raw=[512] * 3, accel_raw=[512] * 3)
    pub = _publisher(server, KEYS.status)
    with caplog.at_level(logging.WARNING, logger="clients.robot"):
        pub.put(encode(imu))
        # Then a real status on the same key: once it is here, the IMU before it was handled.
        pub.put(encode(_status("r1")))
        robot.wait_for("status", timeout=10.0, fresh=False)
    assert [type(m) for m in heard] == [Status]
    assert robot.state.imu is None
    assert robot.strays == 1
    assert "a 'imu' message on darwin/r1/status reached the status subscription" in caplog.text


def test_a_sample_of_another_key_handed_to_a_subscription_is_not_acted_on(
    zenoh_pair: tuple[zenoh.Session, zenoh.Session], robot: Robot
) -> None:
    """What a Zenoh that confused its key mappings would do: another robot's status handed to
    this robot's status subscription (the sample keeps its own key)."""
    server, client = zenoh_pair
    handed = threading.Event()

    def misdeliver(sample: zenoh.Sample) -> None:
        robot._on_sample("status", sample)
        handed.set()

    stray = client.declare_subscriber("darwin/r2/status", misdeliver)
    try:
        _publisher(server, "darwin/r2/status").put(encode(_status("r2")))
        assert handed.wait(10.0)
    finally:
        stray.undeclare()
    assert robot.state.status is None  # r2's status never became this robot's
    assert robot.strays == 1
    _publisher(server, KEYS.status).put(encode(_status("r1")))
    assert robot.wait_for("status", timeout=10.0, fresh=False).robot == "r1"
    assert robot.strays == 1
