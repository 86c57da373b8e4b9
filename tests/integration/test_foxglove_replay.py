"""`darwin foxglove` against `darwin replay`: a recorded session reaches Foxglove as if live."""

from __future__ import annotations

import subprocess
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from schemas import kinematics as K
from schemas.session import free_tcp_port
from tests.fixtures.system import darwin_command
from tests.foxglove_ws import FoxgloveClient
from tests.integration.test_recording_replay import recording  # noqa: F401  (fixture)
from tests.transforms import tf_poses

pytestmark = pytest.mark.timeout(240)


def _stop(proc: subprocess.Popen[str]) -> None:
    if proc.poll() is None:
        proc.terminate()
    try:
        proc.communicate(timeout=10)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.communicate()


@pytest.fixture
def replay_foxglove(recording: tuple[Path, dict]) -> Iterator[str]:  # noqa: F811
    path, _sent = recording
    endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
    replay = subprocess.Popen(
        darwin_command("replay", str(path), "--listen", endpoint, "--robot", "fresh", "--loop"),
        stderr=subprocess.PIPE,
        text=True,
    )
    fox = None
    try:
        assert replay.stderr is not None
        assert replay.stderr.readline().startswith("replaying")
        fox = subprocess.Popen(
            darwin_command(
                "foxglove", "--connect", endpoint, "--robot", "fresh", "--listen", "127.0.0.1:0"
            ),
            stdout=subprocess.PIPE,
            text=True,
        )
        assert fox.stdout is not None
        line = fox.stdout.readline().strip()
        assert line.startswith("foxglove: ws://127.0.0.1:"), line
        yield line.split(" ", 1)[1]
    finally:
        if fox is not None:
            _stop(fox)
        _stop(replay)


def test_a_replayed_session_reaches_foxglove(replay_foxglove: str) -> None:
    with FoxgloveClient.open(replay_foxglove) as fc:
        fc.subscribe("/joints", "/tf", "/camera/image")
        joints = fc.take("/joints")
        # The recording's synthetic angles: 0.01·tick + 0.1·i.
        tick = joints["tick"]
        assert np.allclose(joints["position"], [0.01 * tick + 0.1 * i for i in range(20)])
        stamp_ns = round(joints["stamp"] * 1e9)

        def same_stamp(m) -> bool:  # type: ignore[no-untyped-def]
            t = m.transforms[0].timestamp
            return abs(t.seconds * 1_000_000_000 + t.nanos - stamp_ns) < 1000

        tf = fc.take("/tf", same_stamp)
        pos = dict(zip(joints["id"], joints["position"], strict=True))
        sole = tf_poses(tf.transforms)["l_sole"]
        assert np.allclose(sole, K.leg_fk(pos, "left"), atol=1e-9)
        img = fc.take("/camera/image")
        assert bytes(img.data).startswith(b"\xff\xd8")
