"""One camera owner: a Zenoh subscriber of the camera key and ball play's vision both get the
frames of the daemon's camera thread, which opens the source once for both (a real webcam
cannot be opened twice) and closes it when neither needs frames any more."""

from __future__ import annotations

import threading
import uuid
from collections.abc import Iterator

import pytest
import zenoh

from config.loader import load_all
from robot_daemon.arbiter.registry import Request
from robot_daemon.arbiter.verbs import ballplay
from robot_daemon.engine.camera import CameraThread
from robot_daemon.vision.sources import TestPatternSource, register_source
from schemas.keys import Keys
from schemas.messages import Message
from schemas.session import free_tcp_port, server_config
from tests.fixtures.motion import motion_context

WAIT = 15.0


class CountingSource(TestPatternSource):
    """The test pattern, counting how often it is opened and whether it is open."""

    opened = 0
    open_now = 0

    def __init__(self, ctx: object) -> None:
        super().__init__()
        type(self).opened += 1
        type(self).open_now += 1

    def close(self) -> None:
        type(self).open_now -= 1


@pytest.fixture
def session() -> Iterator[zenoh.Session]:
    s = zenoh.open(server_config([f"tcp/127.0.0.1:{free_tcp_port()}"]))
    yield s
    s.close()


def test_the_camera_is_opened_once_for_a_subscriber_and_ball_play(
    session: zenoh.Session,
) -> None:
    spec = f"counting-{uuid.uuid4().hex[:6]}"
    register_source(spec, CountingSource)
    settings = load_all()
    keys = Keys(f"t{uuid.uuid4().hex[:8]}")
    camera = CameraThread.from_settings(session, keys, spec, settings)
    detections = threading.Event()

    def publish(topic: str, msg: Message) -> None:
        assert topic == "vision_ball"
        detections.set()

    ctx = motion_context(settings, camera=camera, publish=publish)
    jpegs = threading.Event()
    sub = session.declare_subscriber(keys.camera_jpeg, lambda _s: jpegs.set())
    try:
        assert jpegs.wait(WAIT), "no camera frame reached the subscriber"
        started = ballplay.playball(Request("playball", "c1", "t", {"op": "start"}), ctx)
        assert started["camera"] == spec
        assert detections.wait(WAIT), "ball vision saw no frame"
        jpegs.clear()
        assert jpegs.wait(WAIT), "the subscriber stopped getting frames"
        assert CountingSource.opened == 1
        assert camera.status()["opened"] == 1 and camera.status()["readers"] == 1
        ballplay.playball(Request("playball", "c1", "t", {"op": "stop"}), ctx)
    finally:
        sub.undeclare()
        camera.close()
    assert CountingSource.open_now == 0
    assert CountingSource.opened == 1
